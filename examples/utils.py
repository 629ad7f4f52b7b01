"""Builders of the training scripts (``sail_td3.py``, ``gail.py``, ``bc.py``) and ``evaluate.py``,
as in TorchRL's sota-implementations: one ``make_*`` function per piece, from the config.

Env and data (``make_env``, ``make_collector``, ``make_teacher``, ``make_replay``, ...), the
off-policy agent (``make_agent``, ``make_discriminator``, ``make_losses``, ``make_optimizers``,
``make_update``, ``make_reward``, ``make_rnd``) and the on-policy one (``make_ppo_models``).
"""

from __future__ import annotations

import copy
import math
import warnings
from functools import partial
from pathlib import Path

import torch
from config_schema import masks_absorbing_actions
from omegaconf import DictConfig, OmegaConf
from tensordict import TensorDict
from tensordict.nn import AddStateIndependentNormalScale, InteractionType, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.envs import ExplorationType
from torchrl.modules import (
    MLP,
    AdditiveGaussianModule,
    NormalParamExtractor,
    ProbabilisticActor,
    TanhModule,
    TanhNormal,
    ValueOperator,
)
from torchrl.objectives import RNDLoss, SACLoss, SoftUpdate

from torchrl_sail import (
    TRANSITION_KEYS,
    AbsorbingStateTransform,
    AlphaScheduler,
    DelayedRewardTransform,
    Discriminator,
    DiscriminatorLoss,
    DiscriminatorReward,
    FIFOTrajectoryWriter,
    NStepTransform,
    RNDReward,
    SAILLoss,
    TD3ExplorationPolicy,
    TD3Update,
    TeacherReplayBuffer,
    TopKTrajectoryWriter,
    UnionTrajectoryWriter,
    check_demonstration_dims,
    load_demonstrations,
    make_sail_env,
    observation_normalizer,
)
from torchrl_sail._compat import set_ray_weight_sync_timeout
from torchrl_sail.data import keep_columns, parse_columns, unreproduced_columns
from torchrl_sail.data.columns import column_ranges
from torchrl_sail.data.paper_teachers import reproduced_columns, teacher_env
from torchrl_sail.modules.init import reset_linears

# Teachers made by examples/make_teacher.py, one small dataset per env, shipped with the repo.
TEACHERS_DIR = Path(__file__).resolve().parent / "teachers"
_ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU}


# ----------------------------------------------------------------------------- env / data
def normalized_observation_key(cfg: DictConfig) -> str | None:
    """Where the PPO generator (gail, pofd) reads its observations: TorchRL's running normalisation of
    them (its PPO MuJoCo example's VecNorm), ``None`` for the other learners (and runs saved before it).
    ``"observation"`` stays raw: the demonstrations and the discriminator use it."""
    ppo = cfg.algo.ppo
    return "observation_norm" if cfg.algo.learner == "ppo" and ppo.get("normalize_observations", False) else None


def env_kwargs(cfg: DictConfig) -> dict:
    """``env.kwargs`` as the plain dict ``gymnasium.make`` takes (runs saved without it: ``{}``)."""
    kwargs = cfg.env.get("kwargs")
    return {} if kwargs is None else OmegaConf.to_container(kwargs, resolve=True)


def env_device(cfg: DictConfig) -> str | None:
    """The envs' device: none on the CPU (a device-less env is not moved to the CPU every step)."""
    return None if torch.device(cfg.device).type == "cpu" else cfg.device


def env_factory(cfg: DictConfig, *, render_size=None, num_envs: int = 1) -> partial:
    """The run's env constructor, unseeded: one recipe for this process's envs and the workers'
    (``num_envs`` > 1: a batched env of that many, ``make_sail_env``'s)."""
    return partial(
        make_sail_env,
        cfg.env.name,
        max_episode_steps=cfg.env.max_episode_steps,
        rounding=str(cfg.env.reward_rounding),
        absorbing_state=cfg.algo.absorbing_state,
        render_size=None if render_size is None else tuple(render_size),
        device=env_device(cfg),
        normalized_observation_key=normalized_observation_key(cfg),
        env_kwargs=env_kwargs(cfg),
        num_envs=num_envs,
    )


