"""All SAIL components composed in one TorchRL pipeline (Algorithm 1, one iteration of each step).

The unit tests check each piece in isolation; this one checks that they fit together the
way the example wires them: a Hopper-v4 env in the delayed-reward setting, the paper's
teacher file, a ``Collector``, the teacher buffer's promotion rule on collector batches,
exact-ratio mixing with discriminator rewards recomputed at sample time, one
discriminator step, one SAIL critic/actor step with target updates, and the alpha switch.
"""

from __future__ import annotations

import math

import pytest
import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import Compose, DoubleToFloat, GymEnv, InitTracker, StepCounter, TransformedEnv
from torchrl.modules import MLP, AdditiveGaussianModule, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate

from torchrl_sail import (
    TRANSITION_KEYS,
    AlphaScheduler,
    DelayedRewardTransform,
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorReward,
    MixedReplayBuffer,
    SAILLoss,
    TeacherReplayBuffer,
    TimeFeature,
    TopKTrajectoryWriter,
    check_demonstration_dims,
    load_demonstrations,
)

pytestmark = pytest.mark.filterwarnings("ignore:.*is out of date.*")

HOPPER_TEACHER = "expert_data_no_img_Hopper_scores_1500_episodes_1.npz"


def make_env():
    return TransformedEnv(
        GymEnv("Hopper-v4"),
        Compose(
            DoubleToFloat(),
            StepCounter(max_steps=1000),
            InitTracker(),
            TimeFeature(max_steps=1000),
            DelayedRewardTransform(),
        ),
    )


def make_agent(action_spec):
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(in_features=12, out_features=3, num_cells=[32, 32], activation_class=nn.ReLU),
            ["observation"],
            ["param"],
        ),
        TanhModule(["param"], ["action"], spec=action_spec),
    )
    critic = ValueOperator(
        MLP(in_features=15, out_features=1, num_cells=[32, 32], activation_class=nn.ReLU),
        in_keys=["action", "observation"],
    )
    return actor, critic


def test_sail_pipeline_one_iteration(teacher_dir):
    env = make_env()
    env.set_seed(0)

    # Teacher: the paper's Hopper demonstration, ranked by its own delayed reward.
    demos, meta = load_demonstrations(teacher_dir / HOPPER_TEACHER)
    check_demonstration_dims(demos, env=env)
    demos = DelayedRewardTransform().forward(demos)
    assert demos["next", "reward"].sum().item() == math.floor(0.1 * 1480.68823242)
    assert demos["next", "reward"][:-1].eq(0).all()
    teacher = TeacherReplayBuffer(TopKTrajectoryWriter(k=10))
    assert teacher.add_demonstrations(demos) == 1
    assert teacher.writer.threshold == 148.0

    # Collection: a random-warm-up collector; every transition goes to the agent replay,
    # every finished trajectory to the promotion test.
    actor, critic = make_agent(env.action_spec)
    policy = TensorDictSequential(actor, AdditiveGaussianModule(spec=env.action_spec, sigma_init=0.2, sigma_end=0.2))
    collector = Collector(env, policy, frames_per_batch=200, total_frames=400, init_random_frames=400)
    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(1_000))
    num_episodes = 0
    for data in collector:
        done = data["next", "done"].squeeze(-1)
        reward = data["next", "reward"].squeeze(-1)
        dense_return = data["next", "episode_return"].squeeze(-1)
        # The learner's reward is delayed: floor(0.1 R) at done, 0 elsewhere.
        assert reward[~done].eq(0).all()
        expected = torch.floor(0.1 * dense_return[done]).to(reward.dtype)
        torch.testing.assert_close(reward[done], expected)
        num_episodes += int(done.sum())
        agent.extend(data.reshape(-1))
        teacher.extend(data)
    collector.shutdown()
    assert len(agent) == 400
    # Random Hopper episodes are far below the 1480-return teacher: offered, not promoted.
    assert num_episodes > 0 and teacher.writer.num_offered == num_episodes
    assert teacher.writer.num_promoted == 0 and teacher.writer.threshold == 148.0

    # Mixing: exact 128 + 128 split, rewards recomputed by the current D at sample time.
    disc = Discriminator(12, 3)
    reward_transform = DiscriminatorReward(disc)
    mixer = MixedReplayBuffer(teacher, agent, transform=reward_transform)
    batch = mixer.sample(256, teacher_fraction=0.5)
    assert batch["is_teacher"].sum().item() == 128 and batch["is_teacher"][:128].all()
    # Only transition keys reach the learner: no dense return, no collector bookkeeping.
    assert set(batch.keys(True, True)) == set(TRANSITION_KEYS) | {"is_teacher"}
    with torch.no_grad():
        logits = disc(batch.select("observation", "action").clone())["d_logit"]
    torch.testing.assert_close(batch["next", "reward"], nn.functional.softplus(logits))

    # One discriminator step.
    d_loss = DiscriminatorLoss(disc)
    d_optim = torch.optim.Adam(disc.parameters(), lr=1e-3)
    d_out = d_loss(batch)
    d_total = sum(v for k, v in d_out.items() if k.startswith("loss_"))
    d_optim.zero_grad()
    d_total.backward()
    d_optim.step()
    assert torch.isfinite(d_total)
    # The reward follows the updated D on the next sample (no stale rewards).
    with torch.no_grad():
        new_logits = disc(batch.select("observation", "action").clone())["d_logit"]
    assert not torch.allclose(new_logits, logits)

    # One SAIL critic step and one actor step, targets updated by TorchRL's SoftUpdate.
    loss = SAILLoss(actor, critic, action_spec=env.action_spec)
    loss.make_value_estimator(gamma=0.99)
    updater = SoftUpdate(loss, tau=0.005)
    critic_optim = torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values(), lr=1e-3)
    actor_optim = torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=1e-3)
    target_before = loss.target_qvalue_network_params.clone()
    loss_q, _ = loss.value_loss(batch)
    critic_optim.zero_grad()
    loss_q.backward()
    critic_optim.step()
    loss_a, _ = loss.actor_loss(batch)
    actor_optim.zero_grad()
    loss_a.backward()
    actor_optim.step()
    updater.step()
    assert torch.isfinite(loss_q) and torch.isfinite(loss_a)
    assert (loss.target_qvalue_network_params != target_before).any()

    # Adaptive step: a trajectory beating C is promoted and the dynamic rule drops alpha to 0.
    scheduler = AlphaScheduler(loss, mode="dynamic", initial=0.5)
    assert scheduler.step(frames=400, num_promoted=teacher.writer.num_promoted) == 0.5
    better = demos.clone()
    better["next", "reward"][-1] = 200.0
    teacher.extend(better)
    assert teacher.writer.num_promoted == 1 and teacher.writer.threshold == 148.0
    assert scheduler.step(frames=400, num_promoted=teacher.writer.num_promoted) == 0.0
    assert float(loss.alpha) == 0.0 and scheduler.switched_at_frame == 400
    # alpha acts through the batch composition: with alpha = 0 the batch is all agent rows.
    batch = mixer.sample(256, teacher_fraction=float(loss.alpha))
    assert not batch["is_teacher"].any()
    assert torch.isfinite(loss(batch)["loss_qvalue"])
