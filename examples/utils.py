"""Builders and run-folder helpers for ``sail_td3.py`` (sota-implementations layout)."""
from __future__ import annotations

import importlib.util
import json
import math
import random
import resource
from functools import partial
from pathlib import Path

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import MLP, AdditiveGaussianModule, TanhModule, ValueOperator
from torchrl.objectives import SoftUpdate
from torchrl.record.loggers import get_logger

from torchrl_sail import (
    AlphaScheduler,
    check_demonstration_dims,
    DelayedRewardTransform,
    Discriminator,
    DiscriminatorLoss,
    load_demonstrations,
    make_sail_env,
    SAILLoss,
    TopKTeacherReplayBuffer,
)
from torchrl_sail._io import atomic_save, atomic_write
from torchrl_sail.data._keys import TRANSITION_KEYS

# Teachers made by examples/make_teacher.py, one small file per env, shipped with the repo.
TEACHERS_DIR = Path(__file__).resolve().parent / "teachers"
CHECKPOINT = "checkpoint.pt"
_ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}


# ----------------------------------------------------------------------------- config
def check_config(cfg: DictConfig) -> None:
    """Reject invalid values before anything is built, naming the key and the fix."""

    def fail(key, value, why):
        raise ValueError(f"config {key}={value!r}: {why}")

    c, o, d = cfg.collector, cfg.optim, cfg.optim.discriminator
    for key, value in [
        ("collector.total_frames", c.total_frames),
        ("collector.frames_per_batch", c.frames_per_batch),
        ("collector.num_workers", c.num_workers),
        ("optim.batch_size", o.batch_size),
        ("optim.train_every_frames", o.train_every_frames),
        ("optim.policy_delay", o.policy_delay),
        ("optim.discriminator.every_frames", d.every_frames),
        ("optim.discriminator.batch_size", d.batch_size),
        ("env.replay_size", cfg.env.replay_size),
        ("eval.episodes", cfg.eval.episodes),
    ]:
        if not isinstance(value, int) or value < 1:
            fail(key, value, "must be a positive integer")
    for key, value in [
        ("collector.init_random_frames", c.init_random_frames),
        ("optim.updates_per_train", o.updates_per_train),
        ("optim.discriminator.steps", d.steps),
        ("eval.every_frames", cfg.eval.every_frames),
        ("checkpoint.every_frames", cfg.checkpoint.every_frames),
    ]:
        if not isinstance(value, int) or value < 0:
            fail(key, value, "must be a non-negative integer (0 disables)")
    for key, value in [("optim.lr", o.lr), ("optim.discriminator.lr", d.lr)]:
        if not value > 0:
            fail(key, value, "must be > 0")
    if not 0 < o.gamma <= 1:
        fail("optim.gamma", o.gamma, "must be in (0, 1]")
    if not 0 < o.tau <= 1:
        fail("optim.tau", o.tau, "must be in (0, 1]")
    if cfg.env.exploration_noise < 0:
        fail("env.exploration_noise", cfg.env.exploration_noise, "must be >= 0")
    if o.batch_size < 2:
        fail("optim.batch_size", o.batch_size, "needs >= 2 rows to split teacher/agent")
    if cfg.algo.discriminator_agent_data not in ("replay", "recent"):
        fail("algo.discriminator_agent_data", cfg.algo.discriminator_agent_data, "use replay | recent")
    bad = set(cfg.logger.backends) - {"csv", "wandb", "tensorboard"}
    if bad:
        fail("logger.backends", list(cfg.logger.backends), f"unknown {sorted(bad)}; use csv, wandb, tensorboard")
    if "tensorboard" in cfg.logger.backends and importlib.util.find_spec("tensorboard") is None:
        fail("logger.backends", list(cfg.logger.backends),
             "the tensorboard backend needs the tensorboard package: pip install -e '.[tensorboard]'")
    if c.backend not in (None, "direct", "process", "ray"):
        fail("collector.backend", c.backend, "use null, direct, process or ray")
    if c.backend == "direct" and c.num_workers != 1:
        fail("collector.backend", c.backend, f"direct runs one worker, but collector.num_workers={c.num_workers}")
    if c.backend == "ray" and importlib.util.find_spec("ray") is None:
        fail("collector.backend", c.backend, "the ray backend needs Ray: pip install ray")
    if cfg.device != "cpu" and not torch.cuda.is_available():
        fail("device", cfg.device, "CUDA is not available on this machine; use device=cpu")


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


