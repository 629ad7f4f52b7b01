"""The typed config schema (examples/config_schema.py): the source of every default; every shipped YAML
conforms and holds only what differs from it; bad values name their key."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))
from config_schema import (
    AlgoConfig,
    EnvConfig,
    Learner,
    LRDecayConfig,
    NStepConfig,  # noqa: E402
    OptimConfig,
    PPOConfig,
    RNDConfig,
    SAILConfig,
    check_config,
    register_config_schema,
)

register_config_schema()
ALGOS = sorted(p.stem for p in (REPO / "conf" / "algo").glob("*.yaml"))
ENVS = sorted(p.stem for p in (REPO / "conf" / "env").glob("*.yaml"))


def make(*overrides: str):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def test_defaults_are_the_papers_budget_and_typed():
    cfg = make()
    assert cfg.collector.total_frames == 1_000_000  # the paper's evaluation point; the authors' code: 3M
    assert OmegaConf.get_type(cfg) is SAILConfig and OmegaConf.get_type(cfg.algo).__name__ == "AlgoConfig"
    assert cfg.algo.learner == "td3" and cfg.algo.learner is Learner.td3 and f"{cfg.algo.learner}" == "td3"
    assert OmegaConf.to_container(cfg, enum_to_str=True)["logger"]["backends"] == ["csv", "wandb"]
    assert make("collector.total_frames=3000000").collector.total_frames == 3_000_000
    assert make().network.discriminator_init == "xavier"  # the SAIL authors'; DAC's release: orthogonal
    assert make("algo=dac_published").network.discriminator_init == "orthogonal"
    bc = make("algo=bc").algo.bc  # the authors' BC: their TD3 batch, 100 epochs per demonstration episode
    assert (bc.batch_size, bc.epochs, bc.lr) == (256, 100, 1e-3)


def leaves(node, prefix: tuple = ()) -> dict:
    """``{path: value}`` of a plain mapping's leaves (an empty mapping is a leaf: it sets a block's defaults)."""
    if isinstance(node, dict) and node:
        return {key: value for name, child in node.items() for key, value in leaves(child, (*prefix, name)).items()}
    return {prefix: node}


def yaml_file(path: Path) -> tuple[dict, list]:
    """A conf/ file's values (its defaults list removed) and that defaults list."""
    data = OmegaConf.to_container(OmegaConf.load(path))
    return data, data.pop("defaults", [])


@pytest.mark.parametrize(
    "path",
    sorted((REPO / "conf" / "env").glob("*.yaml")) + sorted((REPO / "conf" / "algo").glob("*.yaml")),
    ids=lambda path: f"{path.parent.name}/{path.name}",
)
def test_yaml_files_hold_only_what_differs_from_the_schema(path):
    # One source of defaults: a value an env or method file sets is one the schema (or the method it
    # extends, e.g. pofd extends gail) does not already give.
    data, defaults = yaml_file(path)
    # the optional blocks (null by default) with their own defaults, which a file setting the block gets
    algo = AlgoConfig(rnd=RNDConfig(), ppo=PPOConfig(), nstep=NStepConfig())
    if path.read_text().startswith("# @package _global_"):  # e.g. dac_published: algo.*, env.*, optim.*, ...
        base = OmegaConf.to_container(
            OmegaConf.structured(SAILConfig(algo=algo, optim=OptimConfig(actor_lr_decay=LRDecayConfig())))
        )
    else:
        base = OmegaConf.to_container(OmegaConf.structured(EnvConfig if path.parent.name == "env" else algo))
        for parent in [entry for entry in defaults if entry != "_self_"]:
            base = OmegaConf.to_container(OmegaConf.merge(base, yaml_file(path.parent / f"{parent}.yaml")[0]))
    base = leaves(base)
    repeated = {
        ".".join(key): value
        for key, value in leaves(data).items()
        if key != ("name",) and key in base and base[key] == value
    }
    assert not repeated, f"{path.name} repeats the schema's defaults: {repeated}"


@pytest.mark.parametrize("algo", ALGOS)
def test_every_algo_conforms(algo):
    cfg = make(f"algo={algo}")
    assert cfg.algo.name == algo
    assert (cfg.algo.ppo is not None) == (cfg.algo.learner == "ppo")


@pytest.mark.parametrize("env", ENVS)
def test_every_env_conforms(env):
    cfg = make(f"env={env}")
    assert cfg.env.name == env and cfg.teacher.capacity == cfg.env.teacher_capacity


@pytest.mark.parametrize(
    "override, message",
    [
        ("optim.lr=abc", "Value 'abc' of type 'str' could not be converted to Float\n    full_key: optim.lr"),
        ("collector.total_frames=1e6", "could not be converted to Integer\n    full_key: collector.total_frames"),
        ("algo.adaptive=maybe", "Value 'maybe' is not a valid bool (type str)\n    full_key: algo.adaptive"),
        (
            "network.activation=gelu",
            "Invalid value 'gelu', expected one of [relu, tanh, elu]\n    full_key: network.activation",
        ),
        ("logger.backends=[csv,mlflow]", "Invalid value 'mlflow', expected one of [csv, wandb, tensorboard]"),
        ("network.actor_cells=[400,big]", "full_key: network.actor_cells[1]"),
        ("optim.lrr=1", "Key 'lrr' not in 'OptimConfig'\n    full_key: optim.lrr"),
        ("teacher.eviction=lru", "full_key: teacher.eviction"),
    ],
)
def test_wrong_value_names_the_key(override, message):
    with pytest.raises(ConfigCompositionException) as err:
        make(override)
    assert message in str(err.value.__cause__), str(err.value.__cause__)


