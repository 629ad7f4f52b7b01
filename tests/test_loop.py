"""The training loop's steps (``examples/loop.py``) and the run's clock and checkpoint (``examples/run_utils.py``),
each on its own, with stand-ins for the buffers, losses and envs they drive."""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
from tensordict import TensorDict

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

import loop  # noqa: E402
from run_utils import BestEvaluatedPolicy, RunCheckpoint, RunClock, evaluation_metrics  # noqa: E402
from tensordict.nn import TensorDictModule, TensorDictSequential  # noqa: E402
from torchrl import timeit  # noqa: E402
from torchrl.data import Bounded, LazyTensorStorage, TensorDictReplayBuffer  # noqa: E402
from torchrl.modules import MLP, TanhModule, ValueOperator  # noqa: E402

from torchrl_sail import (  # noqa: E402
    AbsorbingStateTransform,
    AlphaScheduler,
    NStepTransform,
    PrioritizedMixedReplayBuffer,
    SAILLoss,
)


def collected(num_envs: int = 2, steps: int = 3, done_at=None) -> TensorDict:
    """A collector batch ``[num_envs, steps]``: observation ``(env * 100 + step, 0)`` (the second column is
    where an absorbing-state indicator goes), its return the first column, one terminal per ``done_at``."""
    value = (torch.arange(num_envs)[:, None] * 100 + torch.arange(steps)[None]).float().unsqueeze(-1)
    obs = torch.cat([value, torch.zeros_like(value)], -1)
    done = torch.zeros(num_envs, steps, 1, dtype=torch.bool)
    for env, step in done_at or []:
        done[env, step] = True
    return TensorDict(
        {
            "observation": obs,
            "action": torch.ones(num_envs, steps, 1),
            "step_count": torch.arange(steps).expand(num_envs, steps).unsqueeze(-1),
            "next": {
                "observation": obs + torch.tensor([1.0, 0.0]),
                "reward": torch.zeros(num_envs, steps, 1),
                "done": done,
                "terminated": done.clone(),
                "truncated": torch.zeros_like(done),
                "episode_return": value.clone(),
            },
        },
        batch_size=[num_envs, steps],
    )


class Buffer(list):
    def extend(self, rows):
        self.append(rows.clone())


def test_store_puts_every_row_in_every_buffer():
    replay, recent = Buffer(), Buffer()
    loop.TransitionStore([replay, recent])(collected())
    assert len(replay) == len(recent) == 1
    rows = replay[0]
    assert rows.shape == (6,) and rows["observation"][:, 0].tolist() == [0, 1, 2, 100, 101, 102]
    assert "step_count" not in rows.keys()  # only the transition's own entries are stored
    assert (recent[0] == rows).all()


def test_store_adds_absorbing_transitions_after_terminals():
    replay = Buffer()
    store = loop.TransitionStore([replay], absorbing=AbsorbingStateTransform())
    store(collected(done_at=[(0, 1), (1, 2)]))
    # 6 steps + one absorbing transition per terminal
    rows = replay[0]
    assert rows.shape == (8,)
    # each terminal row now leads into s_a = (0, 1), and an (s_a, s_a) row follows it
    assert rows["observation"][:, 1].tolist() == [0, 0, 1, 0, 0, 0, 0, 1]
    assert rows["next", "observation"][:, 1].tolist() == [0, 1, 1, 0, 0, 0, 1, 1]
    assert rows["observation"][:, 0].tolist() == [0, 1, 0, 2, 100, 101, 102, 0]


def test_store_waits_for_the_nstep_window():
    replay = Buffer()
    store = loop.TransitionStore([replay], nstep=NStepTransform(2, 0.99))
    store(collected(steps=3))
    # per stream, a step is stored once the 2 steps after it are collected: step 0 of each of 2 streams
    assert replay[0].shape == (2,)
    assert replay[0]["observation"][:, 0].tolist() == [0, 100]
    store(collected(steps=3))
    assert replay[1].shape == (6,)


def test_store_stores_nothing_while_every_row_waits():
    replay = Buffer()
    loop.TransitionStore([replay], nstep=NStepTransform(5, 0.99))(collected(steps=3))
    assert replay == []


class Teacher:
    def __init__(self, promote_at: int) -> None:
        self.calls, self.promote_at = 0, promote_at
        self.writer = SimpleNamespace(num_promoted=0)

    def extend(self, data):
        self.calls += 1
        self.writer.num_promoted = int(self.calls >= self.promote_at)