# ----------------------------------------------------------------------------- env / teacher
def make_env(cfg: DictConfig, seed: int):
    env = make_sail_env(
        cfg.env.name, max_episode_steps=cfg.env.max_episode_steps, device=cfg.device
    )
    env.set_seed(seed)
    return env


def make_collector(cfg: DictConfig, env, policy, *, frames: int):
    """TorchRL's ``Collector`` for what is left of the budget after ``frames`` (0 on a fresh run)."""
    backend = cfg.collector.backend or ("process" if cfg.collector.num_workers > 1 else "direct")
    kwargs = {}
    if backend != "direct":
        options = cfg.collector.backend_options
        kwargs = {"backend": backend, "num_collectors": cfg.collector.num_workers, "sync": True,
                  "backend_options": {} if options is None else OmegaConf.to_container(options, resolve=True)}
        # Workers build their own env (seeded below) from the installed package, so remote
        # workers (Ray actors) need torchrl_sail installed but not this examples/ folder.
        env = partial(make_sail_env, cfg.env.name, max_episode_steps=cfg.env.max_episode_steps,
                      device=cfg.device)
    collector = Collector(
        env,
        policy,
        frames_per_batch=cfg.collector.frames_per_batch,
        total_frames=max(cfg.collector.total_frames - frames, cfg.collector.frames_per_batch),
        init_random_frames=max(0, cfg.collector.init_random_frames - frames),
        **kwargs,
    )
    if backend != "direct":
        # One seed per worker (worker 0 gets seed, each next one the seed env.set_seed returns):
        # with one shared seed, all workers would replay the same episodes.
        collector.set_seed(cfg.seed + frames)
    return collector


def teacher_path(cfg: DictConfig) -> Path:
    if cfg.teacher.path is not None:
        return Path(cfg.teacher.path).expanduser()
    shipped = TEACHERS_DIR / f"{cfg.env.name}.pt"
    if not shipped.exists():
        raise FileNotFoundError(
            f"No teacher.path given and no shipped teacher for env {cfg.env.name!r} at "
            f"{shipped}. Pass teacher.path=<file.npz|file.pt> (e.g. the paper's "
            f"../shared/data/teachers/expert_data_no_img_Hopper_scores_1500_episodes_1.npz "
            f"for Hopper) or make one with `python examples/make_teacher.py env={cfg.env.name}`."
        )
    return shipped


def load_teacher(cfg: DictConfig, env):
    """Demonstrations for the teacher buffer, with the learner's delayed reward."""
    path = teacher_path(cfg)
    demos, meta = load_demonstrations(path, max_episode_steps=cfg.env.max_episode_steps)
    check_demonstration_dims(demos, env=env, source=str(path))
    # The buffer ranks trajectories by r_e = floor(0.1 R), the only reward the learner sees.
    demos = DelayedRewardTransform().forward(demos).select(*TRANSITION_KEYS)
    return demos, meta


def make_teacher_buffer(cfg: DictConfig, demos) -> TopKTeacherReplayBuffer:
    t = cfg.teacher
    buffer = TopKTeacherReplayBuffer(
        k=t.k,
        eviction=t.eviction,
        max_trajectory_length=cfg.env.max_episode_steps,
        capacity=t.capacity if t.eviction == "fifo" else None,
    )
    buffer.add_demonstrations(demos)
    return buffer


def make_replay(size: int) -> TensorDictReplayBuffer:
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size))