def test_optional_blocks_are_typed_when_set():
    with pytest.raises(ConfigCompositionException) as err:
        make("algo=sail_rnd", "algo.rnd.features=many")
    assert "full_key: algo.rnd.features" in str(err.value.__cause__)
    assert make().algo.nstep is None and make().algo.l2_coef == 0.0  # the 1-step methods: no n-step view, no L2
    ddpgfd = make("algo=ddpgfd").algo
    assert (ddpgfd.nstep.n, ddpgfd.nstep.lambda1, ddpgfd.l2_coef) == (10, 1.0, 1e-5)
    per = ddpgfd.per
    assert (per.alpha, per.beta, per.eps, per.teacher_eps, per.action_grad_coef) == (0.3, 1.0, 1e-6, 1.0, 1.0)
    assert make().algo.per is None and make("algo=ddpgfd", "algo.per=null").algo.per is None
    with pytest.raises(ConfigCompositionException) as err:
        make("algo=ddpgfd", "algo.nstep.n=ten")
    assert "full_key: algo.nstep.n" in str(err.value.__cause__)
    cfg = make(
        "algo=sail_rnd", "algo.rnd.coef=0.5", "resume=auto", "collector.backend_options={remote_configs: {num_cpus: 1}}"
    )
    assert (
        cfg.algo.rnd.coef == 0.5 and cfg.resume == "auto" and cfg.collector.backend_options.remote_configs.num_cpus == 1
    )


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["optim.batch_size=1"], "config optim.batch_size=1: must be >= 2"),
        (["optim.gamma=1.5"], "optim.gamma=1.5: must be in (0, 1]"),
        (["resume=maybe"], "config resume='maybe': use true, false or auto"),
        (["eval.video_every_frames=-1"], "eval.video_every_frames=-1: must be >= 0 (0 disables)"),
        (["algo=dac", "algo.adaptive=true"], "absorbing states need a fixed teacher"),
        (["algo.max_promoted=0"], "algo.max_promoted=0: promotions stop once this many trajectories"),
        (["algo=sail_no_adapt", "algo.max_promoted=10"], "set it > 0, with algo.adaptive=true"),
        (["algo=sail_sac", "optim.precision=bf16"], "bf16 is TD3's fused step only"),
        (["optim.cudagraphs=true"], "config optim.cudagraphs=True: CUDA graphs replay TD3's fused step on a GPU"),
        (["algo.learner=ppo"], "algo.learner=ppo needs the PPO settings"),
        (["algo=gail", "algo.reward.source=env"], "the PPO generator (gail, pofd) learns from D's reward"),
        (["algo=pofd_td3", "algo.reward.coef_decay=0.5"], "and 1 unless algo.learner=ppo"),
        (["algo=pofd", "algo.reward.coef_decay=0"], "algo.reward.coef_decay=0.0: must be in (0, 1]"),
        (["algo.reward.shift=inf"], "algo.reward.shift=inf: must be a finite number"),
        (["optim.actor_preactivation_coef=-1e-3"], "optim.actor_preactivation_coef=-0.001: must be a finite number"),
        (["algo=sail_sac", "optim.actor_preactivation_coef=1e-3"], "and 0 unless algo.learner=td3"),
        (["algo=sail_sac", "eval.other_actor=true"], "eval.other_actor=True: needs a second actor"),
        (["eval.actor=average"], "eval.actor='average': average needs eval.average_frames > 0"),
        (["eval.average_frames=-1"], "eval.average_frames=-1: must be >= 0"),
        (["algo=gail", "eval.average_frames=10000"], "eval.average_frames=10000: is the off-policy learners'"),
        (["algo=sail_sac", "eval.actor=target"], "eval.actor='target': target is TD3's (algo.learner=td3)"),
        (["algo.alpha.initial=1.5"], "config algo.alpha.initial=1.5: must be in [0, 1] (a teacher share)"),
        (["algo=sail_no_lfd", "algo.alpha.final=-0.1"], "config algo.alpha.final=-0.1: must be in [0, 1]"),
        (["algo.alpha.mode=linear"], "config algo.alpha.anneal_frames=None: algo.alpha.mode=linear anneals over"),
        (["algo.alpha.mode=linear", "algo.alpha.anneal_frames=0"], "config algo.alpha.anneal_frames=0: algo.alpha"),
        (["eval.best_policy.window=0"], "eval.best_policy.window=0: must be >= 1"),
        (["eval.best_policy.episodes=-1"], "eval.best_policy.episodes=-1: must be >= 0"),
        (["algo=ddpgfd", "algo.nstep.n=1"], "algo.nstep.n=1: must be >= 2 (algo.nstep=null for the 1-step"),
        (["algo=ddpgfd", "algo.nstep.lambda1=0"], "algo.nstep.lambda1=0.0: must be a finite number > 0"),
        (
            ["algo=ddpgfd", "algo.adaptive=true"],
            "the n-step loss (DDPGfD) needs algo.learner=td3, algo.reward.source=env",
        ),
        (["algo=ddpgfd", "algo.reward.source=discriminator"], "the n-step loss (DDPGfD) needs"),  # sample-time reward
        (["algo=ddpgfd", "algo.l2_coef=-1e-5"], "algo.l2_coef=-1e-05: must be a finite number >= 0"),
        (["algo=bc", "algo.l2_coef=1e-5"], "and 0 unless algo.learner is td3 or sac"),
        (["algo=ddpgfd", "algo.per.eps=0"], "algo.per.eps=0.0: must be a finite number > 0 (a row of priority 0"),
        (["algo=ddpgfd", "algo.per.alpha=-0.5"], "algo.per.alpha=-0.5: must be a finite number >= 0"),
        (["algo=ddpgfd", "algo.per.action_grad_coef=inf"], "algo.per.action_grad_coef=inf: must be a finite"),
        (
            ["algo=ddpgfd", "algo.nstep=null", "algo.adaptive=true"],
            "prioritized replay (DDPGfD) needs algo.learner=td3, algo.adaptive=false",
        ),
        # a collector batch longer than D's cadence, or one that does not divide it
        (
            ["collector.frames_per_batch=1000"],
            "optim.discriminator.every_frames=500: must be a multiple of collector.frames_per_batch=1000",
        ),
        (["collector.frames_per_batch=300"], "optim.discriminator.every_frames=500: must be a multiple"),
        (["algo=td3_delayed", "collector.frames_per_batch=300"], "optim.train_every_frames=1000: must be a multiple"),
        (["algo=sail_sac", "optim.discriminator.every_frames=750"], "optim.discriminator.every_frames=750"),
        (["optim.discriminator.label_smoothing=0.5"], "optim.discriminator.label_smoothing=0.5: must be in [0, 0.5)"),
        (["optim.discriminator.instance_noise=-1"], "optim.discriminator.instance_noise=-1.0: must be a finite"),
        (["optim.discriminator.max_accuracy=1.0"], "optim.discriminator.max_accuracy=1.0: must be in [0.5, 1)"),
        (["collector.weight_sync_timeout_s=0"], "collector.weight_sync_timeout_s=0.0: must be a finite number > 0"),
    ],
)
def test_check_config_keeps_ranges_and_cross_field_rules(overrides, message):
    with pytest.raises(ValueError, match="^config ") as err:
        check_config(make(*overrides))
    assert message in str(err.value)
    check_config(make())  # the defaults pass


@pytest.mark.parametrize(
    "overrides",
    [
        ["collector.frames_per_batch=250"],  # divides both cadences
        ["algo=td3_delayed", "collector.frames_per_batch=1000"],  # no D: only the TD3 cadence counts
        ["optim.discriminator.steps=0", "collector.frames_per_batch=1000"],  # D never trained
        ["algo=gail", "collector.frames_per_batch=300"],  # PPO: D once per on-policy batch
    ],
)
def test_check_config_accepts_cadences_the_batch_divides(overrides):
    check_config(make(*overrides))


def test_check_config_accepts_a_linear_alpha_with_its_length():
    cfg = make("algo.alpha.mode=linear", "algo.alpha.anneal_frames=100000", "algo.alpha.final=1")
    check_config(cfg)
    assert (cfg.algo.alpha.initial, cfg.algo.alpha.final, cfg.algo.alpha.anneal_frames) == (0.5, 1.0, 100_000)


def test_evaluate_config_is_typed():
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=["run_dir=outputs/x"])
        assert cfg.episodes == 10 and cfg.video is False and cfg.video_format == "mp4" and cfg.export is None
        with pytest.raises(ConfigCompositionException) as err:
            compose(config_name="evaluate", overrides=["run_dir=x", "episodes=many"])
    assert "full_key: episodes" in str(err.value.__cause__)


@pytest.mark.parametrize(
    "eviction, writer, capacity",
    [
        ("topk", "TopKTrajectoryWriter", 10 * 1000),  # K slots of max_episode_steps rows
        ("union", "UnionTrajectoryWriter", None),  # the demonstrations' rows + total_frames
        ("fifo", "FIFOTrajectoryWriter", 100_000),  # env.teacher_capacity (Hopper: the authors' 1e5)
    ],
)
def test_teacher_eviction_builds_its_writer(eviction, writer, capacity):
    from utils import make_env, make_teacher

    cfg = make("env=Hopper-v4", f"teacher.eviction={eviction}", "collector.total_frames=5000")
    teacher, _, _ = make_teacher(cfg, make_env(cfg, seed=0))
    assert type(teacher.writer).__name__ == writer and teacher.writer.k == 10
    demonstration_rows = len(teacher)  # the shipped teacher: all of it admitted, nothing evicted
    assert teacher.writer.num_demonstrations >= 1 and demonstration_rows > 0
    assert teacher.writer.capacity == (demonstration_rows + 5000 if capacity is None else capacity)


