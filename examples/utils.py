"""Builders and run-folder helpers for ``sail_td3.py`` (sota-implementations layout)."""
from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import math
import os
import platform
import random
import resource
import shutil
import subprocess
from functools import partial
from pathlib import Path

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from tensordict.nn import InteractionType, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl._utils import timeit
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import (MLP, AdditiveGaussianModule, NormalParamExtractor, ProbabilisticActor, TanhModule,
                             TanhNormal, ValueOperator)
from torchrl.objectives import RNDLoss, SACLoss, SoftUpdate
from torchrl.record.loggers import get_logger

from torchrl_sail import (
    AbsorbingStateTransform,
    AlphaScheduler,
    check_demonstration_dims,
    DelayedRewardTransform,
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorReward,
    FIFOTrajectoryWriter,
    load_demonstrations,
    make_sail_env,
    NStepTransform,
    SAILLoss,
    TD3Update,
    TeacherReplayBuffer,
    RNDReward,
    TopKTrajectoryWriter,
    TRANSITION_KEYS,
    UnionTrajectoryWriter,
)

# Teachers made by examples/make_teacher.py, one small dataset per env, shipped with the repo.
TEACHERS_DIR = Path(__file__).resolve().parent / "teachers"
_ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}


# ----------------------------------------------------------------------------- config
def check_config(cfg: DictConfig) -> None:
    """Rejects invalid values before anything is built, naming the key and the fix.

    Types and choices are the schema's (``config_schema.py``, enforced by Hydra); what is left
    here is what a type cannot say: ranges, and rules across fields.
    """

    def fail(key, value, why):
        raise ValueError(f"config {key}={value!r}: {why}")

    c, o, d = cfg.collector, cfg.optim, cfg.optim.discriminator
    if cfg.algo.learner == "ppo" and cfg.algo.ppo is None:
        fail("algo.ppo", None, "algo.learner=ppo needs the PPO settings (algo=gail has them)")
    for key, value, low in [
        ("collector.total_frames", c.total_frames, 1),
        ("collector.frames_per_batch", c.frames_per_batch, 1),
        ("collector.num_workers", c.num_workers, 1),
        ("optim.batch_size", o.batch_size, 2),
        ("optim.train_every_frames", o.train_every_frames, 1),
        ("optim.policy_delay", o.policy_delay, 1),
        ("optim.discriminator.every_frames", d.every_frames, 1),
        ("optim.discriminator.batch_size", d.batch_size, 1),
        ("env.replay_size", cfg.env.replay_size, 1),
        ("eval.episodes", cfg.eval.episodes, 1),
        *([("algo.ppo.frames_per_batch", cfg.algo.ppo.frames_per_batch, 1), ("algo.ppo.epochs", cfg.algo.ppo.epochs, 1),
           ("algo.ppo.minibatch_size", cfg.algo.ppo.minibatch_size, 1)] if cfg.algo.learner == "ppo" else []),
        ("algo.bc.epochs", cfg.algo.bc.epochs, 1),
        ("algo.bc.batch_size", cfg.algo.bc.batch_size, 1),
        ("collector.init_random_frames", c.init_random_frames, 0),
        ("optim.updates_per_train", o.updates_per_train, 0),
        ("optim.discriminator.steps", d.steps, 0),
        ("eval.every_frames", cfg.eval.every_frames, 0),
        ("eval.video_every_frames", cfg.eval.video_every_frames, 0),
        ("checkpoint.every_frames", cfg.checkpoint.every_frames, 0),
    ]:
        if value < low:
            fail(key, value, f"must be >= {low}" + (" (0 disables)" if low == 0 else ""))
    for key, value, ok, why in [
        ("optim.lr", o.lr, o.lr > 0, "must be > 0"),
        ("optim.actor_updates_after", o.actor_updates_after, o.actor_updates_after >= 0, "must be >= 0"),
        ("optim.actor_max_grad_norm", o.actor_max_grad_norm, o.actor_max_grad_norm is None or o.actor_max_grad_norm > 0,
         "must be > 0, or null (no clipping)"),
        ("optim.actor_lr_decay", None if o.actor_lr_decay is None else dict(o.actor_lr_decay),
         o.actor_lr_decay is None or (0 < o.actor_lr_decay.rate <= 1 and o.actor_lr_decay.every_frames >= 1),
         "needs 0 < rate <= 1 and every_frames >= 1, or null"),
        ("optim.actor_lr_decay", None if o.actor_lr_decay is None else dict(o.actor_lr_decay),
         o.actor_lr_decay is None or cfg.algo.learner == "td3", "is TD3's (algo.learner=td3)"),
        ("optim.discriminator.lr", d.lr, d.lr > 0, "must be > 0"),
        ("algo.bc.lr", cfg.algo.bc.lr, cfg.algo.bc.lr > 0, "must be > 0"),
        ("optim.gamma", o.gamma, 0 < o.gamma <= 1, "must be in (0, 1]"),
        ("optim.tau", o.tau, 0 < o.tau <= 1, "must be in (0, 1]"),
        ("env.exploration_noise", cfg.env.exploration_noise, cfg.env.exploration_noise >= 0, "must be >= 0"),
        ("algo.rnd", cfg.algo.rnd, cfg.algo.rnd is None or (c.num_workers == 1 and c.backend in (None, "direct")),
         "the RND bonus keeps its statistics in the training env: use collector.num_workers=1 and "
         "collector.backend=null"),
        ("algo.absorbing_state", cfg.algo.absorbing_state, not (cfg.algo.absorbing_state and cfg.algo.adaptive),
         "absorbing states need a fixed teacher (algo.adaptive=false): promotion reads unrewritten trajectories"),
        ("optim.precision", o.precision, o.precision == "fp32" or (
            o.implementation == "fused" and cfg.algo.learner == "td3" and not masks_absorbing_actions(cfg)),
         "bf16 is TD3's fused step only: optim.implementation=fused, algo.learner=td3, and no bootstrapped "
         "absorbing states (DAC's masked actor runs the loss's own step)"),
        ("algo.reward.clip", cfg.algo.reward.clip, cfg.algo.reward.clip is None or (
            len(cfg.algo.reward.clip) == 2 and 0 < cfg.algo.reward.clip[0] < cfg.algo.reward.clip[1] < 1),
         "must be [low, high] with 0 < low < high < 1, or null"),
        ("collector.backend", c.backend, c.backend != "direct" or c.num_workers == 1,
         f"direct runs one worker, but collector.num_workers={c.num_workers}"),
        ("collector.backend", c.backend, c.backend != "ray" or importlib.util.find_spec("ray") is not None,
         "the ray backend needs Ray: pip install ray"),
        ("resume", cfg.resume, cfg.resume in (True, False, "auto"), "use true, false or auto"),
        ("algo.nstep.n", cfg.algo.nstep and cfg.algo.nstep.n, cfg.algo.nstep is None or cfg.algo.nstep.n >= 2,
         "must be >= 2 (algo.nstep=null for the 1-step TD loss alone)"),
        ("algo.nstep.lambda1", cfg.algo.nstep and cfg.algo.nstep.lambda1,
         cfg.algo.nstep is None or 0 < cfg.algo.nstep.lambda1 < math.inf, "must be a finite number > 0"),
        # The n-step sums are of the stored env reward, made when a transition is stored; other
        # rewards are made at sample time for the 1-step entries only, and promoted, absorbing or
        # SAC/BC/PPO rows have no n-step view.
        ("algo.nstep", "set", cfg.algo.nstep is None or (
            cfg.algo.learner == "td3" and cfg.algo.reward.source == "env" and cfg.algo.rnd is None
            and not cfg.algo.adaptive and not cfg.algo.absorbing_state),
         "the n-step loss (DDPGfD) needs algo.learner=td3, algo.reward.source=env, algo.rnd=null, "
         "algo.adaptive=false and algo.absorbing_state=false"),
        ("algo.l2_coef", cfg.algo.l2_coef, 0 <= cfg.algo.l2_coef < math.inf and (
            cfg.algo.l2_coef == 0 or cfg.algo.learner in ("td3", "sac")),
         "must be a finite number >= 0, and 0 unless algo.learner is td3 or sac (the actor's and the critic's "
         "Adam weight decay)"),
        ("algo.reward.source", cfg.algo.reward.source, cfg.algo.learner != "ppo" or (
            cfg.algo.reward.source != "env" and cfg.algo.rnd is None and not cfg.algo.absorbing_state),
         "the PPO generator (gail, pofd) learns from D's reward (discriminator or shaped), without an RND "
         "bonus or absorbing states"),
        ("algo.reward.coef_decay", cfg.algo.reward.coef_decay, 0 < cfg.algo.reward.coef_decay <= 1 and (
            cfg.algo.reward.coef_decay == 1 or cfg.algo.learner == "ppo"),
         "must be in (0, 1], and 1 unless algo.learner=ppo (it decays the shaping once per on-policy batch)"),
        ("collector.backend_options", c.backend_options, c.backend_options is None or isinstance(c.backend_options, DictConfig),
         "must be a mapping (forwarded to TorchRL's Collector) or null"),
        ("device", cfg.device, cfg.device == "cpu" or torch.cuda.is_available(),
         "CUDA is not available on this machine; use device=cpu"),
    ]:
        if not ok:
            fail(key, value, why)
    # The off-policy loop runs the D steps and TD3 updates of every cadence crossed by a
    # collector batch at once, after it: a batch longer than a cadence bunches them, and one
    # that does not divide it shifts them, so the reward would come from a D that is behind.
    if cfg.algo.learner in ("td3", "sac"):
        cadences = [("optim.train_every_frames", o.train_every_frames)]
        if cfg.algo.reward.source != "env" and d.steps:
            cadences.insert(0, ("optim.discriminator.every_frames", d.every_frames))
        for key, every in cadences:
            if every % c.frames_per_batch:  # a synchronous collector's batch is over all its workers
                fail(key, every, f"must be a multiple of collector.frames_per_batch={c.frames_per_batch}: a larger "
                                 f"collector batch, or one that does not divide it, runs these updates late or "
                                 f"bunched, so D's reward comes from a stale D (lower collector.frames_per_batch)")
    if len(cfg.eval.video_size) != 2 or min(cfg.eval.video_size) < 16:
        fail("eval.video_size", list(cfg.eval.video_size), "must be [width, height], each >= 16")
    if cfg.eval.video_every_frames and cfg.eval.video_format == "mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
        fail("eval.video_format", "mp4", "MP4 videos need imageio-ffmpeg: pip install -e '.[video]' (or use gif)")
    if cfg.eval.video_every_frames and "wandb" in cfg.logger.backends and importlib.util.find_spec("moviepy") is None:
        fail("eval.video_every_frames", cfg.eval.video_every_frames,
             "wandb encodes videos with moviepy: pip install -e '.[video]' (or drop wandb from logger.backends)")
    if "tensorboard" in cfg.logger.backends and importlib.util.find_spec("tensorboard") is None:
        fail("logger.backends", list(cfg.logger.backends),
             "the tensorboard backend needs the tensorboard package: pip install -e '.[tensorboard]'")