def make_env(cfg: DictConfig, seed: int, *, render_size=None, num_envs: int = 1):
    """The run's env, seeded; ``render_size=(width, height)`` also renders ``"pixels"`` (videos);
    ``num_envs`` > 1: a batched env whose env ``i`` is seeded ``seed + i * SEED_STRIDE``
    (``torchrl_sail.envs.SEED_STRIDE``)."""
    env = env_factory(cfg, render_size=render_size, num_envs=num_envs)()
    env.set_seed(seed)
    return env


def make_eval_env(cfg: DictConfig, seed: int, episodes: int):
    """The env of evaluations of ``episodes`` episodes from ``seed``: with ``eval.vectorized``, one
    batched env of ``episodes`` envs that plays them at once (``run_utils.evaluate_episodes``);
    else one env that plays them one after the other."""
    return make_env(cfg, seed, num_envs=episodes if cfg.eval.vectorized else 1)


def make_collector(cfg: DictConfig, env, policy, *, frames: int):
    """TorchRL's ``Collector`` for what is left of the budget after ``frames`` (0 on a fresh run)."""
    backend = str(cfg.collector.backend or ("process" if cfg.collector.num_workers > 1 else "direct"))
    # One env in this process: trajectory ids are not needed (episode ends are the done flags).
    kwargs = {"track_traj_ids": False}
    if backend != "direct":
        options = cfg.collector.backend_options
        kwargs = {
            "backend": backend,
            "num_collectors": cfg.collector.num_workers,
            "sync": True,
            "backend_options": {} if options is None else OmegaConf.to_container(options, resolve=True),
        }
        # Workers build their own env (seeded below) from the installed package, so remote
        # workers (Ray actors) need torchrl_sail installed but not this examples/ folder.
        env = env_factory(cfg)
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
        set_ray_weight_sync_timeout(cfg.collector.weight_sync_timeout_s)
        # First push now, before any batch: it connects TorchRL's RayWeightSyncScheme (a gloo
        # group of the learner and the actors), so a failure stops the run before it trains.
        # Later pushes (one per batch, in the loop) reuse the group.
        collector.update_policy_weights_()
    return collector


def make_nstep(cfg: DictConfig) -> NStepTransform | None:
    """DDPGfD's n-step view of stored transitions (``algo.nstep``), ``None`` for the 1-step methods."""
    return None if cfg.algo.nstep is None else NStepTransform(cfg.algo.nstep.n, cfg.optim.gamma)


def stored_keys(cfg: DictConfig) -> list:
    """The entries every stored transition keeps: TRANSITION_KEYS, and the n-step view with ``algo.nstep``."""
    nstep = make_nstep(cfg)
    return [*TRANSITION_KEYS, *(nstep.out_keys_inv if nstep is not None else ())]


def make_absorbing(cfg: DictConfig, action_spec=None) -> AbsorbingStateTransform | None:
    """``algo.absorbing_*`` as a transform of stored transitions (``None`` without absorbing states).

    ``action_spec`` is the agent's: with ``algo.absorbing_action=random`` the agent's absorbing
    transitions store a random action (the SAIL authors' DAC); the demonstrations' always the zero action.
    """
    if not cfg.algo.absorbing_state:
        return None
    random = cfg.algo.absorbing_action == "random" and action_spec is not None
    return AbsorbingStateTransform(bootstrap=cfg.algo.absorbing_bootstrap, action_spec=action_spec if random else None)