def test_env_kwargs_reach_the_env_and_the_teacher_check_names_them():
    from utils import make_env, make_teacher

    cfg = make("env=Hopper-v4", "+env.kwargs.exclude_current_positions_from_observation=false")
    env = make_env(cfg, seed=0)
    assert env.observation_spec["observation"].shape[-1] == 13  # x position + 11 + time feature
    with pytest.raises(ValueError, match="env.kwargs"):  # the shipped teacher has 12 columns
        make_teacher(cfg, env)


def test_discriminator_remedies_reach_the_loss_the_net_and_the_step():
    import torch
    from tensordict import TensorDict
    from utils import discriminator_step, make_discriminator, make_discriminator_loss

    from torchrl_sail import make_sail_env

    cfg = make(
        "optim.discriminator.label_smoothing=0.1",
        "optim.discriminator.instance_noise=0.2",
        "optim.discriminator.max_accuracy=0.9",
        "network.discriminator_spectral_norm=true",
        "network.discriminator_cells=[8,8]",
    )
    check_config(cfg)
    discriminator = make_discriminator(cfg, make_sail_env("Pendulum-v1", max_episode_steps=200))
    assert discriminator.net.spectral_norm
    d_loss = make_discriminator_loss(cfg, discriminator)
    assert d_loss.label_smoothing.item() == pytest.approx(0.1) and d_loss.instance_noise.item() == pytest.approx(0.2)
    optimizer = torch.optim.Adam(discriminator.parameters(), lr=1e-2)
    tag = torch.arange(8) < 4

    def batch(separation):  # teacher rows at +separation, agent rows at -separation
        sign = torch.where(tag, 1.0, -1.0).unsqueeze(-1)
        obs = separation * sign.expand(8, 4) + 0.01 * torch.randn(8, 4)
        return TensorDict(observation=obs, action=torch.zeros(8, 1), is_teacher=tag, batch_size=[8])

    def raw_weights():
        return [p.detach().clone() for p in discriminator.parameters()]

    # overlapping sides: D steps; far apart and learned: D is past the bound and skips
    before = raw_weights()
    out = discriminator_step(cfg, d_loss, optimizer, batch(0.0))
    assert out["d/skipped"] == 0.0 and any(not torch.equal(a, b) for a, b in zip(before, raw_weights(), strict=True))
    for _ in range(200):
        out = discriminator_step(cfg, d_loss, optimizer, batch(3.0))
        if out["d/skipped"]:
            break
    assert out["d/skipped"] == 1.0
    assert (out["d/accuracy_teacher"] + out["d/accuracy_agent"]).item() / 2 > 0.9
    before = raw_weights()
    assert discriminator_step(cfg, d_loss, optimizer, batch(3.0))["d/skipped"] == 1.0
    assert all(
        torch.equal(a, b) for a, b in zip(before, raw_weights(), strict=True)
    )  # a skipped step changes no parameter
    assert all(p.grad is None for p in discriminator.parameters())


@pytest.mark.parametrize("rounding", ["floor", "none"])
def test_reward_rounding_reaches_the_env_and_the_demonstrations(rounding):
    from utils import make_env, make_teacher

    cfg = make("env=Hopper-v4", f"env.reward_rounding={rounding}")
    env = make_env(cfg, seed=0)
    teacher, teacher_return, _ = make_teacher(cfg, env)
    # the shipped Hopper teacher: one demonstration, so C is its r_e
    expected = math.floor(0.1 * teacher_return) if rounding == "floor" else 0.1 * teacher_return
    assert teacher.writer.threshold == pytest.approx(expected, rel=1e-6)
    rollout = env.rollout(1000, break_when_any_done=True)  # random actions: Hopper falls within 1000 steps
    dense_return = float(rollout["next", "episode_return"][-1])
    reward = rollout["next", "reward"].reshape(-1)
    assert reward[:-1].abs().sum() == 0  # delayed: nothing before the episode's end
    expected = math.floor(0.1 * dense_return) if rounding == "floor" else 0.1 * dense_return
    assert float(reward[-1]) == pytest.approx(expected, rel=1e-5, abs=1e-6)


def test_collector_workers_build_the_env_with_the_runs_settings(monkeypatch):
    import utils

    cfg = make("env=Hopper-v4", "env.reward_rounding=none", "collector.num_workers=2")
    seen = {}

    class Collector:  # records what TorchRL's Collector would receive, without starting workers
        def __init__(self, env, policy, **kwargs):
            seen.update(env=env, kwargs=kwargs)

        def set_seed(self, seed):
            seen["seed"] = seed

    monkeypatch.setattr(utils, "Collector", Collector)
    utils.make_collector(cfg, None, None, frames=500)
    assert seen["kwargs"]["num_collectors"] == 2 and seen["seed"] == cfg.seed + 500
    # the workers' env is this process's: the same transforms, rounding included, and the same specs
    worker_env, own_env = seen["env"](), utils.make_env(cfg, seed=0)
    try:
        assert worker_env.transform[-1].rounding == own_env.transform[-1].rounding == "none"
        assert [type(t) for t in worker_env.transform] == [type(t) for t in own_env.transform]
        assert worker_env.observation_spec == own_env.observation_spec
    finally:
        worker_env.close()
        own_env.close()


def test_ant_observes_its_contact_forces_without_paying_for_them():
    import numpy as np
    from utils import make_env

    env = make_env(make("env=Ant-v4"), seed=0)
    try:
        assert env.observation_spec["observation"].shape[-1] == 111 + 1  # the teacher's columns + time
        ant = env.base_env._env.unwrapped
        ant.reset(seed=0)
        for _ in range(30):  # the legs reach the floor: contact forces the observation carries
            ant.step(np.zeros(8))
        # Ant-v2 (the teacher's) charged nothing for them: nor does Ant-v4 with the config's weight
        assert np.abs(ant.contact_forces).sum() > 0 and ant.contact_cost == 0.0
        _, reward, *_, info = ant.step(np.zeros(8))
        assert reward == pytest.approx(info["reward_forward"] + ant.healthy_reward)  # zero action: no control cost
    finally:
        env.close()


def test_flush_denormal_reaches_torch():
    import torch
    from run_utils import set_cpu_math

    assert make().flush_denormal is True and make("flush_denormal=false").flush_denormal is False
    denormal = torch.tensor([1e-39])  # below float32's smallest normal, 1.18e-38
    threads = torch.get_num_threads()
    if not torch.set_flush_denormal(False):
        pytest.skip("this CPU has no flush-to-zero mode")
    try:
        assert (denormal * 1.0).item() != 0.0
        set_cpu_math(0, flush_denormal=True)  # 0 threads: torch's setting stays
        assert (denormal * 1.0).item() == 0.0 and torch.get_num_threads() == threads
        set_cpu_math(0, flush_denormal=False)
        assert (denormal * 1.0).item() != 0.0
        # with 2 threads, an op large enough to be split across torch's intra-op workers flushes on each
        large = torch.full((1 << 20,), 1e-39)
        set_cpu_math(2, flush_denormal=True)
        assert torch.get_num_threads() == 2 and not (large * 1.0).any()
    finally:
        torch.set_flush_denormal(False)  # torch's default, for the tests after this one
        torch.set_num_threads(threads)