def test_teacher_update_promotes_then_switches_alpha_once():
    teacher = Teacher(promote_at=2)
    update = loop.TeacherUpdate(teacher, AlphaScheduler(SimpleNamespace(alpha=1.0)), adaptive=True)
    assert update(None, 1000) == (0.5, {})
    assert update(None, 2000) == (0.0, {"alpha_switch_frame": 2000})
    assert update(None, 3000) == (0.0, {})
    assert teacher.calls == 3


def test_teacher_update_without_adaptation_leaves_the_teacher_alone():
    teacher = Teacher(promote_at=1)
    update = loop.TeacherUpdate(teacher, AlphaScheduler(SimpleNamespace(alpha=1.0)), adaptive=False)
    assert update(None, 1000) == (0.5, {}) and teacher.calls == 0


def test_teacher_update_stops_promoting_at_its_count():
    offered = []  # each batch offered: the number of trajectories it promotes
    writer = SimpleNamespace(num_promoted=0)
    teacher = SimpleNamespace(
        writer=writer, extend=lambda n: (offered.append(n), setattr(writer, "num_promoted", writer.num_promoted + n))
    )
    update = loop.TeacherUpdate(teacher, AlphaScheduler(SimpleNamespace(alpha=1.0)), adaptive=True, max_promoted=3)
    assert update(0, 500) == (0.5, {})
    assert update(2, 1000) == (0.0, {"alpha_switch_frame": 1000})
    update(2, 1500)  # 2 < 3: offered (a batch may promote past the count)
    update(5, 2000)  # 4 >= 3: held
    assert offered == [0, 2, 2] and writer.num_promoted == 4


def test_finished_episodes_feeds_the_best_policy_and_logs_the_means():
    seen = []
    best = SimpleNamespace(observe=lambda returns, before, frames: seen.append((returns.tolist(), before, frames)))
    metrics = loop.finished_episodes(collected(done_at=[(0, 1), (1, 2)]), best, before=500, frames=506)
    assert seen == [([1.0, 102.0], 500, 506)]  # the returns of the episodes that ended (their observations here)
    assert metrics["train/dense_return"].item() == pytest.approx(51.5)
    assert metrics["train/episode_length"].item() == pytest.approx((2 + 3) / 2)  # step_count + 1
    assert loop.finished_episodes(collected(), best, before=0, frames=6) == {}


def test_frame_cadence_counts_the_multiples_crossed_from_its_start():
    cadence = loop.FrameCadence(every_frames=1000, steps=50, start=2000)
    assert [cadence(before, now, None) for before, now in [(0, 1999), (1999, 2000), (2000, 4500)]] == [0, 50, 100]


def test_episode_cadence_trains_per_frame_of_each_episode_that_ended_after_its_start():
    # one env, frames 1001..1005: an episode of 2 steps ends at frame 1002, one of 3 at frame 1005
    data = collected(num_envs=1, steps=5, done_at=[(0, 1), (0, 4)])
    data["step_count"] = torch.tensor([[0, 1, 0, 1, 2]]).unsqueeze(-1)
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=1000)(1000, 1005, data) == 2 + 3
    assert loop.EpisodeCadence(steps_per_frame=0.5, start=1000)(1000, 1005, data) == round(0.5 * 5)
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=1003)(1000, 1005, data) == 3  # the 1st ended before
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=0)(1000, 1005, collected(num_envs=1, steps=5)) == 0


def test_each_cadence_names_the_frame_count_its_blocks_schedules_read():
    # the episodes above: 2 steps from frame 1000 to 1002, 3 steps from 1002 to 1005
    data = collected(num_envs=1, steps=5, done_at=[(0, 1), (0, 4)])
    data["step_count"] = torch.tensor([[0, 1, 0, 1, 2]]).unsqueeze(-1)
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=1000).began_at(1000, data) == 1000
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=1003).began_at(1000, data) == 1002  # the 2nd only
    # an episode that began in an earlier batch: ended at frame 1002 after 40 steps, so it began at 962
    data["step_count"] = torch.tensor([[38, 39, 0, 1, 2]]).unsqueeze(-1)
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=0).began_at(1000, data) == 962
    no_end = collected(num_envs=1, steps=5)
    assert loop.EpisodeCadence(steps_per_frame=1.0, start=0).began_at(1000, no_end) == 1000
    assert loop.FrameCadence(every_frames=1000, steps=50, start=0).began_at(1500, data) == 1500