def make_teacher(cfg: DictConfig, env, absorbing: AbsorbingStateTransform | None = None):
    """The teacher buffer seeded with the demonstrations, the teacher's best dense return, its path.

    With ``absorbing`` (DAC), the demonstrations get the indicator and the absorbing transitions
    the agent's data gets.
    """
    path = Path(cfg.teacher.path).expanduser() if cfg.teacher.path else TEACHERS_DIR / cfg.env.name
    if cfg.teacher.path is None and not path.exists():
        raise FileNotFoundError(
            f"No teacher.path given and no shipped teacher for env {cfg.env.name!r} at {path}. Pass "
            f"teacher.path=<file.npz|dataset folder|minari:<dataset id>> (the paper's files: `python -m "
            f"torchrl_sail.data.download`, then e.g. teacher.path=<that folder>/"
            f"expert_data_no_img_Hopper_scores_1500_episodes_1.npz for Hopper) or make one with "
            f"`python examples/make_teacher.py env={cfg.env.name}`."
        )
    # The env appends the time feature: a file recorded without it gets it computed from the
    # episode steps ("minari:<id>" survives Path: load_demonstrations reads it).
    demos, meta = load_demonstrations(path, max_episode_steps=cfg.env.max_episode_steps, time_feature=True)
    demos = select_teacher_columns(cfg, demos)
    check_teacher_columns(cfg, demos["observation"], path)
    # The buffer ranks trajectories by r_e (floor(0.1 R) by default), the only reward the learner
    # sees: the demonstrations' is computed as the env computes the agent's.
    demos = DelayedRewardTransform(rounding=str(cfg.env.reward_rounding)).forward(demos).select(*TRANSITION_KEYS)
    if absorbing is not None:
        demos = absorbing(demos)
    check_demonstration_dims(demos, env=env, source=str(path), env_name=cfg.env.name)
    nstep = make_nstep(cfg)
    if nstep is not None:  # DDPGfD: the demonstrations' n-step view, as the agent's (whole episodes)
        demos = nstep.apply_to_trajectories(demos)
    t, keys = cfg.teacher, stored_keys(cfg)
    if t.eviction == "fifo":  # the authors' transition ring
        writer = FIFOTrajectoryWriter(k=t.k, capacity=t.capacity, keys=keys)
    elif t.eviction == "union":  # the paper's R_T <- R_T U tau: room for the demonstrations and every frame
        writer = UnionTrajectoryWriter(k=t.k, capacity=demos.numel() + cfg.collector.total_frames, keys=keys)
    else:  # the K best trajectories, the paper's window as the buffer (+ 1 row: an absorbing transition)
        writer = TopKTrajectoryWriter(
            k=t.k, max_trajectory_length=cfg.env.max_episode_steps + (absorbing is not None), keys=keys
        )
    buffer = TeacherReplayBuffer(writer, device=cfg.device)
    buffer.add_demonstrations(demos)
    return buffer, float(max(meta["episode_returns"])), str(path)


def select_teacher_columns(cfg: DictConfig, demos):
    """The demonstrations with only the observation columns ``teacher.keep_columns`` names, or without
    those ``teacher.drop_columns`` names (both count the file's columns, the time feature included)."""
    t, width = cfg.teacher, demos["observation"].shape[-1]
    if t.keep_columns is not None:
        key, spec = "teacher.keep_columns", t.keep_columns
        kept = parse_columns(spec, width, key=key)
    elif t.drop_columns is not None:
        key, spec = "teacher.drop_columns", t.drop_columns
        dropped = set(parse_columns(spec, width, key=key))
        kept = [column for column in range(width) if column not in dropped]
    else:
        return demos
    if width - 1 not in kept:  # make_env appends the time feature: the demonstrations need theirs
        raise ValueError(
            f"{key}='{spec}' leaves out column {width - 1}, the time feature 1 - t/T (the file's last column, "
            f"appended on loading where the file has none), which the env appends to its observations: keep it."
        )
    return keep_columns(demos, kept)