def test_actor_saturation_on_the_agent_rows():
    import torch
    from tensordict import TensorDict
    from utils import actor_saturation, make_agent

    from torchrl_sail import make_sail_env

    cfg = make("network.actor_cells=[4]")
    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    actor, _, _ = make_agent(cfg, env)
    mlp = actor.module[0].module
    with torch.no_grad():  # pre-tanh x = the observation's first entry
        for p in mlp.parameters():
            p.zero_()
        mlp[0].weight[0, 0] = 1.0
        mlp[-1].weight[0, 0] = 1.0
    obs = torch.zeros(6, env.observation_spec["observation"].shape[-1])
    obs[:, 0] = torch.tensor([0.5, 2.0, 3.0, 0.0, 100.0, 100.0])  # |x| >= atanh(0.99) = 2.647: 3.0 and the teacher's
    batch = TensorDict(observation=obs, is_teacher=torch.tensor([False] * 4 + [True] * 2), batch_size=[6])
    out = actor_saturation(cfg, actor, batch)  # teacher rows (100.0) left out
    assert out["actor/saturation"].item() == pytest.approx(1 / 4)  # agent x: 0.5, 2.0, 3.0, 0.0
    assert out["actor/preactivation"].item() == pytest.approx((0.5 + 2.0 + 3.0 + 0.0) / 4)
    assert all(v.item() == 0.0 for v in actor_saturation(cfg, actor, batch[4:]).values())  # no agent row: finite
    every = actor_saturation(cfg, actor, batch.exclude("is_teacher"))  # no teacher flag: every row is the agent's
    assert every["actor/saturation"].item() == pytest.approx(3 / 6)
    assert every["actor/preactivation"].item() == pytest.approx((0.5 + 2.0 + 3.0 + 0.0 + 100.0 + 100.0) / 6)
    assert actor_saturation(make("algo=sail_sac"), actor, batch) == {}  # SAC's actor has no pre-tanh action


def test_target_actor_evaluation_swaps_the_weights_in_and_back():
    """actor_returns(weights=target's) runs the actor with the loss's target weights, then restores the
    actor's, and leaves the loss's target tensors the same objects (what the run saves and Polyak-updates)."""
    import copy

    import torch
    from run_utils import actor_returns, evaluate
    from tensordict import TensorDict
    from utils import make_agent, make_discriminator, make_losses

    from torchrl_sail import make_sail_env

    cfg = make()
    env = make_sail_env("Pendulum-v1", max_episode_steps=20)
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    with torch.no_grad():  # a target actor other than the actor
        for value in loss.target_actor_network_params.values(True, True):
            value.add_(0.5)
    online = TensorDict.from_module(actor).flatten_keys(".")
    target = loss.target_actor_network_params.flatten_keys(".")
    online_ids = {key: id(value) for key, value in online.items()}
    target_ids = {key: (id(value), type(value)) for key, value in target.items()}
    # the reference: a copy of the actor holding the target weights
    reference = copy.deepcopy(actor)
    loss.target_actor_network_params.to_module(reference)

    env.set_seed(0)
    swapped = sum(actor_returns(env, actor, loss.target_actor_network_params, 2, 20)) / 2
    env.set_seed(0)
    assert swapped == evaluate(env, reference, 2, 20)
    env.set_seed(0)
    assert evaluate(env, actor, 2, 20) != swapped  # the actor's own weights are back
    after = TensorDict.from_module(actor).flatten_keys(".")
    assert {key: id(value) for key, value in after.items()} == online_ids
    after_target = loss.target_actor_network_params.flatten_keys(".")
    assert {key: (id(value), type(value)) for key, value in after_target.items()} == target_ids


def test_evaluations_act_with_the_td3_actor_as_one_module():
    """evaluate_episodes steps a TD3 actor as one module (TD3ExplorationPolicy without noise): the
    episodes are those of TorchRL's own rollout with the actor's sequence; SAC's actor is used as it is."""
    import torch
    from run_utils import evaluate_episodes, one_module_policy
    from torchrl.envs import ExplorationType, set_exploration_type
    from utils import make_agent

    from torchrl_sail import TD3ExplorationPolicy, make_sail_env

    env = make_sail_env("Pendulum-v1", max_episode_steps=20)
    actor = make_agent(make(), env)[0]
    policy = one_module_policy(actor)
    assert isinstance(policy, TD3ExplorationPolicy) and policy.noise is None and policy.mlp is actor.module[0].module
    env.set_seed(0)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        reference = env.rollout(20, actor, break_when_any_done=True)
    env.set_seed(0)
    episode = evaluate_episodes(env, actor, 1, 20, keep_rollouts=True)[0]
    assert torch.equal(episode["rollout"]["action"], reference["action"])
    assert episode["dense_return"] == float(reference["next", "episode_return"][-1])
    sac_actor = make_agent(make("algo=sail_sac"), env)[0]
    assert one_module_policy(sac_actor) is sac_actor


def test_episodes_at_once_are_those_of_envs_seeded_alike():
    """On a batched env, evaluate_episodes plays one episode per env: env i's starts where the episode of
    one env seeded i * SEED_STRIDE does, and is that episode (its r_e, length and steps; its return up to
    the batched forward pass's rounding), whether it ends before max_steps (52) or is cut by it (53:
    54 and 55 steps long uncut); an env that ended is not read again. The next evaluation's episodes
    start where each single env's second does: the resets of the envs that ended early and stepped on
    do not shift them."""
    import torch
    from run_utils import evaluate_episodes
    from utils import make_agent

    from torchrl_sail.envs import SEED_STRIDE, make_sail_env

    torch.manual_seed(0)
    actor = make_agent(make("env=Walker2d-v4"), make_sail_env("Walker2d-v4"))[0]
    alone, second = [], []
    for i in range(4):
        env = make_sail_env("Walker2d-v4")
        env.set_seed(i * SEED_STRIDE)
        alone += evaluate_episodes(env, actor, 1, 53, keep_rollouts=True)
        second += evaluate_episodes(env, actor, 1, 53, keep_rollouts=True)
    batched = make_sail_env("Walker2d-v4", num_envs=4)
    batched.set_seed(0)
    at_once = evaluate_episodes(batched, actor, 4, 53, keep_rollouts=True)
    then = evaluate_episodes(batched, actor, 4, 53, keep_rollouts=True)
    assert [e["length"] for e in at_once] == [e["length"] for e in alone] == [53, 53, 52, 52]
    # r_e = floor(0.1 R) where an episode ends (R of 12-14): 1; none for the cut ones
    assert [e["delayed_reward"] for e in at_once] == [e["delayed_reward"] for e in alone] == [0.0, 0.0, 1.0, 1.0]
    for mine, reference in zip(at_once + then, alone + second, strict=True):
        start, reference_start = mine["rollout"]["observation"][0], reference["rollout"]["observation"][0]
        assert torch.equal(start, reference_start)  # the same start state, exactly
        assert mine["dense_return"] == pytest.approx(reference["dense_return"], rel=1e-2)
        assert mine["rollout"].batch_size == reference["rollout"].batch_size
        torch.testing.assert_close(mine["rollout"]["next", "done"], reference["rollout"]["next", "done"])
    # the second evaluation's start states are not the first's
    assert not any(
        torch.equal(a["rollout"]["observation"][0], b["rollout"]["observation"][0])
        for a, b in zip(alone, second, strict=True)
    )
    with pytest.raises(ValueError, match=r"batch_size \(4,\) for 3 episodes"):
        evaluate_episodes(batched, actor, 3, 53)