def actor_lr(cfg: DictConfig, frames: int) -> float:
    """The actor's learning rate at ``frames``: ``optim.lr``, decayed stepwise by ``optim.actor_lr_decay``."""
    decay = cfg.optim.actor_lr_decay
    return cfg.optim.lr if decay is None else cfg.optim.lr * decay.rate ** (frames // decay.every_frames)


def masks_absorbing_actions(cfg: DictConfig) -> bool:
    """DAC as published: the actor outputs 0 at the absorbing state, which is bootstrapped through."""
    return bool(cfg.algo.absorbing_state and cfg.algo.absorbing_bootstrap)


def make_absorbing(cfg: DictConfig, action_spec=None) -> AbsorbingStateTransform | None:
    """``algo.absorbing_*`` as a transform of stored transitions (``None`` without absorbing states).

    ``action_spec`` is the agent's: with ``algo.absorbing_action=random`` the agent's absorbing
    transitions store a random action (the SAIL authors' DAC); the demonstrations' always the zero action.
    """
    if not cfg.algo.absorbing_state:
        return None
    random = cfg.algo.absorbing_action == "random" and action_spec is not None
    return AbsorbingStateTransform(bootstrap=cfg.algo.absorbing_bootstrap, action_spec=action_spec if random else None)


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def crossings(every: int, start: int, before: int, now: int) -> int:
    """How many multiples of ``every`` that are ``>= start`` lie in ``(before, now]`` (0 if ``every`` is 0).

    Every cadence of the loop (updates, evaluation, checkpoints) is derived from the frame count
    this way, so a resumed run needs no other counter.
    """
    if not every:
        return 0
    return max(0, now // every - (max(start, before + 1) - 1) // every)


# ----------------------------------------------------------------------------- env / data
def normalized_observation_key(cfg: DictConfig) -> str | None:
    """Where the PPO generator (gail, pofd) reads its observations: TorchRL's running normalisation of
    them (its PPO MuJoCo example's VecNorm), ``None`` for the other learners (and runs saved before it).
    ``"observation"`` stays raw: the demonstrations and the discriminator use it."""
    ppo = cfg.algo.ppo
    return "observation_norm" if cfg.algo.learner == "ppo" and ppo.get("normalize_observations", False) else None


def make_env(cfg: DictConfig, seed: int):
    env = make_sail_env(cfg.env.name, max_episode_steps=cfg.env.max_episode_steps,
                        absorbing_state=cfg.algo.absorbing_state, device=cfg.device,
                        normalized_observation_key=normalized_observation_key(cfg))
    env.set_seed(seed)
    return env


def make_collector(cfg: DictConfig, env, policy, *, frames: int):
    """TorchRL's ``Collector`` for what is left of the budget after ``frames`` (0 on a fresh run)."""
    backend = str(cfg.collector.backend or ("process" if cfg.collector.num_workers > 1 else "direct"))
    # One env in this process: trajectory ids are not needed (episode ends are the done flags).
    kwargs = {"track_traj_ids": False}
    if backend != "direct":
        options = cfg.collector.backend_options
        kwargs = {"backend": backend, "num_collectors": cfg.collector.num_workers, "sync": True,
                  "backend_options": {} if options is None else OmegaConf.to_container(options, resolve=True)}
        # Workers build their own env (seeded below) from the installed package, so remote
        # workers (Ray actors) need torchrl_sail installed but not this examples/ folder.
        env = partial(make_sail_env, cfg.env.name, max_episode_steps=cfg.env.max_episode_steps,
                      absorbing_state=cfg.algo.absorbing_state, device=cfg.device)
    collector = Collector(
        env,
        policy,
        frames_per_batch=cfg.collector.frames_per_batch,
        total_frames=max(cfg.collector.total_frames - frames, 0),
        init_random_frames=max(0, cfg.collector.init_random_frames - frames),
        **kwargs,
    )
    if backend != "direct":
        # One seed per worker (worker 0 gets seed, each next one the seed env.set_seed returns):
        # with one shared seed, all workers would replay the same episodes.
        collector.set_seed(cfg.seed + frames)
    if backend == "ray":
        # First push now, before any batch: it connects TorchRL's RayWeightSyncScheme (a gloo
        # group of the learner and the actors, 60 s rendezvous), so a failure stops the run
        # before it trains. Later pushes (one per batch, in the loop) reuse the group.
        collector.update_policy_weights_()
    return collector


def make_nstep(cfg: DictConfig) -> NStepTransform | None:
    """DDPGfD's n-step view of stored transitions (``algo.nstep``), ``None`` for the 1-step methods."""
    return None if cfg.algo.nstep is None else NStepTransform(cfg.algo.nstep.n, cfg.optim.gamma)


def stored_keys(cfg: DictConfig) -> list:
    """The entries every stored transition keeps: TRANSITION_KEYS, and the n-step view with ``algo.nstep``."""
    nstep = make_nstep(cfg)
    return [*TRANSITION_KEYS, *(nstep.out_keys_inv if nstep is not None else ())]


def make_teacher(cfg: DictConfig, env, absorbing: AbsorbingStateTransform | None = None):
    """The teacher buffer seeded with the demonstrations, the teacher's best dense return, its path.

    With ``absorbing`` (DAC), the demonstrations get the indicator and the absorbing transitions
    the agent's data gets.
    """
    path = Path(cfg.teacher.path).expanduser() if cfg.teacher.path else TEACHERS_DIR / cfg.env.name
    if cfg.teacher.path is None and not path.exists():
        raise FileNotFoundError(
            f"No teacher.path given and no shipped teacher for env {cfg.env.name!r} at {path}. Pass "
            f"teacher.path=<file.npz|dataset folder|minari:<dataset id>> (e.g. the paper's ../shared/data/teachers/"
            f"expert_data_no_img_Hopper_scores_1500_episodes_1.npz for Hopper) or make one with "
            f"`python examples/make_teacher.py env={cfg.env.name}`."
        )
    # The env appends the time feature: a Minari dataset recorded without it gets it appended
    # (exact), a .npz file must have it ("minari:<id>" survives Path: load_demonstrations reads it).
    demos, meta = load_demonstrations(path, max_episode_steps=cfg.env.max_episode_steps, time_feature=True)
    # The buffer ranks trajectories by r_e = floor(0.1 R), the only reward the learner sees.
    demos = DelayedRewardTransform().forward(demos).select(*TRANSITION_KEYS)
    if absorbing is not None:
        demos = absorbing(demos)
    check_demonstration_dims(demos, env=env, source=str(path))
    nstep = make_nstep(cfg)
    if nstep is not None:  # DDPGfD: the demonstrations' n-step view, as the agent's (whole episodes)
        demos = nstep.apply_to_trajectories(demos)
    t, keys = cfg.teacher, stored_keys(cfg)
    if t.eviction == "fifo":  # the authors' transition ring
        writer = FIFOTrajectoryWriter(k=t.k, capacity=t.capacity, keys=keys)
    elif t.eviction == "union":  # the paper's R_T <- R_T U tau: room for the demonstrations and every frame
        writer = UnionTrajectoryWriter(k=t.k, capacity=demos.numel() + cfg.collector.total_frames, keys=keys)
    else:  # the paper's K best trajectories (+ 1 row: a terminated episode's absorbing transition)
        writer = TopKTrajectoryWriter(k=t.k, max_trajectory_length=cfg.env.max_episode_steps + (absorbing is not None),
                                      keys=keys)
    buffer = TeacherReplayBuffer(writer, device=cfg.device)
    buffer.add_demonstrations(demos)
    return buffer, float(max(meta["episode_returns"])), str(path)


def make_replay(size: int, device: str) -> TensorDictReplayBuffer:
    # On the learner's device: with device=cuda, sampling and the update never leave the GPU.
    return TensorDictReplayBuffer(storage=LazyTensorStorage(size, device=device))


class FilledRows:
    """Checkpoints a replay buffer's filled rows only (its storage preallocates every row).

    Args:
        buffer (TensorDictReplayBuffer): a buffer with a ``RoundRobinWriter``.
    """

    def __init__(self, buffer: TensorDictReplayBuffer) -> None:
        self.buffer = buffer

    def state_dict(self) -> dict:
        n = len(self.buffer)
        data = self.buffer.storage.get(torch.arange(n)).to_dict() if n else {}
        return {"size": n, "data": data, "writer": self.buffer.writer.state_dict()}

    def load_state_dict(self, state: dict) -> None:
        if state["size"]:
            self.buffer.extend(TensorDict(state["data"], batch_size=[state["size"]]))
        self.buffer.writer.load_state_dict(state["writer"])


# ----------------------------------------------------------------------------- networks / losses
def make_agent(cfg: DictConfig, env):
    """Actor, critic and exploration policy: TD3's deterministic actor with Gaussian noise, or
    (``algo.learner=sac``) SAC's tanh-Gaussian actor, which explores by sampling."""
    obs_dim = env.observation_spec["observation"].shape[-1]
    action_spec = env.action_spec
    act_dim = action_spec.shape[-1]
    activation = _ACTIVATIONS[cfg.network.activation]
    critic = ValueOperator(
        MLP(in_features=obs_dim + act_dim, out_features=1, num_cells=list(cfg.network.critic_cells),
            activation_class=activation, device=cfg.device),
        in_keys=["action", "observation"],
    )
    if cfg.algo.learner == "sac":
        # TorchRL's sota SAC actor: MLP -> (loc, softplus scale) -> TanhNormal on the action bounds
        net = nn.Sequential(
            MLP(in_features=obs_dim, out_features=2 * act_dim, num_cells=list(cfg.network.actor_cells),
                activation_class=activation, device=cfg.device),
            NormalParamExtractor(scale_mapping="biased_softplus_1.0", scale_lb=0.1),
        )
        actor = ProbabilisticActor(
            TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
            in_keys=["loc", "scale"], spec=action_spec, distribution_class=TanhNormal,
            distribution_kwargs={"low": action_spec.space.low, "high": action_spec.space.high, "tanh_loc": False},
            default_interaction_type=InteractionType.RANDOM,
        )
        return actor, critic, actor
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(in_features=obs_dim, out_features=act_dim, num_cells=list(cfg.network.actor_cells),
                activation_class=activation, device=cfg.device),
            in_keys=["observation"],
            out_keys=["param"],
        ),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=action_spec),
        # DAC: pi(s_a) = 0, the action the absorbing transitions store (only read where s_a is bootstrapped)
        *([AbsorbingStateTransform().action_mask()] if masks_absorbing_actions(cfg) else []),
    )
    modules = [actor]
    if cfg.env.exploration_noise > 0:
        # Gaussian noise in RANDOM exploration mode only; projected onto the action bounds.
        modules.append(
            AdditiveGaussianModule(spec=action_spec, sigma_init=1.0, sigma_end=1.0, std=cfg.env.exploration_noise)
        )
    return actor, critic, TensorDictSequential(*modules)