def test_learning_blocks_in_either_order_and_no_d_block_without_a_discriminator():
    cfg = SimpleNamespace(
        algo=SimpleNamespace(reward=SimpleNamespace(source="discriminator")),
        collector=SimpleNamespace(init_random_frames=0),
        optim=SimpleNamespace(
            cadence="frames",
            start_frames=None,
            block_order="td3_first",
            discriminator=SimpleNamespace(every_frames=500, steps=10, batch_size=4),
        ),
    )
    td3 = object()
    d_opt = {"discriminator": None}
    blocks = loop.make_learning_blocks(cfg, td3, None, None, d_opt)
    assert blocks[0] is td3 and isinstance(blocks[1], loop.DiscriminatorBlock)
    cfg.optim.block_order = "discriminator_first"
    assert loop.make_learning_blocks(cfg, td3, None, None, d_opt)[1] is td3
    cfg.algo.reward.source = "env"
    assert loop.make_learning_blocks(cfg, td3, None, None, d_opt) == [td3]


def test_actor_lr_decay_is_a_function_of_frames():
    optimizer = torch.optim.Adam([torch.zeros(1, requires_grad=True)], lr=1.0)
    decay = loop.ActorLRDecay(optimizer, 1e-3, rate=0.5, every_frames=100_000)
    assert decay(99_999) == {"sail/actor_lr": 1e-3}
    assert decay(250_000) == {"sail/actor_lr": 2.5e-4} and optimizer.param_groups[0]["lr"] == 2.5e-4


class Batches:
    """Stands in for MixedReplayBuffer: blocks of ``[num_batches, batch_size]`` rows, reward = row index."""

    def __init__(self) -> None:
        self.calls = []

    def sample(self, batch_size, *, teacher_fraction, num_batches):
        self.calls.append((batch_size, teacher_fraction, num_batches))
        reward = torch.arange(num_batches * batch_size, dtype=torch.float32).reshape(num_batches, batch_size, 1)
        return TensorDict({"next": {"reward": reward}}, batch_size=[num_batches, batch_size])


def td3_block(**kwargs):
    steps = []  # per gradient step: whether it moved the actor, "targets" after a target-only update

    def update(batch, update_actor):
        steps.append(update_actor)
        return {"loss_qvalue": torch.tensor(float(len(steps)))}

    alpha = kwargs.pop("alpha", 0.5)
    options = dict(
        batch_size=4,
        cadence=loop.FrameCadence(every_frames=1000, steps=3, start=2000),
        alpha_scheduler=SimpleNamespace(alpha=alpha),
        policy_delay=2,
        actor_updates_after=0,
        reward_tag="sail/d_reward_mean",
        update_targets=lambda: steps.append("targets"),
    )
    options.update(kwargs)
    batches = Batches()
    return loop.TD3Block(batches, update, **options), batches, steps


def test_td3_block_runs_at_its_cadence_after_warmup():
    block, batches, steps = td3_block()
    assert block(0, 1500, None) == {} and batches.calls == []  # warm-up
    metrics = block(1500, 3000, None)  # crosses 2000 and 3000: two blocks' worth
    assert batches.calls == [(4, 0.5, 6)]
    assert steps == [False, True, False, True, False, True]  # every policy_delay-th step moves the actor
    assert metrics["sail/d_reward_mean"].item() == pytest.approx(sum(range(24)) / 24)
    assert metrics["sail/loss_qvalue"].item() == 6.0  # the block's last step
    assert block.gradient_steps == 6


def test_td3_block_continues_a_resumed_count_and_delays_the_actor():
    block, _, steps = td3_block(gradient_steps=5, actor_updates_after=8, policy_delay=1, alpha=0.0)
    block(2500, 3000, None)
    # steps 6, 7, 8: before the actor starts, the targets still move at every policy_delay-th step
    assert steps == [False, "targets", False, "targets", True] and block.gradient_steps == 8


def test_td3_block_moves_the_targets_every_policy_delay_steps_before_the_actor_starts():
    block, _, steps = td3_block(actor_updates_after=4, policy_delay=2, alpha=0.0)
    block(1500, 3000, None)  # steps 1-6; the actor from step 4 on, at steps 4 and 6
    assert steps == [False, False, "targets", False, True, False, True]