@pytest.mark.parametrize("fixed", [True, False])
def test_sac_temperature_fixed_as_the_authors_or_learned(fixed):
    import torch
    from utils import make_agent, make_discriminator, make_losses, make_optimizers

    from torchrl_sail import make_sail_env

    cfg = make("algo=sail_sac", *([] if fixed else ["algo.sac.fixed_alpha=false", "algo.sac.alpha_init=1.0"]))
    check_config(cfg)
    assert cfg.network.actor_cells == [256, 256] == cfg.network.critic_cells  # the authors' CustomSACPolicy
    assert make("algo=sail_sac", "env=HalfCheetah-v4").optim.tau == 0.01 and cfg.optim.tau == 0.005
    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    actor, critic, _ = make_agent(cfg, env)
    discriminator = make_discriminator(cfg, env)
    loss = make_losses(cfg, actor, critic, discriminator, env.action_spec)[0]
    optimizers = make_optimizers(cfg, loss, discriminator)
    # the authors' 0.01, a buffer no optimizer steps; learned: a parameter from TorchRL's 1.0 with its Adam
    assert loss.log_alpha.detach().exp().item() == pytest.approx(0.01 if fixed else 1.0)
    assert isinstance(loss.log_alpha, torch.nn.Parameter) is (not fixed) and ("alpha" in optimizers) is (not fixed)


def test_actor_lr_sets_the_actors_adam_alone_and_its_decay_starts_from_it():
    """optim.actor_lr=3e-4: the actor's Adam at 3e-4, the critic's at optim.lr (1e-3); null: both at
    optim.lr. With optim.actor_lr_decay (dac_published's, at rate 0.5 every 1000 frames) the TD3 block's
    decay starts from the actor's rate: 3e-4 * 0.5 ** 2 = 7.5e-5 at 2500 frames."""
    from loop import make_td3_block
    from torchrl.objectives import SoftUpdate
    from utils import make_agent, make_discriminator, make_losses, make_optimizers

    from torchrl_sail import make_sail_env

    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    decay = ("algo=dac_published", "optim.actor_lr_decay.rate=0.5", "optim.actor_lr_decay.every_frames=1000")
    for overrides, expected in ((decay, 1e-3), ((*decay, "optim.actor_lr=3e-4"), 3e-4)):
        cfg = make(*overrides)
        check_config(cfg)
        actor, critic, _ = make_agent(cfg, env)
        discriminator = make_discriminator(cfg, env)
        loss = make_losses(cfg, actor, critic, discriminator, env.action_spec)[0]
        optimizers = make_optimizers(cfg, loss, discriminator)
        assert [group["lr"] for group in optimizers["actor"].param_groups] == [expected]
        assert [group["lr"] for group in optimizers["critic"].param_groups] == [1e-3]
        targets = SoftUpdate(loss, tau=cfg.optim.tau)
        block = make_td3_block(cfg, None, None, actor, loss, None, optimizers, gradient_steps=0, target_updater=targets)
        assert block.lr_decay(2500) == {"sail/actor_lr": pytest.approx(expected / 4)}
        assert optimizers["actor"].param_groups[0]["lr"] == pytest.approx(expected / 4)
        assert optimizers["critic"].param_groups[0]["lr"] == 1e-3
    with pytest.raises(ValueError, match=r"optim.actor_lr=0.0: must be > 0 or null"):
        check_config(make("algo=sail", "optim.actor_lr=0"))


def test_sac_temperature_must_be_positive():
    with pytest.raises(ValueError, match=r"algo.sac.alpha_init=0.0: must be a finite number > 0"):
        check_config(make("algo=sail_sac", "algo.sac.alpha_init=0"))


def test_sails_default_is_the_trusted_default_on_every_td3_variant_and_no_other_method():
    """conf/algo/sail.yaml sets the pre-tanh penalty and the target actor; the SAIL variants on TD3 extend
    it, each with its own name and settings; SAC (no target actor) and the baselines keep the schema's."""
    for algo in ("sail", "sail_no_adapt", "sail_no_lfd", "sail_onpolicy", "sail_rnd"):
        cfg = make(f"algo={algo}")
        check_config(cfg)
        assert cfg.algo.name == algo and cfg.optim.actor_preactivation_coef == 0.001 and cfg.eval.actor == "target"
    assert make("algo=sail_no_adapt").algo.adaptive is False and make("algo=sail_no_lfd").algo.alpha.initial == 0.0
    assert make("algo=sail_rnd").algo.rnd is not None
    assert make("algo=sail_onpolicy").algo.discriminator_agent_data == "recent"
    for algo in ("sail_sac", "dac", "dac_published", "td3_delayed", "ddpgfd", "pofd_td3", "gail", "pofd", "bc"):
        cfg = make(f"algo={algo}")
        assert (cfg.optim.actor_preactivation_coef, cfg.eval.actor) == (0.0, "online"), algo
    # the authors' settings, on the command line
    cfg = make("optim.actor_preactivation_coef=0", "eval.actor=online")
    assert (cfg.optim.actor_preactivation_coef, cfg.eval.actor) == (0.0, "online")


def test_actor_preactivation_coef_reaches_the_loss():
    from utils import make_agent, make_discriminator, make_losses

    from torchrl_sail import make_sail_env

    cfg = make("optim.actor_preactivation_coef=0.001")
    check_config(cfg)
    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    assert loss.preactivation_coef == 0.001 and loss.preactivation_key == "param"


@pytest.mark.parametrize("overrides, activation", [((), "ReLU"), (("algo.rnd.activation=tanh",), "Tanh")])
def test_rnd_networks_take_their_activation(overrides, activation):
    """RND's target and predictor: ReLU hidden layers (RND's and the SAIL authors' dormant code), tanh on
    request (what RND runs saved before the setting ran with)."""
    from utils import make_rnd

    from torchrl_sail import make_sail_env

    cfg = make("algo=sail_rnd", *overrides)
    check_config(cfg)
    rnd, _ = make_rnd(cfg, make_sail_env("Pendulum-v1", max_episode_steps=200))
    for net in (rnd.target_network, rnd.predictor_network):
        layers = [type(layer).__name__ for layer in net]
        assert layers == ["Linear", activation, "Linear", activation, "Linear"], layers
        assert [layer.out_features for layer in net if type(layer).__name__ == "Linear"] == [256, 256, 64]


def test_critic_layer_norm_puts_a_layer_norm_after_each_hidden_layer_of_the_critic_alone():
    """RLPD's critic: Linear -> LayerNorm -> ReLU per hidden layer; the actor is unchanged, and the
    fused TD3 step takes the norm (checked equal to the loss's own step in test_td3_update.py)."""
    from torch import nn
    from torchrl.objectives import SoftUpdate
    from utils import make_agent, make_discriminator, make_losses, make_optimizers, make_update

    from torchrl_sail import TD3Update, make_sail_env

    cfg = make("network.critic_layer_norm=true")
    check_config(cfg)
    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    actor, critic, _ = make_agent(cfg, env)
    layers = list(critic.module)
    assert [type(layer) for layer in layers] == [nn.Linear, nn.LayerNorm, nn.ReLU] * 2 + [nn.Linear]
    assert [layer.normalized_shape for layer in layers if isinstance(layer, nn.LayerNorm)] == [(400,), (300,)]
    assert not any(isinstance(module, nn.LayerNorm) for module in actor.modules())
    assert not any(isinstance(module, nn.LayerNorm) for module in make_agent(make(), env)[1].modules())
    loss, *_ = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)
    optimizers = make_optimizers(cfg, loss, make_discriminator(cfg, env))
    update = make_update(cfg, loss, optimizers, SoftUpdate(loss, tau=cfg.optim.tau))
    assert isinstance(update, TD3Update) and update.implementation == "fused"