def make_discriminator(cfg: DictConfig, env) -> Discriminator:
    return Discriminator(
        env.observation_spec["observation"].shape[-1],
        env.action_spec.shape[-1],
        num_cells=tuple(cfg.network.discriminator_cells),
        activation_class=_ACTIVATIONS[cfg.network.discriminator_activation],
        normalize_observations=cfg.network.normalize_observations,
    ).to(cfg.device)


def make_reward(cfg: DictConfig, discriminator: Discriminator, rnd: RNDReward | None = None, **kwargs):
    """The sample-time reward of ``algo.reward``, then ``rnd``'s bonus if given (``None``: the env's reward)."""
    r = cfg.algo.reward
    reward = None
    if r.source != "env":
        reward = DiscriminatorReward(discriminator, kind=r.kind, coef=r.coef, clip=None if r.clip is None else tuple(r.clip),
                                     mode="add" if r.source == "shaped" else "replace", **kwargs)
    if rnd is None or reward is None:
        return reward or rnd

    def reward_then_bonus(batch):
        return rnd(reward(batch))

    return reward_then_bonus


def make_rnd(cfg: DictConfig, env) -> tuple[RNDReward | None, RNDLoss | None]:
    """``algo.rnd``'s bonus, appended to the training ``env`` (it keeps the running statistics), and its loss."""
    if cfg.algo.rnd is None:
        return None, None
    r, obs_dim = cfg.algo.rnd, env.observation_spec["observation"].shape[-1]

    def net():
        return MLP(in_features=obs_dim, out_features=r.features, num_cells=list(r.cells), device=cfg.device)

    rnd = RNDReward(net(), net(), coef=r.coef, row_id_key="row_id")  # once per distinct row of a block
    env.append_transform(rnd)
    rnd.train()  # append_transform leaves transforms in eval mode, where RND's statistics stay frozen
    return rnd, RNDLoss(rnd.predictor_network, rnd.target_network)