def test_td3_block_says_when_its_first_actor_step_is_done():
    for after, delay, first in ((0, 2, 2), (1001, 2, 1002), (1000, 2, 1000), (8, 1, 8)):
        block, _, _ = td3_block(actor_updates_after=after, policy_delay=delay, gradient_steps=first - 1)
        assert not block.actor_started
        block.gradient_steps = first
        assert block.actor_started, (after, delay)


def test_random_episodes_until_the_first_episode_that_starts_after_the_actor_did():
    """Kostrikov et al.'s sample_random: whole episodes of uniform random actions until one starts
    after the actor's first update; from then on the policy, whatever started() says later."""
    spec = Bounded(-1.0, 1.0, (2,))
    policy = TensorDictModule(lambda obs: torch.full((2,), 0.5), in_keys=["observation"], out_keys=["action"])
    started = [False]
    wrapper = loop.RandomEpisodesUntil(policy, spec, lambda: started[0])
    assert wrapper.in_keys == ["observation", "is_init"] and wrapper.out_keys == ["action"]

    def act(is_init: bool) -> torch.Tensor:
        td = TensorDict(observation=torch.zeros(3), is_init=torch.tensor([is_init]), batch_size=[])
        return wrapper(td)["action"]

    torch.manual_seed(0)
    random = [act(True), act(False)]
    started[0] = True
    random.append(act(False))  # the actor started mid-episode: that episode stays random
    for action in random:
        assert action.shape == (2,) and action.abs().max() <= 1 and not torch.equal(action, torch.full((2,), 0.5))
    assert len({tuple(action.tolist()) for action in random}) == 3  # a fresh draw per step
    assert torch.equal(act(True), torch.full((2,), 0.5))  # the next episode: the policy
    started[0] = False
    assert torch.equal(act(True), torch.full((2,), 0.5)) and not wrapper.random


def test_td3_block_decays_the_lr_and_measures_saturation_on_agent_rows_only():
    seen = []
    block, _, _ = td3_block(
        lr_decay=lambda frames: seen.append(frames) or {"sail/actor_lr": 1.0},
        saturation=lambda batch: {"actor/saturation": torch.tensor(0.25)},
    )
    metrics = block(2500, 3000, None)
    assert seen == [2500] and metrics["sail/actor_lr"] == 1.0 and "actor/saturation" in metrics
    block.alpha_scheduler.alpha = 1.0  # a teacher-only batch
    assert "actor/saturation" not in block(3500, 4000, None)
    # on the episode cadence, the frame count before the episode trained on began (the release's
    # decay, set before each rollout): a 600-step episode ending at frame 100_300 began at 99_700
    data = collected(num_envs=1, steps=500, done_at=[(0, 299)])
    data["step_count"] = torch.cat([torch.arange(300, 600), torch.arange(200)]).reshape(1, 500, 1)
    episodes = loop.EpisodeCadence(steps_per_frame=1.0, start=0)
    seen.clear()
    block, _, steps = td3_block(cadence=episodes, lr_decay=lambda frames: seen.append(frames) or {})
    block(100_000, 100_500, data)
    assert seen == [99_700] and len(steps) == 600


def test_td3_block_draws_each_prioritized_batch_after_the_step_before_set_its_priorities():
    teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(2))
    teacher.extend(TensorDict({"next": {"reward": torch.ones(2, 1)}}, [2]))
    replay = TensorDictReplayBuffer(storage=LazyTensorStorage(8))
    batches = PrioritizedMixedReplayBuffer(teacher, replay, alpha=1.0, eps=1e-9, keys=[("next", "reward")])
    replay.extend(TensorDict({"next": {"reward": torch.zeros(2, 1)}}, [2]))

    def update(batch, update_actor):  # DDPGfD's delta^2: large on teacher rows, 0 on the agent's
        batch["td_error"] = batch["is_teacher"].float() * 100
        return {}

    prioritized = loop.PrioritizedUpdate(
        update, batches, SimpleNamespace(tensor_keys=SimpleNamespace(priority="td_error")), action_grad_coef=0.0
    )
    block = loop.TD3Block(
        batches,
        prioritized,
        batch_size=64,
        cadence=loop.FrameCadence(every_frames=1000, steps=3, start=2000),
        alpha_scheduler=SimpleNamespace(alpha=0.5),
        policy_delay=2,
        actor_updates_after=0,
        reward_tag="sail/d_reward_mean",
        update_targets=lambda: None,
    )
    torch.manual_seed(0)
    metrics = block(2500, 3000, None)  # 3 steps of 64 rows
    # the first batch drew the 4 rows at priority 1, one per equal range: exactly half teacher rows;
    # after it, only the teacher rows have mass
    first = metrics["sail/teacher_share"].item() * 3 - 2
    assert first == pytest.approx(0.5) and metrics["sail/d_reward_mean"].item() == pytest.approx((first + 2) / 3)
    assert torch.allclose(batches.probabilities(), torch.tensor([0.5, 0.5, 0.0, 0.0], dtype=torch.float64))