def check_teacher_columns(cfg: DictConfig, teacher_observations: torch.Tensor, source) -> None:
    """Names, before training, the teacher's observation columns the env does not reproduce
    (:func:`~torchrl_sail.data.unreproduced_columns` against a random rollout of ``teacher.column_check_steps``
    steps, on an env of its own: the training env's stream is untouched), with the choices;
    ``teacher.column_check`` says whether to warn, to stop, or not to look."""
    if cfg.teacher.column_check == "off":
        return
    env = make_env(cfg, cfg.seed + 40_000)
    with torch.random.fork_rng(devices=[]):  # random actions that leave the run's own random stream as it was
        torch.manual_seed(cfg.seed + 40_000)
        rollout = env.rollout(cfg.teacher.column_check_steps, break_when_any_done=False)
    env.close()
    env_observations = rollout["observation"].reshape(-1, rollout["observation"].shape[-1])
    # episode ids: a column the env holds constant through each episode (a goal) is reproduced
    done = rollout["next", "done"].reshape(-1).long()
    episodes = torch.cumsum(done, 0) - done
    width = teacher_observations.shape[-1]
    if cfg.algo.absorbing_state:  # DAC's env appends the absorbing indicator, the demonstrations get it later
        env_observations = env_observations[..., :-1]
    if env_observations.shape[-1] != width:  # check_demonstration_dims says why, next
        return
    found = unreproduced_columns(teacher_observations.reshape(-1, width), env_observations, env_episodes=episodes)
    if not found:
        return
    lines = [
        f"teacher {source}: {len(found)} of its {width} observation columns are not what {cfg.env.name} "
        f"produces (a random rollout of {cfg.teacher.column_check_steps} steps), so the discriminator can tell "
        f"the teacher's rows from the agent's by them alone:"
    ]
    for kind, what in (("constant", "constant in the teacher, varying in the env"), ("outside", "far outside")):
        columns = [c for c in found if c["kind"] == kind]
        if columns:
            t, e = columns[0]["teacher"], columns[0]["env"]
            lines.append(
                f"  columns {column_ranges([c['column'] for c in columns])}: {what} (column {columns[0]['column']}: "
                f"teacher {t[0]:.3g} to {t[1]:.3g}, env {e[0]:.3g} to {e[1]:.3g})"
            )
    named = {c["column"] for c in found}
    teacher_constant = teacher_observations.reshape(-1, width).amin(0) == teacher_observations.reshape(-1, width).amax(
        0
    )
    env_constant = env_observations.amin(0) == env_observations.amax(0)
    quiet = [c for c in range(width) if teacher_constant[c] and env_constant[c] and c not in named]
    if quiet:  # a random rollout may leave still what an agent moves: the user sees the whole block
        lines.append(
            f"  columns {column_ranges(quiet)}: constant in the teacher and in this rollout too, which may part "
            f"once the agent moves otherwise"
        )
    name = Path(str(source)).name
    published = teacher_env(name)
    if published is not None and published[1]:
        lines.append(f"  (the authors' {published[0]} files: {published[1]})")
    drop = reproduced_columns(name)
    if drop is None:
        drop = (
            f"teacher.drop_columns='{column_ranges(sorted(named))}' and env.kwargs that make the env produce the "
            f"columns kept (e.g. env.kwargs.use_contact_forces=false for Ant's contact forces)"
        )
    lines.append(
        f"Choices: train as it is (teacher.column_check=off hides this, =error stops here), or train on the "
        f"columns the env reproduces: {drop}."
    )
    message = "\n".join(lines)
    if cfg.teacher.column_check == "error":
        raise ValueError(message)
    warnings.warn(message, UserWarning, stacklevel=2)


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


# ----------------------------------------------------------------------------- off-policy agent (TD3, SAC)
def make_agent(cfg: DictConfig, env):
    """Actor, critic and exploration policy: TD3's deterministic actor with Gaussian noise, or
    (``algo.learner=sac``) SAC's tanh-Gaussian actor, which explores by sampling; their linear
    layers initialised by ``network.actor_critic_init``."""
    actor, critic, policy = _make_agent(cfg, env)
    init = cfg.network.actor_critic_init
    if init != "torch":  # "torch" keeps the layers (and the RNG stream) as built
        reset_linears(actor, init)
        reset_linears(critic, init)
        if init == "orthogonal":  # Kostrikov et al.'s release: the actor's output layer at gain 0.01
            output = [layer for layer in actor.modules() if isinstance(layer, nn.Linear)][-1]
            with torch.no_grad():
                output.weight.mul_(0.01)  # orthogonal at gain g is g times the gain-1 draw
    return actor, critic, policy