# ----------------------------------------------------------------------------- networks / losses
def make_agent(cfg: DictConfig, env):
    obs_dim = env.observation_spec["observation"].shape[-1]
    action_spec = env.action_spec
    act_dim = action_spec.shape[-1]
    activation = _ACTIVATIONS[cfg.network.activation]
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(in_features=obs_dim, out_features=act_dim, num_cells=list(cfg.network.actor_cells),
                activation_class=activation),
            in_keys=["observation"],
            out_keys=["param"],
        ),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=action_spec),
    )
    critic = ValueOperator(
        MLP(in_features=obs_dim + act_dim, out_features=1, num_cells=list(cfg.network.critic_cells),
            activation_class=activation),
        in_keys=["action", "observation"],
    )
    modules = [actor]
    if cfg.env.exploration_noise > 0:
        # Gaussian noise in RANDOM exploration mode only; projected onto the action bounds.
        modules.append(
            AdditiveGaussianModule(
                spec=action_spec, sigma_init=1.0, sigma_end=1.0, std=cfg.env.exploration_noise
            )
        )
    exploration_policy = TensorDictSequential(*modules)
    return actor, critic, exploration_policy


def make_discriminator(cfg: DictConfig, env) -> Discriminator:
    return Discriminator(
        env.observation_spec["observation"].shape[-1],
        env.action_spec.shape[-1],
        num_cells=tuple(cfg.network.discriminator_cells),
        activation_class=_ACTIVATIONS[cfg.network.discriminator_activation],
        normalize_observations=cfg.network.normalize_observations,
    )


def make_losses(cfg: DictConfig, actor, critic, discriminator, action_spec):
    o = cfg.optim
    loss = SAILLoss(
        actor,
        critic,
        action_spec=action_spec,
        alpha=cfg.algo.alpha.initial,
        policy_noise=o.policy_noise,
        noise_clip=o.noise_clip,
        loss_function=o.loss_function,
    )
    loss.make_value_estimator(gamma=o.gamma)
    if o.truncation_is_terminal:
        # The authors store done = 1 at time-limit truncation too: no bootstrap there.
        loss.set_keys(terminated="done")
    updater = SoftUpdate(loss, tau=o.tau)
    a = cfg.algo.alpha
    scheduler = AlphaScheduler(
        loss, mode=a.mode, initial=a.initial, final=a.final, anneal_frames=a.anneal_frames
    )
    d_loss = DiscriminatorLoss(
        discriminator, entropy_coef=o.discriminator.entropy_coef, gp_coef=o.discriminator.gp_coef
    )
    return loss, updater, scheduler, d_loss


def make_optimizers(cfg: DictConfig, loss, discriminator):
    return {
        # convert_to_functional re-samples and stacks the twin Q params: optimise the loss's copy.
        "critic": torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values(), lr=cfg.optim.lr),
        "actor": torch.optim.Adam(loss.actor_network_params.flatten_keys().values(), lr=cfg.optim.lr),
        "discriminator": torch.optim.Adam(discriminator.parameters(), lr=cfg.optim.discriminator.lr),
    }


# ----------------------------------------------------------------------------- evaluation
@torch.no_grad()
def evaluate(env, actor, episodes: int, max_steps: int) -> list[float]:
    """Dense returns of deterministic episodes (reporting only; the learner never sees them)."""
    returns = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            rollout = env.rollout(max_steps, actor, break_when_any_done=True)
            returns.append(float(rollout["next", "episode_return"][-1]))
    return returns


# ----------------------------------------------------------------------------- logging
def make_loggers(cfg: DictConfig, run_dir: Path, states: dict | None = None) -> dict:
    """TorchRL loggers by backend name; ``states`` (from ``logger_states``) resumes them."""
    loggers = {}
    for backend in dict.fromkeys(["csv", *cfg.logger.backends]):  # csv always, once
        kwargs = {}
        if backend == "wandb":
            # get_logger forwards only `wandb_kwargs`; offline mode needs no account.
            kwargs = {"wandb_kwargs": {
                "offline": cfg.logger.wandb_mode == "offline",
                "project": cfg.logger.project,
                "config": OmegaConf.to_container(cfg, resolve=True),
            }}
        if states and backend in states:
            kwargs["state_dict"] = states[backend]  # e.g. wandb: log to the same run id
        loggers[backend] = get_logger(backend, logger_name=str(run_dir), experiment_name="logs", **kwargs)
    return loggers