def linear_critic_loss():
    """A TD3 loss on 3-dim observations and 2-dim actions whose critics are linear,
    Q_i(s, a) = W_i [a, s] + b_i: grad_a Q_1 = W_1[:, :2] on every row."""
    spec = Bounded(-1.0, 1.0, (2,))
    actor = TensorDictSequential(
        TensorDictModule(MLP(in_features=3, out_features=2, num_cells=[8]), ["observation"], ["param"]),
        TanhModule(["param"], ["action"], spec=spec),
    )
    critic = ValueOperator(MLP(in_features=5, out_features=1, num_cells=[]), in_keys=["action", "observation"])
    return spec, SAILLoss(actor, critic, action_spec=spec)


def test_prioritized_update_adds_the_first_critics_action_gradient():
    spec, loss = linear_critic_loss()
    batch = TensorDict({"observation": torch.randn(6, 3), "action": spec.rand((6,))}, [6])
    weight = loss.qvalue_network_params[0]["module", "0", "weight"]
    expected = weight[0, :2].pow(2).sum().detach().expand(6)
    gradient = loop.PrioritizedUpdate(None, None, loss, action_grad_coef=1.0).action_gradient(batch)
    torch.testing.assert_close(gradient, expected)
    assert "td_error" not in batch.keys() and not batch["action"].requires_grad  # the batch is left as it was


def test_prioritized_update_sets_each_rows_td_error_plus_lambda3_times_the_action_gradient_before_the_step():
    """DDPGfD's priority delta^2 + lambda_3 |grad_a Q_1(s, a)|^2 (the buffer adds eps, eps_D): the step's
    own delta^2, and the gradient of the critic as it was before the step moved it."""
    spec, loss = linear_critic_loss()
    weight = loss.qvalue_network_params[0]["module", "0", "weight"]
    before = weight[0, :2].pow(2).sum().item()  # |grad_a Q_1|^2 of the linear critic, on every row

    def update(batch, update_actor):  # the TD3 step: writes delta^2 and moves the critic
        batch["td_error"] = torch.arange(4, dtype=torch.float32)
        with torch.no_grad():
            weight.mul_(3.0)
        return {"loss_qvalue": torch.tensor(1.0)}

    seen = []
    buffer = SimpleNamespace(index_key="index", update_priority=lambda index, priority: seen.append((index, priority)))
    prioritized = loop.PrioritizedUpdate(update, buffer, loss, action_grad_coef=0.5)
    assert loss.tensor_keys.priority == "td_error"
    batch = TensorDict(
        {"observation": torch.randn(4, 3), "action": spec.rand((4,)), "index": torch.arange(10, 14)}, [4]
    )
    assert prioritized(batch, update_actor=False) == {"loss_qvalue": torch.tensor(1.0)}
    ((index, priority),) = seen
    assert index.tolist() == [10, 11, 12, 13]
    torch.testing.assert_close(priority, torch.tensor([0.0, 1.0, 2.0, 3.0]) + 0.5 * before)


class DLoss:
    """Stands in for DiscriminatorLoss: a loss on one parameter, accuracy 0.6 on each side."""

    def __init__(self) -> None:
        self.weight = torch.nn.Parameter(torch.zeros(1))

    def __call__(self, batch):
        return {
            "loss_discriminator": (self.weight - 1).pow(2).sum(),
            "accuracy_teacher": torch.tensor(0.6),
            "accuracy_agent": torch.tensor(0.6),
        }


def d_block(steps: int, after_step=None, max_accuracy=None):
    d_loss, batches = DLoss(), Batches()
    optimizer = torch.optim.SGD([d_loss.weight], lr=0.1)
    cfg = SimpleNamespace(optim=SimpleNamespace(discriminator=SimpleNamespace(max_accuracy=max_accuracy)))
    block = loop.DiscriminatorBlock(
        cfg,
        batches,
        d_loss,
        optimizer,
        cadence=loop.FrameCadence(every_frames=500, steps=steps, start=1000),
        batch_size=2,
        after_step=after_step,
    )
    return block, batches, d_loss