def _make_agent(cfg: DictConfig, env):
    obs_dim = env.observation_spec["observation"].shape[-1]
    action_spec = env.action_spec
    act_dim = action_spec.shape[-1]
    activation = _ACTIVATIONS[cfg.network.activation]
    norm = (
        {"norm_class": nn.LayerNorm, "norm_kwargs": [{"normalized_shape": cells} for cells in cfg.network.critic_cells]}
        if cfg.network.critic_layer_norm
        else {}
    )
    critic = ValueOperator(
        MLP(
            in_features=obs_dim + act_dim,
            out_features=1,
            num_cells=list(cfg.network.critic_cells),
            activation_class=activation,
            device=cfg.device,
            **norm,
        ),
        in_keys=["action", "observation"],
    )
    if masks_absorbing_actions(cfg):
        # DAC's release: Q(s_a, 0) at the absorbing state, whatever action reaches it (TD3's target
        # noise included: the release zeroes the noisy target action there)
        critic = TensorDictSequential(AbsorbingStateTransform().action_mask(), critic)
    if cfg.algo.learner == "sac":
        # TorchRL's sota SAC actor: MLP -> (loc, softplus scale) -> TanhNormal on the action bounds
        net = nn.Sequential(
            MLP(
                in_features=obs_dim,
                out_features=2 * act_dim,
                num_cells=list(cfg.network.actor_cells),
                activation_class=activation,
                device=cfg.device,
            ),
            NormalParamExtractor(scale_mapping="biased_softplus_1.0", scale_lb=0.1),
        )
        actor = ProbabilisticActor(
            TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"]),
            in_keys=["loc", "scale"],
            spec=action_spec,
            distribution_class=TanhNormal,
            distribution_kwargs={"low": action_spec.space.low, "high": action_spec.space.high, "tanh_loc": False},
            default_interaction_type=InteractionType.RANDOM,
        )
        return actor, critic, actor
    actor = TensorDictSequential(
        TensorDictModule(
            MLP(
                in_features=obs_dim,
                out_features=act_dim,
                num_cells=list(cfg.network.actor_cells),
                activation_class=activation,
                device=cfg.device,
            ),
            in_keys=["observation"],
            out_keys=["param"],
        ),
        TanhModule(in_keys=["param"], out_keys=["action"], spec=action_spec),
        # DAC: pi(s_a) = 0, the action the absorbing transitions store (only read where s_a is bootstrapped)
        *([AbsorbingStateTransform().action_mask()] if masks_absorbing_actions(cfg) else []),
    )
    noise = None
    if cfg.env.exploration_noise > 0:
        # Gaussian noise in RANDOM exploration mode only; projected onto the action bounds.
        noise = AdditiveGaussianModule(spec=action_spec, sigma_init=1.0, sigma_end=1.0, std=cfg.env.exploration_noise)
    if masks_absorbing_actions(cfg):  # DAC's masked actor: TorchRL's sequence
        return actor, critic, TensorDictSequential(actor, *([noise] if noise is not None else []))
    # the same action as TensorDictSequential(actor, noise), one tensordict read and write per env step
    return actor, critic, TD3ExplorationPolicy(actor, noise)


# |tanh(x)| >= 0.99 from |x| >= atanh(0.99) = 2.65 on, where the actor's gradient through its
# tanh, 1 - tanh(x)^2, is below 0.02 of its value at 0
SATURATED_PREACTIVATION = math.atanh(0.99)


@torch.no_grad()
def actor_saturation(cfg: DictConfig, actor, batch) -> dict:
    """How far the TD3 actor's tanh is saturated on the agent's rows of a batch (``{}`` for SAC).

    ``actor/saturation``: the share of action components with ``|tanh(x)| >= 0.99``, ``x`` the
    actor's pre-tanh output; ``actor/preactivation``: the mean ``|x|``. An actor saturated on
    every component no longer moves (its gradient through the tanh vanishes), whatever its
    critic says: what a stalled run looks like from the actor's side.
    """
    if cfg.algo.learner != "td3":
        return {}
    body = actor.module[0]  # the MLP before TanhModule (make_agent)
    x = body(batch.select(*body.in_keys).copy())[body.out_keys[0]].abs()
    # the agent's rows by weight, not by index: no host sync (a batch without one gives 0, finite for the
    # divergence check; sail_td3.py calls this only when alpha < 1)
    agent = (~batch["is_teacher"]).reshape(-1, 1).to(x.dtype) if "is_teacher" in batch.keys() else x.new_ones(len(x), 1)
    count = (agent.sum() * x.shape[-1]).clamp_min(1)
    return {
        "actor/saturation": ((x >= SATURATED_PREACTIVATION).to(x.dtype) * agent).sum() / count,
        "actor/preactivation": (x * agent).sum() / count,
    }


class ActorDrift:
    """How far one TD3 block moves the actor, on the observations of a batch of that block.

    ``start(batch)`` before the block's updates records the actor's actions on the batch's
    observations; ``measure()`` after it gives ``actor/change``, the mean ``|a_after - a_before|``
    over rows and action components, and ``actor/target_gap``, the same distance from the target
    actor (the Polyak average that evaluations may use instead). A large change per block with a
    small target gap is an online actor that swings around a steadier average.
    """

    def __init__(self, actor, loss) -> None:
        self.actor, self.loss = actor, loss
        self.observations = self.before = None

    @torch.no_grad()
    def _actions(self, params=None) -> torch.Tensor:
        if params is None:
            return self.actor(self.observations.copy())["action"]
        with params.to_module(self.actor, preserve_module_state=False):
            return self.actor(self.observations.copy())["action"]

    def start(self, batch) -> None:
        self.observations = batch.select(*self.actor.in_keys).clone()
        self.before = self._actions()

    def measure(self) -> dict:
        after = self._actions()
        target = self._actions(self.loss.target_actor_network_params)
        return {
            "actor/change": (after - self.before).abs().mean(),
            "actor/target_gap": (after - target).abs().mean(),
        }