class TeacherShare:
    """Where SAC runs keep SAIL's alpha: ``SACLoss.alpha`` is SAC's entropy temperature, and
    the share acts through the batch composition alone (``MixedReplayBuffer``)."""

    def __init__(self, alpha: float) -> None:
        self.alpha = alpha


def make_losses(cfg: DictConfig, actor, critic, discriminator, action_spec):
    o, a = cfg.optim, cfg.algo.alpha
    if cfg.algo.learner == "sac":
        loss = SACLoss(actor, critic, num_qvalue_nets=2, loss_function=o.loss_function,
                       alpha_init=cfg.algo.sac.alpha_init, action_spec=action_spec)
        share = TeacherShare(a.initial)
    else:
        # mixing="batch": alpha acts through the batch composition alone (the authors' code).
        loss = SAILLoss(actor, critic, action_spec=action_spec, alpha=a.initial, mixing="batch",
                        policy_noise=o.policy_noise, noise_clip=o.noise_clip, loss_function=o.loss_function)
        share = loss
    loss.make_value_estimator(gamma=o.gamma)
    if o.truncation_is_terminal and not masks_absorbing_actions(cfg):
        # The authors store done = 1 at time-limit truncation too: no bootstrap there. With
        # bootstrapped absorbing states (DAC) only terminations end an episode, through s_a.
        loss.set_keys(terminated="done")
    updater = SoftUpdate(loss, tau=o.tau)
    scheduler = AlphaScheduler(share, mode=a.mode, initial=a.initial, final=a.final, anneal_frames=a.anneal_frames)
    d_loss = DiscriminatorLoss(discriminator, entropy_coef=o.discriminator.entropy_coef,
                               gp_coef=o.discriminator.gp_coef)
    return loss, updater, scheduler, d_loss