def test_discriminator_block_steps_at_its_cadence():
    calls = []
    block, batches, d_loss = d_block(steps=2, after_step=lambda batch: calls.append(batch.shape) or {"rnd/x": 1.0})
    assert block(0, 900, None) == {} and batches.calls == []  # warm-up
    metrics = block(1000, 2000, None)  # crosses 1500 and 2000
    assert batches.calls == [(4, 0.5, 4)] and len(calls) == 4  # 2 teacher + 2 agent rows per step
    # 4 SGD steps on (w - 1)^2 from 0 at lr 0.1: w = 1 - 0.8^4
    assert d_loss.weight.item() == pytest.approx(1 - 0.8**4)
    assert metrics["d/skipped"] == 0.0 and metrics["rnd/x"] == 1.0


def test_discriminator_block_without_steps_samples_nothing():
    block, batches, _ = d_block(steps=0)
    assert block(1000, 5000, None) == {} and batches.calls == []


def test_discriminator_block_skips_steps_beyond_max_accuracy():
    block, _, d_loss = d_block(steps=1, max_accuracy=0.5)
    assert block(1000, 1500, None)["d/skipped"] == 1.0 and d_loss.weight.item() == 0.0


def test_evaluations_at_their_cadence_with_the_other_actors_and_videos(monkeypatch):
    evaluated, other, videos = [], [], []
    monkeypatch.setattr(
        loop,
        "record_evaluation",
        lambda env, actor, actors, cfg, run, frames, teacher: evaluated.append((env, frames)) or {"eval/return": 10.0},
    )
    returns = {None: [30.0, 10.0, 20.0], "avg": [40.0, 50.0, 60.0]}  # online's (its own weights), the average's
    monkeypatch.setattr(
        loop,
        "actor_returns",
        lambda env, actor, weights, episodes, steps: other.append((env, weights)) or returns[weights],
    )
    cfg = SimpleNamespace(
        eval=SimpleNamespace(actor="target", every_frames=1000, video_every_frames=2000, episodes=3),
        env=SimpleNamespace(max_episode_steps=1000),
    )
    envs = {"evaluated": "e", "others": {"online": "o", "average": "a"}, "video": "v"}
    actors = {"online": "own", "target": "tgt", "average": "avg"}
    swapped = []  # the weights each video ran with: the evaluated actor's
    monkeypatch.setattr(loop, "weights_in", lambda actor, weights: swapped.append(weights) or contextlib.nullcontext())
    evaluations = loop.Evaluations(cfg, None, actors, {}, 15.0, envs, lambda env, actor, frames: videos.append(frames))
    assert evaluations(0, 500) == {}
    assert evaluations(500, 1000) == {
        "eval/return": 10.0,
        "eval/return_online": 20.0,
        "eval/min_return_online": 10.0,
        "eval/below_teacher_online": 1 / 3,  # 10 of (30, 10, 20) below the teacher's 15
        "eval/return_average": 50.0,
        "eval/min_return_average": 40.0,
        "eval/below_teacher_average": 0.0,
    }
    evaluations(1500, 2000)
    assert evaluated == [("e", 1000), ("e", 2000)] and other == [("o", None), ("a", "avg")] * 2
    assert videos == [2000] and swapped == ["tgt"]


def test_evaluations_keep_the_actors_at_the_evaluated_actors_best_return(monkeypatch):
    """The best evaluated policy follows the evaluated actor's eval/return alone (10, 30, 20, 30: the
    second, as a tie does not replace it), whatever the other actors return, and keeps every actor's
    weights of that evaluation."""
    evaluated_returns = iter([10.0, 30.0, 20.0, 30.0])
    monkeypatch.setattr(loop, "record_evaluation", lambda *args: {"eval/return": next(evaluated_returns)})
    monkeypatch.setattr(loop, "actor_returns", lambda env, actor, weights, episodes, steps: [100.0])  # online's
    cfg = SimpleNamespace(
        eval=SimpleNamespace(actor="target", every_frames=1000, video_every_frames=0, episodes=1),
        env=SimpleNamespace(max_episode_steps=1000),
    )
    actors = {"online": TensorDict({"w": torch.zeros(1)}), "target": TensorDict({"w": torch.zeros(1)})}
    best = BestEvaluatedPolicy(actors)
    envs = {"evaluated": "e", "others": {"online": "o"}}
    evaluations = loop.Evaluations(cfg, None, actors, {}, 15.0, envs, None, best_evaluated=best)
    for frames in (1000, 2000, 3000, 4000):
        actors["online"]["w"] += 1.0  # the weights at each evaluation: frames / 1000
        actors["target"]["w"] -= 1.0
        evaluations(frames - 1000, frames)
    assert best.record() == {"frames": 2000, "periodic_eval_return": 30.0}
    assert best.params("online")["w"].tolist() == [2.0] and best.params("target")["w"].tolist() == [-2.0]