@pytest.mark.parametrize(
    "overrides, normalization",
    [((), "sum"), (("algo=ddpgfd",), "count"), (("algo=ddpgfd", "algo.per.weight_normalization=sum"), "sum")],
)
def test_the_prioritized_weights_normalization_reaches_the_loss(overrides, normalization):
    """DDPGfD's losses reduce its importance weights as PER does (mean of w l) unless told TorchRL's way."""
    from utils import make_agent, make_discriminator, make_losses

    from torchrl_sail import make_sail_env

    cfg = make(*overrides)
    check_config(cfg)
    env = make_sail_env("Pendulum-v1", max_episode_steps=200)
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    assert loss.weight_normalization == normalization
    with pytest.raises(Exception, match="weight_normalization"):
        make("algo=ddpgfd", "algo.per.weight_normalization=max")


def _td3_loss():
    from utils import make_agent, make_discriminator, make_losses

    from torchrl_sail import make_sail_env

    cfg = make()
    env = make_sail_env("Pendulum-v1", max_episode_steps=20)
    actor, critic, _ = make_agent(cfg, env)
    return actor, make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0], env


def test_best_policy_keeps_the_weights_at_the_best_window_mean_and_resumes(tmp_path):
    """The authors' rule on hand-computed window means: compared only at multiples of every_frames,
    a strictly higher mean keeps the actor's and the target actor's weights of that moment; the
    state survives a checkpoint, and best_policy.pt loads into another loss."""
    import torch
    from run_utils import BestPolicy, actor_weights, load_kept_policy
    from torchrl.checkpoint import Checkpoint

    actor, loss, _ = _td3_loss()
    best = BestPolicy(actor_weights(loss), every_frames=1000, window=3)

    def shift(value):
        with torch.no_grad():
            for params in (loss.actor_network_params, loss.target_actor_network_params):
                for tensor in params.values(True, True):
                    tensor.add_(value)

    def first_weight(params):
        return next(iter(params.values(True, True))).flatten()[0].item()

    weights = {}  # the first actor weight at each frame
    steps = [
        # (returns ended in the batch, frames): window, mean at a multiple of 1000, kept?
        ([10.0], 500, False),  # 500: no comparison
        ([20.0], 1000, True),  # (10, 20): 15 -> kept
        ([90.0], 1500, False),  # no comparison, though the mean (40) is higher
        ([], 2000, True),  # (10, 20, 90): 40 -> kept
        ([0.0, 20.0], 3000, False),  # (90, 0, 20): 36.7 < 40
        ([100.0], 4000, False),  # (0, 20, 100): 40, not strictly higher
    ]
    before = 0
    for returns, frames, kept in steps:
        shift(1.0)
        weights[frames] = first_weight(loss.actor_network_params)
        assert best.observe(torch.tensor(returns), before=before, frames=frames) is kept, frames
        before = frames
    assert (best.frames, best.score) == (2000, 40.0)
    assert first_weight(best.params("online")) == pytest.approx(weights[2000])  # the weights of frame 2000
    assert first_weight(best.params("target")) != first_weight(loss.target_actor_network_params)  # not the last
    kept_target = best.kept["target_actor"].clone()
    Checkpoint(best_policy=best).save(tmp_path / "ckpt")
    best.write(tmp_path / "best_policy.pt")

    _, other_loss, _ = _td3_loss()
    resumed = BestPolicy(actor_weights(other_loss), every_frames=1000, window=3)
    Checkpoint(best_policy=resumed).load(tmp_path / "ckpt")
    assert (resumed.frames, resumed.score, resumed.returns) == (2000, 40.0, [0.0, 20.0, 100.0])
    assert (resumed.kept["target_actor"] == kept_target).all()
    record = load_kept_policy(tmp_path / "best_policy.pt", other_loss, "target")
    assert record == {"frames": 2000, "train_return_mean": 40.0, "window": 3}
    assert (other_loss.actor_network_params.data == kept_target).all()
    with pytest.raises(FileNotFoundError, match="none.pt: no such kept policy"):
        load_kept_policy(tmp_path / "none.pt", other_loss, "online")


def test_best_policy_loads_the_state_of_a_checkpoint_that_named_its_score_mean():
    """A BestPolicy checkpointed before KeptPolicy held its best window mean as "mean"."""
    from run_utils import BestPolicy, actor_weights

    _, loss, _ = _td3_loss()
    state = BestPolicy(actor_weights(loss), every_frames=500, window=3).state_dict()
    state["mean"] = state.pop("score")
    state.update(mean=42.0, frames=1500, returns=[40.0, 44.0])
    resumed = BestPolicy(actor_weights(loss), every_frames=500, window=3)
    resumed.load_state_dict(state)
    assert (resumed.score, resumed.frames, resumed.returns) == (42.0, 1500, [40.0, 44.0])


def test_best_policy_writes_nothing_before_a_training_episode_ends(tmp_path):
    import torch
    from run_utils import BestPolicy, actor_weights

    _, loss, _ = _td3_loss()
    best = BestPolicy(actor_weights(loss), every_frames=500, window=100)
    assert best.observe(torch.tensor([]), before=0, frames=500) is False
    best.write(tmp_path / "best_policy.pt")
    assert not (tmp_path / "best_policy.pt").exists() and best.record()["frames"] is None


def test_actor_average_is_uniform_then_exponential_in_frames_and_resumes(tmp_path):
    """Hand-computed: nothing before start; the batch that reaches start (whose learning block has
    run) copies the actor; then the uniform average of the weights since start while
    n / (frames - start) is the larger step; then 1 - exp(-n / memory_frames). The state survives a
    checkpoint."""
    import math

    import torch
    from run_utils import ActorAverage
    from tensordict import TensorDict
    from torchrl.checkpoint import Checkpoint

    live = TensorDict({"layer": {"w": torch.zeros(2)}})
    average = ActorAverage(live, memory_frames=2000, start=1000)
    steps = [
        # (the actor's weight, before, frames, the average after)
        (1.0, 0, 500, 0.0),  # before start: unchanged
        (2.0, 500, 1000, 2.0),  # the batch that reaches start: the actor's weights
        (3.0, 1000, 1500, 3.0),  # 500 frames since start: step 500/500 (the uniform average of one)
        (5.0, 1500, 2500, (500 * 3.0 + 1000 * 5.0) / 1500),  # step 1000/1500 > 1 - exp(-0.5)
        (10.0, 2500, 6500, None),  # step 1 - exp(-2) = 0.865 > 4000/5500 = 0.727
    ]
    for weight, before, frames, expected in steps:
        live["layer", "w"].fill_(weight)
        average.update(before=before, frames=frames)
        if expected is None:
            expected = 13 / 3 - math.expm1(-2.0) * (10.0 - 13 / 3)
        assert average.weights["layer", "w"].tolist() == pytest.approx([expected] * 2), frames
    assert live["layer", "w"].tolist() == [10.0, 10.0]  # the actor's own weights are untouched
    Checkpoint(actor_average=average).save(tmp_path / "ckpt")
    resumed = ActorAverage(TensorDict({"layer": {"w": torch.ones(2)}}), memory_frames=2000, start=1000)
    Checkpoint(actor_average=resumed).load(tmp_path / "ckpt")
    assert torch.equal(resumed.weights["layer", "w"], average.weights["layer", "w"])