def make_optimizers(cfg: DictConfig, loss, discriminator, rnd: RNDReward | None = None) -> dict:
    # fused Adam: one kernel for all parameters of a network (CPU and CUDA).
    adam = partial(torch.optim.Adam, fused=True)
    # DDPGfD's lambda_2 (algo.l2_coef): Adam's coupled weight decay adds l2_coef * theta to the
    # gradient, i.e. l2_coef / 2 * ||theta||^2 in the actor's and the critic's losses (0: none)
    l2 = cfg.algo.l2_coef
    optimizers = {
        # convert_to_functional re-samples and stacks the twin Q params: optimise the loss's copy.
        "critic": adam(loss.qvalue_network_params.flatten_keys().values(), lr=cfg.optim.lr, weight_decay=l2),
        "actor": adam(loss.actor_network_params.flatten_keys().values(), lr=cfg.optim.lr, weight_decay=l2),
        "discriminator": adam(discriminator.parameters(), lr=cfg.optim.discriminator.lr),
    }
    if rnd is not None:
        optimizers["rnd"] = adam(rnd.predictor_network.parameters(), lr=cfg.algo.rnd.lr)
    if cfg.algo.learner == "sac":  # SAC's entropy temperature
        optimizers["alpha"] = adam([loss.log_alpha], lr=cfg.algo.sac.alpha_lr)
    return optimizers