def test_eval_envs_one_per_other_actor_the_run_has():
    """eval.other_actor: an env for every actor but eval.actor: online, TD3's target, the average."""
    made = []

    def make_eval_env(cfg, seed, episodes):
        made.append((seed, episodes))
        return f"env{len(made)}"

    def cfg(learner, actor, other_actor, average_frames):
        return SimpleNamespace(
            seed=3,
            algo=SimpleNamespace(learner=learner),
            eval=SimpleNamespace(actor=actor, other_actor=other_actor, average_frames=average_frames, episodes=7),
        )

    assert loop.make_eval_envs(cfg("td3", "online", False, 5000), make_eval_env)["others"] == {}
    assert list(loop.make_eval_envs(cfg("td3", "target", True, 0), make_eval_env)["others"]) == ["online"]
    assert list(loop.make_eval_envs(cfg("td3", "average", True, 5000), make_eval_env)["others"]) == ["online", "target"]
    assert list(loop.make_eval_envs(cfg("sac", "online", True, 5000), make_eval_env)["others"]) == ["average"]
    assert set(made) == {(10_003, 7)}  # every one on the evaluation's seed, for its episodes


def test_evaluation_metrics_of_an_evaluations_episodes():
    assert evaluation_metrics([300.0, 100.0, 350.0, 250.0], teacher_return=200.0) == {
        "eval/return": 250.0,
        "eval/min_return": 100.0,
        "eval/below_teacher": 0.25,
    }
    # equal to the teacher is not below it; the other actor's tags carry its suffix
    assert evaluation_metrics([200.0, 199.0], teacher_return=200.0, suffix="_target") == {
        "eval/return_target": 199.5,
        "eval/min_return_target": 199.0,
        "eval/below_teacher_target": 0.5,
    }


def test_run_clock_starts_the_timed_part_after_warmup():
    batches = [torch.zeros(1000) for _ in range(3)]

    class Collector(list):
        total_frames = 3000

    clock = RunClock({"wall_seconds": 7.0}, 0, warmup=1000)
    seen = []
    for _ in clock.batches(Collector(batches), 0):
        seen.append(clock.train_clock is not None)
        with timeit("work"):
            pass
    # timed from the batch collected after 1000 frames: the 2nd and 3rd, then the call that finds none
    assert seen == [False, True, True] and clock.train_clock[1] == 1000
    clock.stop()
    summary = clock.summary(3000)
    assert summary["train_frames"] == 2000 and summary["counts"]["collect"] == 3 and summary["counts"]["work"] == 2
    assert clock.wall_seconds() >= 7.0


def test_run_clock_has_no_batch_for_a_finished_run():
    class Collector(list):
        total_frames = 0

    assert list(RunClock({"wall_seconds": None}, 3000).batches(Collector([1]), 3000)) == []


def test_run_checkpoint_checks_saves_then_writes_what_must_match(tmp_path):
    order = []
    run = {"evals": [], "frames": 0}

    def divergence(metrics, frame, checkpoint):
        order.append(("check", frame))

    checkpoint = SimpleNamespace(save=lambda path: order.append(("save", dict(run)["gradient_steps"])))
    clock = SimpleNamespace(wall_seconds=lambda: 3.0)
    save = RunCheckpoint(
        checkpoint,
        tmp_path,
        run,
        loggers={},
        divergence=divergence,
        clock=clock,
        after_save=[lambda: order.append(("best_policy",))],
    )
    save({}, frames=2000, gradient_steps=40)
    assert order == [("check", 2000), ("save", 40), ("best_policy",)]
    assert run["frames"] == 2000 and run["wall_seconds"] == 3.0