def test_a_sac_run_has_the_online_and_averaged_actors_and_no_target():
    """SACLoss answers target_actor_network_params with the actor's own weights: not a target actor."""
    from run_utils import actor_names, actor_weights, make_actor_average
    from utils import make_agent, make_discriminator, make_losses

    from torchrl_sail import make_sail_env

    cfg = make("algo=sail_sac", "eval.average_frames=5000", "eval.other_actor=true")
    env = make_sail_env("Pendulum-v1", max_episode_steps=20)
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    actors = actor_weights(loss, make_actor_average(cfg, loss))
    assert list(actors) == actor_names(cfg) == ["online", "average"]


def test_best_policy_keeps_the_averaged_actor_and_loads_it(tmp_path):
    """With an averaged actor, the best policy keeps its weights too, and best_policy.pt loads them
    by eval.actor's name average."""
    import torch
    from run_utils import ActorAverage, BestPolicy, actor_weights, load_kept_policy

    _, loss, _ = _td3_loss()
    average = ActorAverage(loss.actor_network_params, memory_frames=1000, start=0)
    with torch.no_grad():
        average.weights.apply_(lambda tensor: tensor.fill_(0.25))
    actors = actor_weights(loss, average)
    assert list(actors) == ["online", "target", "average"]
    best = BestPolicy(actors, every_frames=500, window=2)
    assert best.observe(torch.tensor([1.0]), before=0, frames=500)
    with torch.no_grad():
        average.weights.apply_(lambda tensor: tensor.fill_(0.5))  # after the keep: not in the kept copy
    assert all((value == 0.25).all() for value in best.params("average").values(True, True))
    best.write(tmp_path / "best_policy.pt")
    _, other_loss, _ = _td3_loss()
    load_kept_policy(tmp_path / "best_policy.pt", other_loss, "average")
    assert all((value == 0.25).all() for value in other_loss.actor_network_params.values(True, True))
    plain = BestPolicy(actor_weights(loss), every_frames=500, window=2)
    plain.observe(torch.tensor([1.0]), before=0, frames=500)
    plain.write(tmp_path / "plain.pt")
    with pytest.raises(ValueError, match="holds no average actor"):
        load_kept_policy(tmp_path / "plain.pt", other_loss, "average")


def test_actor_drift_measures_the_blocks_change_and_the_target_gap():
    """actor/change: mean |a_after - a_before| on the batch's observations; actor/target_gap: mean
    |a - a_target| after the block, each against actions computed by hand from the weights."""
    import torch
    from tensordict import TensorDict
    from utils import ActorDrift

    actor, loss, env = _td3_loss()
    batch = TensorDict({"observation": torch.randn(8, env.observation_spec["observation"].shape[-1])}, [8])
    drift = ActorDrift(actor, loss)
    drift.start(batch)
    with torch.no_grad():
        before = actor(batch.clone())["action"]
        for tensor in loss.actor_network_params.values(True, True):  # the "block": a change of the weights
            tensor.add_(0.05 * torch.randn_like(tensor))
        after = actor(batch.clone())["action"]
        with loss.target_actor_network_params.to_module(actor, preserve_module_state=False):
            target = actor(batch.clone())["action"]
    measured = drift.measure()
    assert measured["actor/change"].item() == pytest.approx((after - before).abs().mean().item(), rel=1e-6)
    assert measured["actor/target_gap"].item() == pytest.approx((after - target).abs().mean().item(), rel=1e-6)
    assert measured["actor/change"].item() > 0
    drift.start(batch)
    assert drift.measure()["actor/change"].item() == 0.0  # no update in between


def test_dac_published_trains_after_each_episode_d_first_and_gail_has_torchrls_discriminator():
    dac = make("algo=dac_published")
    # per-(method, env) files: the release's replay never evicts; the SAIL authors' DAC on Ant, [64, 64]
    assert make("algo=dac_published", "env=Swimmer-v5").env.replay_size == 1_000_000
    assert make("algo=dac", "env=Swimmer-v4").env.replay_size == 10_000
    ant = make("algo=dac", "env=Ant-v4").network
    assert ant.actor_cells == [64, 64] == ant.critic_cells
    assert make("algo=sail", "env=Ant-v4").network.actor_cells == [400, 300]
    assert (dac.optim.cadence, dac.optim.block_order, dac.optim.start_frames) == (
        "episodes",
        "discriminator_first",
        1000,
    )
    # one D step and one TD3 step per frame of each episode
    assert dac.optim.updates_per_train / dac.optim.train_every_frames == 1.0
    assert dac.optim.discriminator.steps / dac.optim.discriminator.every_frames == 1.0
    cheetah = make("algo=dac_published", "env=HalfCheetah-v4")
    assert (cheetah.collector.init_random_frames, cheetah.optim.start_frames) == (10_000, 1000)  # learning from 1000
    # the release's first actor step is critic step 1002 (its check reads the count before the step,
    # >= 1000, on even counts); the release's orthogonal networks
    assert dac.optim.actor_updates_after == 1001 and dac.optim.policy_delay == 2
    assert dac.collector.random_until_actor and not make().collector.random_until_actor  # sample_random
    for overrides in (("collector.num_workers=2",), ("algo=sail_sac",)):
        with pytest.raises(ValueError, match=r"config collector.random_until_actor=True: the random episodes end"):
            check_config(make("collector.random_until_actor=true", *overrides))
    assert (dac.network.actor_critic_init, dac.network.discriminator_init) == ("orthogonal", "orthogonal")
    check_config(dac)
    with pytest.raises(ValueError, match=r"config optim.cadence='episodes': .*collector.num_workers=1"):
        check_config(make("algo=dac_published", "collector.num_workers=2", "collector.frames_per_batch=50"))
    with pytest.raises(ValueError, match=r"config optim.start_frames=-1: must be >= 0"):
        check_config(make("optim.start_frames=-1"))
    for algo in ("gail", "pofd"):
        cfg = make(f"algo={algo}")
        d = cfg.optim.discriminator
        assert (list(cfg.network.discriminator_cells), cfg.network.discriminator_activation) == ([128, 128], "relu")
        assert (cfg.network.discriminator_init, cfg.network.normalize_observations) == ("torch", False)
        assert (d.lr, d.steps, d.batch_size, d.gp_coef, d.entropy_coef) == (3e-4, 1, 256, 0.0, 0.0)
    assert make("algo=pofd").algo.reward.source == "shaped" and make("algo=pofd").algo.name == "pofd"