def logger_states(loggers: dict) -> dict:
    # The CSV logger's state is its whole history, already on disk: resume truncates the
    # files instead (truncate_scalars).
    return {name: logger.state_dict() for name, logger in loggers.items() if name != "csv"}


def truncate_scalars(run_dir: Path, frames: int) -> None:
    """Drops CSV rows logged after ``frames``: a resumed run re-logs them from its checkpoint."""
    for path in sorted((run_dir / "logs" / "scalars").glob("**/*.csv")):
        lines = path.read_text().splitlines(keepends=True)
        kept = [line for line in lines if line.strip() and int(float(line.split(",")[0])) <= frames]
        if len(kept) != len(lines):
            atomic_write(path, lambda f, text="".join(kept): f.write(text.encode()))


def log_metrics(loggers, metrics: dict, step: int) -> None:
    values = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in metrics.items() if v is not None}
    metrics = {k: v for k, v in values.items() if math.isfinite(v)}
    for logger in loggers.values():
        logger.log_metrics(metrics, step)


def read_scalar(run_dir: Path, tag: str) -> tuple[list[int], list[float]]:
    """(steps, values) of one scalar written by TorchRL's CSV logger."""
    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
    if not path.exists():
        return [], []
    rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
    return [int(float(r[0])) for r in rows], [float(r[1]) for r in rows]


def plot_learning_curve(run_dir: Path, *, teacher_return: float, alpha_switch_frame, title: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    steps, values = read_scalar(run_dir, "train/dense_return")
    if steps:
        ax.plot(steps, values, alpha=0.35, label="training return (noisy actions)")
    steps, values = read_scalar(run_dir, "eval/return")
    if steps:
        ax.plot(steps, values, marker="o", ms=3, label="eval return (deterministic)")
    ax.axhline(teacher_return, ls="--", c="gray", label=f"teacher ({teacher_return:.0f})")
    if alpha_switch_frame is not None:
        ax.axvline(alpha_switch_frame, ls=":", c="red", label="alpha -> 0 (first promotion)")
    ax.set_xlabel("environment frames")
    ax.set_ylabel("dense episode return")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path = run_dir / "learning_curve.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def peak_memory_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def write_json(path: Path, payload: dict) -> None:
    atomic_write(path, lambda f: f.write(json.dumps(payload, indent=2).encode()))


# ----------------------------------------------------------------------------- checkpoints
def replay_state(rb: TensorDictReplayBuffer) -> dict:
    """Only the filled rows (a full state_dict would save the whole preallocated storage)."""
    n = len(rb)
    data = rb.storage.get(torch.arange(n)) if n else None
    return {
        "data": None if data is None else data.to_dict(),
        "writer": rb.writer.state_dict(),
    }


def load_replay_state(rb: TensorDictReplayBuffer, state: dict) -> None:
    if state["data"] is not None:
        n = len(state["data"]["action"])
        rb.extend(TensorDict.from_dict(state["data"], batch_size=[n]))
    rb.writer.load_state_dict(state["writer"])


def rng_state() -> dict:
    return {
        "torch": torch.get_rng_state(),
        "numpy": np.random.get_state(),
        "python": random.getstate(),
    }


def load_rng_state(state: dict) -> None:
    torch.set_rng_state(state["torch"])
    np.random.set_state(state["numpy"])
    random.setstate(state["python"])


def save_checkpoint(path: Path, state: dict) -> None:
    atomic_save(state, path)


def load_checkpoint(path: Path) -> dict:
    if not path.exists():
        raise FileNotFoundError(
            f"resume=true but there is no checkpoint at {path}: start without resume=true, "
            f"or point hydra.run.dir at the run folder to continue."
        )
    try:
        # Our own file, with numpy RNG state and python tuples inside: not weights_only.
        return torch.load(path, map_location="cpu", weights_only=False)
    except Exception as err:  # truncated / corrupt
        raise ValueError(
            f"checkpoint {path} is unreadable ({type(err).__name__}: {err}); checkpoints are "
            f"written atomically, so this file was damaged after writing. Delete it to start over."
        ) from err