def make_update(cfg: DictConfig, loss, optimizers: dict, target_updater):
    """One gradient step ``update(batch, update_actor) -> metrics``: TD3's fused implementation or
    the loss's own (``optim.implementation=loss``); for SAC, TorchRL's ``SACLoss`` as its sota script
    steps it (actor, critics and temperature every step, then the targets)."""
    if cfg.algo.learner != "sac":
        # DAC's masked actor is not the fused step's MLP + tanh: it runs the loss's own step
        implementation = "loss" if masks_absorbing_actions(cfg) else cfg.optim.implementation
        nstep = make_nstep(cfg)  # DDPGfD: + lambda_1 * the TD loss of each row's stored n-step view
        nstep_kwargs = {} if nstep is None else {"nstep_key": nstep.out_key, "nstep_weight": cfg.algo.nstep.lambda1}
        return TD3Update(loss, critic_optimizer=optimizers["critic"], actor_optimizer=optimizers["actor"],
                         target_updater=target_updater, implementation=implementation,
                         precision=cfg.optim.precision, actor_max_grad_norm=cfg.optim.actor_max_grad_norm,
                         **nstep_kwargs)
    steps = [optimizers[name] for name in ("critic", "actor", "alpha")]

    def sac_update(batch, update_actor: bool) -> dict:  # noqa: ARG001 (SAC updates its actor every step)
        out = loss(batch)
        (out["loss_qvalue"] + out["loss_actor"] + out["loss_alpha"]).backward()
        for optimizer in steps:
            optimizer.step()
            optimizer.zero_grad(set_to_none=True)
        target_updater.step()
        # SAC's alpha is its entropy temperature; "alpha" in the logs is SAIL's teacher share
        return {"loss_qvalue": out["loss_qvalue"].detach(), "loss_actor": out["loss_actor"].detach(),
                "loss_temperature": out["loss_alpha"].detach(), "temperature": out["alpha"].detach(),
                "entropy": out["entropy"].detach()}

    return sac_update


# ----------------------------------------------------------------------------- evaluation
@torch.no_grad()
def evaluate_episodes(env, actor, episodes: int, max_steps: int, *, keep_rollouts: bool = False) -> list[dict]:
    """Deterministic episodes: the dense return, the delayed reward r_e and the length of each
    (and its ``"rollout"`` with ``keep_rollouts``)."""
    results = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(episodes):
            rollout = env.rollout(max_steps, actor, break_when_any_done=True)
            results.append({"dense_return": float(rollout["next", "episode_return"][-1]),
                            "delayed_reward": float(rollout["next", "reward"].sum()),
                            "length": rollout.numel(), **({"rollout": rollout} if keep_rollouts else {})})
    return results


def evaluate(env, actor, episodes: int, max_steps: int) -> float:
    """Mean dense return of deterministic episodes (reporting only; the learner never sees it)."""
    return sum(e["dense_return"] for e in evaluate_episodes(env, actor, episodes, max_steps)) / episodes