def test_actor_critic_init_is_the_layers_own_by_default_and_the_authors_glorot_on_request():
    """network.actor_critic_init: "torch" (the default) leaves the layers as nn.Linear made them, the
    same weights from the same seed; "xavier" gives Glorot-uniform weights within sqrt(6 / (fan_in +
    fan_out)) and zero biases in every linear layer of the actor and the critic, the exploration
    policy's included (it holds the actor's modules); "orthogonal" orthonormal rows or columns, the
    actor's output layer scaled to 0.01 (Kostrikov et al.'s release)."""
    import torch
    from config_schema import LayerInit
    from torch import nn
    from utils import _make_agent, make_agent

    from torchrl_sail import make_sail_env
    from torchrl_sail.modules.init import LINEAR_INITS

    assert {choice.value for choice in LayerInit} == set(LINEAR_INITS)
    env = make_sail_env("Pendulum-v1", max_episode_steps=20)  # observation 3 + time feature, action 1

    def linears(*modules):
        return [layer for module in modules for layer in module.modules() if isinstance(layer, nn.Linear)]

    torch.manual_seed(0)
    actor, critic, _ = make_agent(make(), env)
    torch.manual_seed(0)
    built, _, _ = _make_agent(make(), env)  # the networks as built, before any init
    assert make().network.actor_critic_init == "torch"
    assert all(torch.equal(a.weight, b.weight) for a, b in zip(linears(actor), linears(built), strict=True))
    assert all(layer.bias.abs().sum() > 0 for layer in linears(actor, critic))

    actor, critic, policy = make_agent(make("network.actor_critic_init=xavier"), env)
    layers = linears(actor, critic)
    assert [tuple(layer.weight.shape) for layer in layers] == [
        (400, 4),
        (300, 400),
        (1, 300),
        (400, 5),
        (300, 400),
        (1, 300),
    ]
    for layer in layers:
        fan_out, fan_in = layer.weight.shape
        assert layer.weight.abs().max() <= math.sqrt(6 / (fan_in + fan_out)) and not layer.bias.any()
    # a uniform law on +-b has std b / sqrt(3): sqrt(2 / (fan_in + fan_out)) = 0.0544 for 400 x 300
    assert layers[1].weight.std().item() == pytest.approx(math.sqrt(2 / 700), rel=0.02)
    assert linears(policy)[0] is layers[0]

    actor, critic, _ = make_agent(make("network.actor_critic_init=orthogonal"), env)
    first, output = linears(actor)[0].weight, linears(actor)[-1].weight  # 400 x 4: orthonormal columns
    torch.testing.assert_close(first.T @ first, torch.eye(4), atol=1e-5, rtol=0)
    # the release's actor output layer (1 x 300) at gain 0.01: a row of norm 0.01; the critic's at gain 1
    assert output.norm().item() == pytest.approx(0.01, rel=1e-5)
    assert linears(critic)[-1].weight.norm().item() == pytest.approx(1.0, rel=1e-5)
    with pytest.raises(ConfigCompositionException):
        make("network.actor_critic_init=kaiming")


def test_the_loss_trains_critics_drawn_by_the_orthogonal_init():
    """TD3Loss given one critic redraws both twins uniformly between its extreme weights, about
    twice an orthogonal draw's spread; algo=dac_published (orthogonal, as Kostrikov et al.'s release)
    hands the loss two critics, each orthogonal: W^T W = I for a 400 x 16 first layer (Hopper's 11
    observations, the time feature, the absorbing indicator and 3 actions), entries of std
    1 / sqrt(400) = 0.05, zero biases, two different draws, and targets equal to them."""
    import torch
    from utils import make_agent, make_discriminator, make_env, make_losses

    cfg = make("algo=dac_published", "env=Hopper-v4")
    env = make_env(cfg, 0)
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    params = loss.qvalue_network_params.flatten_keys()
    targets = loss.target_qvalue_network_params.flatten_keys()
    weights = [key for key in params.keys() if key.endswith("weight")]
    assert [tuple(params[key].shape) for key in weights] == [(2, 400, 16), (2, 300, 400), (2, 1, 300)]
    first = params[weights[0]].data
    for twin in first:
        torch.testing.assert_close(twin.T @ twin, torch.eye(16), atol=1e-5, rtol=0)
    assert first.std().item() == pytest.approx(1 / math.sqrt(400), rel=0.02)
    assert not torch.equal(first[0], first[1])
    for key in params.keys():
        assert torch.equal(params[key].data, targets[key].data)
        if key.endswith("bias"):
            assert not params[key].data.any()


@pytest.mark.parametrize("version", ["v4", "v5"])
def test_halfcheetah_action_noise_of_each_td3_method(version):
    """SAIL's HalfCheetah runs without action noise (the authors' sail.yml); the TD3 baselines that
    explore by it get the authors' DAC value 0.1 there (conf/algo_env), and elsewhere SAIL's."""
    noise = {
        algo: make(f"algo={algo}", f"env=HalfCheetah-{version}").env.exploration_noise
        for algo in ("sail", "sail_rnd", "dac", "dac_published", "ddpgfd")
    }
    assert noise == {"sail": 0.0, "sail_rnd": 0.0, "dac": 0.1, "dac_published": 0.1, "ddpgfd": 0.1}
    assert make("algo=ddpgfd", f"env=Walker2d-{version}").env.exploration_noise == 0.1
    assert make("algo=ddpgfd", "env=Hopper-v4").env.exploration_noise == 0.2


def test_reset_linears_refuses_an_unknown_init_by_name():
    from torch import nn

    from torchrl_sail.modules.init import reset_linears

    with pytest.raises(ValueError, match="init='kaiming': must be one of"):
        reset_linears(nn.Linear(2, 2), "kaiming")


def test_dac_published_critic_reads_the_zero_action_at_the_absorbing_state():
    """Kostrikov et al.'s release zeroes the noisy target action at the absorbing state s_a: the
    algo=dac_published critic reads action 0 wherever the observation is s_a (indicator 1), whatever
    action it is given, and the given action elsewhere. So the TD target at s_a is Q'(s_a, 0) whatever
    TD3's target noise draws, while at other next states the noise moves it."""
    import torch
    from tensordict import TensorDict
    from utils import make_agent, make_discriminator, make_env, make_losses

    cfg = make("algo=dac_published", "env=Hopper-v4")
    env = make_env(cfg, 0)
    n_obs, n_act = env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]
    assert n_obs == 11 + 1 + 1  # Hopper's, the time feature, the absorbing indicator
    actor, critic, _ = make_agent(cfg, env)
    torch.manual_seed(0)
    obs = torch.randn(4, n_obs)
    obs[:2] = 0.0
    obs[:2, -1] = 1.0  # rows 0-1: s_a
    obs[2:, -1] = 0.0
    action = torch.rand(4, n_act) * 2 - 1

    def q(a):
        return critic(TensorDict(observation=obs, action=a, batch_size=[4]))["state_action_value"]

    given, zero = q(action), q(torch.zeros_like(action))
    assert torch.equal(given[:2], zero[:2]) and not torch.equal(given[2:], zero[2:])

    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    flags = torch.zeros(4, 1, dtype=torch.bool)
    next_obs = obs.clone()
    batch = TensorDict(
        observation=torch.randn(4, n_obs).index_fill_(1, torch.tensor([n_obs - 1]), 0.0),
        action=action,
        next=TensorDict(observation=next_obs, reward=torch.ones(4, 1), done=flags, terminated=flags, truncated=flags),
        batch_size=[4],
    )
    next_values = []
    for seed in (1, 2):  # two draws of TD3's target noise
        torch.manual_seed(seed)
        next_values.append(loss.value_loss(batch)[1]["next_state_value"])
    assert torch.equal(next_values[0][:2], next_values[1][:2])  # at s_a: Q'(s_a, 0) both times
    assert not torch.equal(next_values[0][2:], next_values[1][2:])