def make_discriminator(cfg: DictConfig, env) -> Discriminator:
    return Discriminator(
        env.observation_spec["observation"].shape[-1],
        env.action_spec.shape[-1],
        num_cells=tuple(cfg.network.discriminator_cells),
        activation_class=_ACTIVATIONS[cfg.network.discriminator_activation],
        normalize_observations=cfg.network.normalize_observations,
        spectral_norm=cfg.network.discriminator_spectral_norm,
        init=str(cfg.network.discriminator_init),
    ).to(cfg.device)


def make_discriminator_loss(cfg: DictConfig, discriminator: Discriminator) -> DiscriminatorLoss:
    d = cfg.optim.discriminator
    return DiscriminatorLoss(
        discriminator,
        entropy_coef=d.entropy_coef,
        gp_coef=d.gp_coef,
        label_smoothing=d.label_smoothing,
        instance_noise=d.instance_noise,
    ).to(cfg.device)


def discriminator_step(cfg: DictConfig, d_loss: DiscriminatorLoss, optimizer, batch) -> dict:
    """One D minibatch: the loss, then Adam's step unless D already tells the two sides apart beyond
    ``optim.discriminator.max_accuracy`` on this batch (its balanced accuracy); ``d/skipped`` says which."""
    out = d_loss(batch)
    bound = cfg.optim.discriminator.max_accuracy
    skip = bound is not None and (out["accuracy_teacher"] + out["accuracy_agent"]).item() / 2 > bound
    if not skip:
        sum(value for key, value in out.items() if key.startswith("loss_")).backward()
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
    return {**{f"d/{key}": value.detach() for key, value in out.items()}, "d/skipped": float(skip)}


def discriminator_block(cfg: DictConfig, d_loss: DiscriminatorLoss, optimizer, batches, after_step=None) -> dict:
    """D's steps on a sampled block (``batches``: ``[steps, rows]``): the last step's ``d/*`` metrics, with
    ``d/skipped`` the block's share of skipped steps. ``after_step(batch)`` runs after each D step (RND's
    predictor learns from the same rows) and its metrics are returned too."""
    metrics, skipped = {}, 0.0
    for batch in batches.unbind(0):
        metrics.update(discriminator_step(cfg, d_loss, optimizer, batch))
        skipped += metrics["d/skipped"]
        if after_step is not None:
            metrics.update(after_step(batch))
    metrics["d/skipped"] = skipped / batches.shape[0]
    return metrics


def make_reward(cfg: DictConfig, discriminator: Discriminator, rnd: RNDReward | None = None, **kwargs):
    """The sample-time reward of ``algo.reward``, then ``rnd``'s bonus if given (``None``: the env's reward)."""
    r = cfg.algo.reward
    reward = None
    if r.source != "env":
        reward = DiscriminatorReward(
            discriminator,
            kind=r.kind,
            coef=r.coef,
            clip=None if r.clip is None else tuple(r.clip),
            shift=r.shift,
            mode="add" if r.source == "shaped" else "replace",
            **kwargs,
        )
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
        return MLP(
            in_features=obs_dim,
            out_features=r.features,
            num_cells=list(r.cells),
            activation_class=_ACTIVATIONS[r.activation],
            device=cfg.device,
        )

    rnd = RNDReward(net(), net(), coef=r.coef, row_id_key="row_id")  # once per distinct row of a block
    env.append_transform(rnd)
    rnd.train()  # append_transform leaves transforms in eval mode, where RND's statistics stay frozen
    return rnd, RNDLoss(rnd.predictor_network, rnd.target_network)


class TeacherShare:
    """Where SAC runs keep SAIL's alpha: ``SACLoss.alpha`` is SAC's entropy temperature, and
    the share acts through the batch composition alone (``MixedReplayBuffer``)."""

    def __init__(self, alpha: float) -> None:
        self.alpha = alpha