def record_evaluation(eval_env, actor, cfg: DictConfig, run: dict, frames: int, teacher_return: float) -> float:
    """The loops' evaluation at ``frames``: its mean return, kept in ``run["evals"]`` with the first
    frame it beat the teacher (``run["passed_teacher_at"]``)."""
    value = evaluate(eval_env, actor, cfg.eval.episodes, cfg.env.max_episode_steps)
    run["evals"].append((frames, value))
    if run["passed_teacher_at"] is None and value > teacher_return:
        run["passed_teacher_at"] = frames
    return value


# ----------------------------------------------------------------------------- run folder
def resume_mode(cfg: DictConfig, run_dir: Path) -> bool | None:
    """Whether this run continues the one in ``run_dir``: ``True``, ``False``, or ``None`` to skip it.

    ``resume=false`` refuses a folder that holds a checkpoint (a run is never overwritten),
    ``resume=true`` needs one. ``resume=auto`` (for matrices that must survive interruption)
    skips a run whose ``summary.json`` shows its budget done (offline runs: done), continues one
    with a checkpoint, and starts the rest afresh, first removing the logs of a run that stopped
    before its first checkpoint (nothing can continue them, and a fresh run would append to them).
    """
    checkpoint, summary = run_dir / "checkpoint", run_dir / "summary.json"
    if cfg.resume == "auto":
        if summary.exists():
            done = json.loads(summary.read_text())
            if done.get("offline") or done.get("frames", 0) >= cfg.collector.total_frames:
                return None
            if not checkpoint.exists():
                raise FileNotFoundError(
                    f"{run_dir} holds a finished {done.get('frames')}-frame run but no checkpoint to extend it to "
                    f"collector.total_frames={cfg.collector.total_frames}; choose another folder.")
        if checkpoint.exists():
            return True
        shutil.rmtree(run_dir / "logs", ignore_errors=True)
        return False
    if checkpoint.exists() and not cfg.resume:
        raise FileExistsError(f"{run_dir} already holds a run (checkpoint/). Continue it with resume=true "
                              f"(or resume=auto), or choose another folder with hydra.run.dir=...")
    return cfg.resume


def new_run(cfg: DictConfig) -> dict:
    """The run's own state, saved with the checkpoint: counters, evaluations, logger states, identity."""
    return {"frames": 0, "gradient_steps": 0, "evals": [], "passed_teacher_at": None, "loggers": {},
            "identity": {"env": cfg.env.name, "algo": cfg.algo.name, "seed": cfg.seed, "teacher": cfg.teacher.path}}


def start_or_resume(checkpoint, run_dir: Path, cfg: DictConfig, run: dict, resuming: bool, *,
                    optimizers=(), truncate_logs: bool = True) -> None:
    """Restores ``checkpoint`` from ``run_dir`` when ``resuming``, then writes the config the run goes on with.

    Only a resume that passed its checks drops the run's old ``summary.json``. The ``optimizers``
    keep the learning rates they were built with from the config: a run continued with another
    ``optim.lr`` (e.g. after a divergence) uses it, not the saved one.
    """
    if resuming:
        configured = [[group["lr"] for group in optimizer.param_groups] for optimizer in optimizers]
        resume(checkpoint, run_dir / "checkpoint", cfg, run, truncate_logs=truncate_logs)
        for optimizer, lrs in zip(optimizers, configured):
            for group, lr in zip(optimizer.param_groups, lrs):
                group["lr"] = lr
        if truncate_logs:  # a continued run is unfinished until it ends: no summary of its earlier budget
            (run_dir / "summary.json").unlink(missing_ok=True)
    OmegaConf.save(cfg, run_dir / "config.yaml", resolve=True)


def resume(checkpoint, path: Path, cfg: DictConfig, run: dict, *, truncate_logs: bool = True) -> None:
    """Restores every component of ``checkpoint`` from ``path``, after checking that it is this run's.

    ``truncate_logs`` drops the CSV rows logged after the checkpoint's frame (they are logged
    again); offline runs, whose logs are not indexed by frames, keep theirs.
    """
    if not (path / "manifest.json").exists():
        raise FileNotFoundError(
            f"resume=true but there is no checkpoint at {path}: start without resume=true, or point "
            f"hydra.run.dir at the run folder to continue."
        )
    try:
        checkpoint.load(path, components=["run"])
    except Exception as err:  # a damaged folder
        raise ValueError(f"checkpoint {path} is unreadable ({type(err).__name__}: {err}); delete it to start over.") from err
    this = new_run(cfg)["identity"]
    for key, saved in run["identity"].items():  # (checkpoints from before the teacher was recorded lack it)
        if saved != this[key]:
            key_name = "teacher.path" if key == "teacher" else key
            raise ValueError(f"resume: {path} was written with {key_name}={saved!r}, "
                             f"this run has {key_name}={this[key]!r}; use the same value.")
    checkpoint.load(path)
    if not truncate_logs:
        return
    # Rows logged after the checkpoint are logged again by this run: drop them.
    for csv in sorted((path.parent / "logs" / "scalars").glob("**/*.csv")):
        lines = csv.read_text().splitlines(keepends=True)
        kept = [line for line in lines if line.strip() and int(float(line.split(",")[0])) <= run["frames"]]
        if len(kept) != len(lines):
            write_atomic(csv, "".join(kept))