def twin_critics(cfg: DictConfig, critic, num_qvalue_nets: int = 2):
    """The critics a loss trains. Given one critic, ``TD3Loss`` and ``SACLoss`` draw all
    ``num_qvalue_nets`` anew, each weight uniform between the critic's smallest and largest: the law
    of TorchRL's default and of Xavier's uniform draw, but about twice the spread of an orthogonal one.
    So with ``network.actor_critic_init=orthogonal`` the loss gets a list: the critic and copies of it,
    each drawn by that init."""
    if cfg.network.actor_critic_init != "orthogonal":
        return critic
    copies = [copy.deepcopy(critic) for _ in range(num_qvalue_nets - 1)]
    for copied in copies:
        reset_linears(copied, "orthogonal")
    return [critic, *copies]


def make_losses(cfg: DictConfig, actor, critic, discriminator, action_spec):
    o, a = cfg.optim, cfg.algo.alpha
    critic = twin_critics(cfg, critic)
    if cfg.algo.learner == "sac":
        loss = SACLoss(
            actor,
            critic,
            num_qvalue_nets=2,
            loss_function=o.loss_function,
            alpha_init=cfg.algo.sac.alpha_init,
            fixed_alpha=cfg.algo.sac.fixed_alpha,
            action_spec=action_spec,
        )
        share = TeacherShare(a.initial)
    else:
        # mixing="batch": alpha acts through the batch composition alone (the authors' code).
        loss = SAILLoss(
            actor,
            critic,
            action_spec=action_spec,
            alpha=a.initial,
            mixing="batch",
            policy_noise=o.policy_noise,
            noise_clip=o.noise_clip,
            loss_function=o.loss_function,
            preactivation_coef=o.actor_preactivation_coef,
            # the prioritized batches' importance weights (DDPGfD), reduced as PER or TorchRL does
            weight_normalization="sum" if cfg.algo.per is None else str(cfg.algo.per.weight_normalization),
        )
        share = loss
    loss.make_value_estimator(gamma=o.gamma)
    if o.truncation_is_terminal and not masks_absorbing_actions(cfg):
        # The authors store done = 1 at time-limit truncation too: no bootstrap there. With
        # bootstrapped absorbing states (DAC) only terminations end an episode, through s_a.
        loss.set_keys(terminated="done")
    updater = SoftUpdate(loss, tau=o.tau)
    scheduler = AlphaScheduler(share, mode=a.mode, initial=a.initial, final=a.final, anneal_frames=a.anneal_frames)
    return loss, updater, scheduler, make_discriminator_loss(cfg, discriminator)


def actor_lr(cfg: DictConfig) -> float:
    """The actor's learning rate: ``optim.actor_lr``, or ``optim.lr`` (the critic's) where it is null."""
    return cfg.optim.lr if cfg.optim.actor_lr is None else cfg.optim.actor_lr


def make_optimizers(cfg: DictConfig, loss, discriminator, rnd: RNDReward | None = None) -> dict:
    # fused Adam: one kernel for all parameters of a network (CPU and CUDA).
    adam = partial(torch.optim.Adam, fused=True)
    # a CUDA graph cannot read Adam's step count on the host
    td3_adam = partial(adam, capturable=cfg.optim.cudagraphs)
    # DDPGfD's lambda_2 (algo.l2_coef): Adam's coupled weight decay adds l2_coef * theta to the
    # gradient, i.e. l2_coef / 2 * ||theta||^2 in the actor's and the critic's losses (0: none)
    l2 = cfg.algo.l2_coef
    optimizers = {
        # convert_to_functional re-samples and stacks the twin Q params: optimise the loss's copy.
        "critic": td3_adam(loss.qvalue_network_params.flatten_keys().values(), lr=cfg.optim.lr, weight_decay=l2),
        "actor": td3_adam(loss.actor_network_params.flatten_keys().values(), lr=actor_lr(cfg), weight_decay=l2),
        "discriminator": adam(discriminator.parameters(), lr=cfg.optim.discriminator.lr),
    }
    if rnd is not None:
        optimizers["rnd"] = adam(rnd.predictor_network.parameters(), lr=cfg.algo.rnd.lr)
    if cfg.algo.learner == "sac" and not cfg.algo.sac.fixed_alpha:  # SAC's learned entropy temperature
        optimizers["alpha"] = adam([loss.log_alpha], lr=cfg.algo.sac.alpha_lr)
    return optimizers