def write_atomic(path: Path, text: str) -> None:
    """Writes ``path`` so that a crash never leaves it half-written."""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def make_loggers(cfg: DictConfig, run_dir: Path, states: dict) -> dict:
    """TorchRL loggers by backend name; ``states`` (saved ``logger.state_dict()``) resumes them."""
    loggers = {}
    for backend in dict.fromkeys(["csv", *cfg.logger.backends]):  # csv always, once
        kwargs = {}
        if backend == "wandb":
            # get_logger forwards only `wandb_kwargs`; offline mode needs no account.
            kwargs = {"wandb_kwargs": {
                "offline": cfg.logger.wandb_mode == "offline",
                "project": cfg.logger.project,
                "config": OmegaConf.to_container(cfg, resolve=True, enum_to_str=True),
            }}
        if backend in states:
            kwargs["state_dict"] = states[backend]  # e.g. wandb: log to the same run id
        loggers[backend] = get_logger(backend, logger_name=str(run_dir), experiment_name="logs", **kwargs)
    return loggers


def logger_states(loggers: dict) -> dict:
    # The CSV logger's state is its history, already on disk: resume truncates the files instead.
    return {name: logger.state_dict() for name, logger in loggers.items() if name != "csv"}


def log_metrics(loggers, metrics: dict, step: int) -> None:
    values = {k: float(v.detach()) if torch.is_tensor(v) else float(v) for k, v in metrics.items() if v is not None}
    # Learned quantities reach here finite (DivergenceCheck runs first); what is dropped is
    # bookkeeping, e.g. the promotion threshold, -inf until the window W_k holds a trajectory.
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


def train_timing(train_clock, *, end: float, frames: int) -> dict:
    """Throughput of the part after warm-up, with TorchRL ``timeit`` totals and counts per phase."""
    if train_clock is None:  # the run ended within warm-up
        return {"train_frames": 0, "train_seconds": 0.0, "train_frames_per_second": None}
    t0, frames0 = train_clock
    seconds = end - t0
    return {"train_frames": frames - frames0, "train_seconds": seconds,
            "train_frames_per_second": (frames - frames0) / max(seconds, 1e-9),
            "time_seconds": {name: total for name, (_, total, _) in timeit._REG.items()},
            "counts": {"frames": frames - frames0, **{name: count for name, (_, _, count) in timeit._REG.items()}}}


def provenance() -> dict:
    """What produced a run: the code's git commit (``null`` outside a git checkout), whether
    tracked files differed from it, the library versions, and the CPU and thread count."""

    def git(*args):
        try:
            out = subprocess.run(["git", *args], cwd=Path(__file__).resolve().parent, capture_output=True,
                                 text=True, timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None
        return out.stdout.strip() if out.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no") if commit else None
    versions = {name: importlib.metadata.version(name)
                for name in ("torchrl_sail", "torch", "torchrl", "tensordict", "gymnasium", "mujoco")}
    return {"commit": commit, "dirty": None if status is None else bool(status), "versions": versions,
            "python": platform.python_version(), "cpu": platform.processor() or platform.machine(),
            "cpu_model": cpu_model(), "torch_threads": torch.get_num_threads()}


def cpu_model() -> str | None:
    """The CPU's model name (Linux ``/proc/cpuinfo``), ``None`` where it cannot be read."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def write_summary(run_dir: Path, cfg: DictConfig, *, teacher_return: float, alpha_switch_frame, **results) -> None:
    """``learning_curve.png`` (Figure 2 style) and ``summary.json`` of a run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    for tag, label, style in (("train/dense_return", "training return (noisy actions)", {"alpha": 0.35}),
                              ("eval/return", "eval return (deterministic)", {"marker": "o", "ms": 3})):
        steps, values = read_scalar(run_dir, tag)
        if steps:
            ax.plot(steps, values, label=label, **style)
    ax.axhline(teacher_return, ls="--", c="gray", label=f"teacher ({teacher_return:.0f})")
    if alpha_switch_frame is not None:
        ax.axvline(alpha_switch_frame, ls=":", c="red", label="alpha -> 0 (first promotion)")
    ax.set(xlabel="environment frames", ylabel="dense episode return",
           title=f"{cfg.algo.name} on {cfg.env.name}, seed {cfg.seed}")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(run_dir / "learning_curve.png", dpi=100)
    plt.close(fig)
    summary = {"env": cfg.env.name, "algo": cfg.algo.name, "seed": cfg.seed, "teacher_return": teacher_return,
               "total_frames": 0 if results.get("offline") else cfg.collector.total_frames,
               "alpha_switched_at_frame": alpha_switch_frame, **results,
               "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,  # Linux: KiB
               "learning_curve": "learning_curve.png", "provenance": provenance()}
    write_atomic(run_dir / "summary.json", json.dumps(summary, indent=2))