def make_update(cfg: DictConfig, loss, optimizers: dict, target_updater):
    """One gradient step ``update(batch, update_actor) -> metrics``: TD3's fused implementation or
    the loss's own (``optim.implementation=loss``); for SAC, TorchRL's ``SACLoss`` as its sota script
    steps it (actor, critics and a learned temperature every step, then the targets)."""
    if cfg.algo.learner != "sac":
        # DAC's masked actor is not the fused step's MLP + tanh: it runs the loss's own step
        implementation = "loss" if masks_absorbing_actions(cfg) else cfg.optim.implementation
        nstep = make_nstep(cfg)  # DDPGfD: + lambda_1 * the TD loss of each row's stored n-step view
        nstep_kwargs = {} if nstep is None else {"nstep_key": nstep.out_key, "nstep_weight": cfg.algo.nstep.lambda1}
        return TD3Update(
            loss,
            critic_optimizer=optimizers["critic"],
            actor_optimizer=optimizers["actor"],
            target_updater=target_updater,
            implementation=implementation,
            precision=cfg.optim.precision,
            actor_max_grad_norm=cfg.optim.actor_max_grad_norm,
            cudagraphs=cfg.optim.cudagraphs,
            td_error=cfg.algo.per is not None,  # DDPGfD's priorities start from each row's delta^2
            **nstep_kwargs,
        )
    steps = [optimizers[name] for name in ("critic", "actor", "alpha") if name in optimizers]
    learned_temperature = "alpha" in optimizers

    def sac_update(batch, update_actor: bool) -> dict:  # noqa: ARG001 (SAC updates its actor every step)
        out = loss(batch)
        (out["loss_qvalue"] + out["loss_actor"] + out["loss_alpha"]).backward()
        for optimizer in steps:
            optimizer.step()
            optimizer.zero_grad(set_to_none=True)
        target_updater.step()
        # SAC's alpha is its entropy temperature; "alpha" in the logs is SAIL's teacher share
        metrics = {
            "loss_qvalue": out["loss_qvalue"].detach(),
            "loss_actor": out["loss_actor"].detach(),
            "temperature": out["alpha"].detach(),
            "entropy": out["entropy"].detach(),
        }
        if learned_temperature:
            metrics["loss_temperature"] = out["loss_alpha"].detach()
        return metrics

    return sac_update


# ----------------------------------------------------------------------------- on-policy agent (PPO: GAIL, POfD)
def make_ppo_models(cfg, env):
    """TorchRL's sota PPO/GAIL networks for MuJoCo: tanh MLPs, a state-independent scale, TanhNormal.

    Both read the normalised observations when the run normalises them (``algo.ppo.normalize_observations``).
    """
    key = normalized_observation_key(cfg) or "observation"
    obs_dim, spec = env.observation_spec[key].shape[-1], env.action_spec
    policy = nn.Sequential(
        MLP(
            in_features=obs_dim,
            out_features=spec.shape[-1],
            num_cells=list(cfg.algo.ppo.cells),
            activation_class=nn.Tanh,
            device=cfg.device,
        ),
        AddStateIndependentNormalScale(spec.shape[-1], scale_lb=1e-8, device=cfg.device),
    )
    value = MLP(
        in_features=obs_dim,
        out_features=1,
        num_cells=list(cfg.algo.ppo.cells),
        activation_class=nn.Tanh,
        device=cfg.device,
    )
    for net, gain in ((policy[0], 1.0), (value, 0.01)):
        for layer in net.modules():
            if isinstance(layer, nn.Linear):
                nn.init.orthogonal_(layer.weight, gain)
                layer.bias.data.zero_()
    actor = ProbabilisticActor(
        TensorDictModule(policy, in_keys=[key], out_keys=["loc", "scale"]),
        in_keys=["loc", "scale"],
        spec=spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": spec.space.low, "high": spec.space.high, "tanh_loc": False},
        return_log_prob=True,
        default_interaction_type=ExplorationType.RANDOM,
    )
    return actor, ValueOperator(value, in_keys=[key])


def copy_observation_norm(source_env, target_env) -> None:
    """Gives ``target_env``'s observation normaliser the statistics of ``source_env``'s, frozen.

    Evaluation and video envs run the training statistics without updating them (a copy: the
    training env's own are never touched by an evaluation). Envs without a normaliser: nothing.
    """
    source, target = observation_normalizer(source_env), observation_normalizer(target_env)
    if target is None:
        return
    target.load_state_dict(copy.deepcopy(source.state_dict()))
    target.freeze()
