"""The config of the training scripts: its typed schema, the source of every default, and its checks.

``conf/config.yaml`` lists ``sail_config`` (:class:`SAILConfig`) first in its defaults, so every
YAML file and every command-line override is merged into these dataclasses: a value of the
wrong type (``optim.lr=abc``), a choice outside its set (``network.activation=gelu``) or an
unknown key is rejected by Hydra with the full key named, before anything is built.

The defaults here are SAIL's on MuJoCo, the SAIL authors' code (``docs/paper_vs_code.md`` says
where it departs from the paper and which reading is the default). The YAML files hold only
what differs from them: ``conf/env/<env>.yaml`` per env, ``conf/algo/<method>.yaml`` per method,
``conf/algo_env/<method>_<env>.yaml`` where a method's own code departs from the env file, and
``conf/config.yaml`` the defaults list and Hydra's settings. :func:`check_config` keeps what a
type cannot say: ranges, rules across fields, and options that need a package or device this
machine lacks. :data:`SCRIPTS` names the script that trains each ``algo.learner``.
"""

from __future__ import annotations

import copy
import importlib.util
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import II, MISSING, DictConfig, OmegaConf


class Choice(str, Enum):
    """A string from a fixed set: compares, hashes and formats as the plain string."""

    def __str__(self) -> str:
        return self.value

    __format__ = str.__format__


Learner = Choice("Learner", {name: name for name in ("td3", "sac", "bc", "ppo")})
AlphaMode = Choice("AlphaMode", {name: name for name in ("dynamic", "linear", "constant")})
AgentData = Choice("AgentData", {name: name for name in ("replay", "recent")})
RewardSource = Choice("RewardSource", {name: name for name in ("discriminator", "env", "shaped")})
RewardKind = Choice("RewardKind", {name: name for name in ("gail", "airl")})
AbsorbingAction = Choice("AbsorbingAction", {name: name for name in ("zero", "random")})
Eviction = Choice("Eviction", {name: name for name in ("topk", "union", "fifo")})
ColumnCheck = Choice("ColumnCheck", {name: name for name in ("warn", "error", "off")})
Implementation = Choice("Implementation", {name: name for name in ("fused", "loss")})
Precision = Choice("Precision", {name: name for name in ("fp32", "bf16")})
# an actor of a run: online (the one the TD3 or SAC step trains), target (a TD3 learner's target
# actor, the Polyak average of its recent weights) or average (eval.average_frames' longer average)
EvaluatedActor = Choice("EvaluatedActor", {name: name for name in ("online", "target", "average")})
# a run's last checkpoint, the best policy it kept (eval.best_policy) or the policy at its best evaluation
EvaluatedPolicy = Choice("EvaluatedPolicy", {name: name for name in ("last", "best", "best_evaluated")})
LossFunction = Choice("LossFunction", {name: name for name in ("l1", "l2", "smooth_l1")})
Activation = Choice("Activation", {name: name for name in ("relu", "tanh", "elu")})
# a linear layer's init: torchrl_sail.modules.init.LINEAR_INITS (tests/test_config.py keeps the two alike)
LayerInit = Choice("LayerInit", {name: name for name in ("xavier", "orthogonal", "torch")})
Cadence = Choice("Cadence", {name: name for name in ("frames", "episodes")})
BlockOrder = Choice("BlockOrder", {name: name for name in ("td3_first", "discriminator_first")})
# what a mean loss divides the importance-weighted sum by: the rows (PER's) or the weights' sum (TorchRL's)
WeightNormalization = Choice("WeightNormalization", {name: name for name in ("count", "sum")})
Backend = Choice("Backend", {name: name for name in ("direct", "process", "ray")})
LoggerBackend = Choice("LoggerBackend", {name: name for name in ("csv", "wandb", "tensorboard")})
WandbMode = Choice("WandbMode", {name: name for name in ("offline", "online")})
VideoFormat = Choice("VideoFormat", {name: name for name in ("mp4", "gif")})
RewardRounding = Choice("RewardRounding", {name: name for name in ("floor", "none")})


@dataclass
class EnvConfig:
    """``conf/env/<name>.yaml`` sets ``name`` and what differs from these (the SAIL authors' Hopper settings)."""

    name: str = MISSING
    max_episode_steps: int = 1000
    exploration_noise: float = 0.2  # std of the Gaussian action noise after warm-up (authors' sail.yml)
    replay_size: int = 1_000_000  # agent replay buffer R_B, transitions
    # teacher ring size in transitions for teacher.eviction=fifo (authors' demo_buffer_size)
    teacher_capacity: int = 100_000
    # keyword arguments of gymnasium.make: env.kwargs.<name>=<value> where the env file sets the key
    # (Ant-v4's use_contact_forces), +env.kwargs.<name>=<value> where it does not
    kwargs: dict[str, Any] = field(default_factory=dict)
    # the trajectory-wise reward r_e, the agent's and the demonstrations': floor = the paper's
    # floor(0.1 R) | none = 0.1 R, so promotion compares returns as the authors' code does
    reward_rounding: RewardRounding = RewardRounding.floor


@dataclass
class AlphaConfig:
    """The teacher share alpha of TD3 batches (``round(alpha * batch_size)`` teacher rows)."""

    mode: AlphaMode = (
        AlphaMode.dynamic
    )  # dynamic: `initial` until the first promotion, then `final` | linear | constant
    initial: float = 0.5
    final: float = 0.0
    anneal_frames: int | None = None  # for mode=linear


@dataclass
class RewardConfig:
    """The reward the learner learns from, recomputed with the current D at sample time."""

    # discriminator: D's reward alone (SAIL, DAC) | env: the delayed env reward alone (no D is
    # trained) | shaped: the delayed env reward + coef * D's reward (pofd, pofd_td3)
    source: RewardSource = RewardSource.discriminator
    kind: RewardKind = RewardKind.gail  # gail: -log(1 - D) (SAIL, GAIL) | airl: log D - log(1 - D) (DAC, AIRL)
    clip: list[float] | None = None  # [low, high]: D clipped before the reward (the SAIL authors' DAC)
    # added before coef: r = coef * (f(D) + shift); -0.693147 (-log 2) centres -log(1 - D) at D = 1/2,
    # negative where D says agent (the weak-teacher candidate, docs/training.md); ours, not the authors'
    shift: float = 0.0
    coef: float = 1.0  # weight of D's reward
    # learner=ppo: coef *= coef_decay after every on-policy batch (this repo's option; POfD's lambda_1 is constant here)
    coef_decay: float = 1.0


@dataclass
class RNDConfig:
    """A random-network-distillation bonus (Burda et al. 2019) added to the reward (algo=sail_rnd)."""

    # r = -log(1 - D) + coef * bonus (bonus / its running std, clipped at 5): 0.01 is the ceiling of the
    # SAIL authors' dormant schedule; at 1 the bonus (about 3 per step) outweighs D's reward (under 1)
    coef: float = 0.01
    lr: float = 1.0e-4  # the predictor's Adam (RND's value)
    cells: list[int] = field(default_factory=lambda: [256, 256])  # target and predictor MLPs
    activation: Activation = Activation.relu  # of their hidden layers (RND's, and the SAIL authors' dormant code)
    features: int = 64


@dataclass
class PPOConfig:
    """The PPO generator of GAIL and POfD (learner=ppo): TorchRL's sota PPO MuJoCo settings, which
    its GAIL example shares."""

    frames_per_batch: int = 2048  # on-policy batch (TorchRL: 2048; the authors' GAIL baseline: 2048 with TRPO)
    epochs: int = 10
    minibatch_size: int = 64
    lr: float = 3.0e-4  # Adam, eps 1e-5, for the actor and the critic
    clip_epsilon: float = 0.2
    gae_lambda: float = 0.95
    entropy_coef: float = 0.0
    critic_coef: float = 0.25
    loss_critic_type: LossFunction = LossFunction.l2
    anneal_lr: bool = True  # lr * (1 - updates / all updates of collector.total_frames), per update
    anneal_clip_epsilon: bool = False
    # the actor and critic read TorchRL's VecNorm of the observations (decay 0.99999, eps 1e-2),
    # clipped to [-10, 10], the time feature raw; D reads the raw observations, as the teacher's are
    normalize_observations: bool = True
    cells: list[int] = field(default_factory=lambda: [64, 64])


@dataclass
class SACConfig:
    """learner=sac: TorchRL's SACLoss (the TD3 settings lr, gamma, tau, batch apply).

    The SAIL authors' SAC (hyperparams/sac.yml, Hopper-v2 and HalfCheetah-v2) fixes the entropy
    temperature at 0.01; TorchRL's sota SAC learns it from 1.0 (fixed_alpha=false, alpha_init=1.0).
    """

    fixed_alpha: bool = True  # the authors'; false: learned towards TorchRL's target entropy -dim(A)
    alpha_init: float = 0.01  # the temperature (fixed), or its initial value (learned)
    alpha_lr: float = 3.0e-4  # the learned temperature's Adam (TorchRL's sota SAC)


@dataclass
class BCConfig:
    """Behaviour cloning (learner=bc): TorchRL's BCLoss (MSE on the teacher's actions), Adam."""

    # the authors' BC (pretrain_with_buffer): 100 x n_episodes epochs of max(1, transitions // 256) batches
    epochs: int = 100
    batch_size: int = 256
    lr: float = 1.0e-3


@dataclass
class NStepConfig:
    """DDPGfD's critic loss L_1 + lambda1 * L_n: the n-step TD loss on the same sampled rows.

    The paper's n and lambda1 could not be read offline: n is the one DQfD (Hester et al. 2018,
    same group) is commonly cited with, lambda1 the public reimplementations' (medipixel/rl_algorithms,
    MrSyee/pg-is-all-you-need).
    """

    n: int = 10
    lambda1: float = 1.0


@dataclass
class PrioritizedReplayConfig:
    """DDPGfD's prioritized replay over the demonstrations and the agent's replay together
    (:class:`~torchrl_sail.PrioritizedMixedReplayBuffer`): priority ``delta^2 + action_grad_coef *
    |grad_a Q_1(s, a)|^2 + eps`` (``+ teacher_eps`` on demonstration rows), drawn with probability
    ``p^alpha / sum p^alpha``, importance weights ``(N P)^-beta`` over their max.

    The paper's values could not be read offline: these are the one public DDPGfD implementation's
    that sets all five (medipixel/rl_algorithms, ``per_alpha``, ``per_beta``, ``per_eps``,
    ``per_eps_demo``, ``lambda3``).
    """

    alpha: float = 0.3
    beta: float = 1.0
    eps: float = 1.0e-6
    teacher_eps: float = 1.0  # epsilon_D: the demonstrations' priority bonus
    action_grad_coef: float = 1.0  # lambda_3
    # count: each loss is the batch mean of the weighted per-row losses, mean_i(w_i l_i), as PER
    # (Schaul et al. 2016) and medipixel step | sum: TorchRL's weighted mean, sum_i w_i l_i / sum_i w_i
    # (SAILLoss's weight_normalization)
    weight_normalization: WeightNormalization = WeightNormalization.count


@dataclass
class AlgoConfig:
    """The method: SAIL (the authors' task gail-lfd-adaptive-dynamic) with these defaults;
    ``conf/algo/<method>.yaml`` sets ``name`` and what differs."""

    name: str = MISSING
    # td3 | sac: the off-policy loop (examples/sail_td3.py) | ppo: GAIL, POfD, on-policy
    # (examples/gail.py) | bc: behaviour cloning, offline (examples/bc.py)
    learner: Learner = Learner.td3
    adaptive: bool = True  # promote agent trajectories with r_e > C into the teacher buffer
    # promotions stop once this many agent trajectories were promoted (null: never), so that C and
    # the teacher buffer hold from there: whether their change causes the falls (campaign stage hold)
    max_promoted: int | None = None
    alpha: AlphaConfig = field(default_factory=AlphaConfig)
    # replay: all of R_B (off-policy D) | recent: the last `recent_window` transitions
    discriminator_agent_data: AgentData = AgentData.replay
    recent_window: int = 2048
    reward: RewardConfig = field(default_factory=RewardConfig)
    # DAC's absorbing state after terminations; bootstrapped through (terminations only) unless
    # absorbing_bootstrap=false; the agent's absorbing transitions store the zero or a random action
    absorbing_state: bool = False
    absorbing_bootstrap: bool = True
    absorbing_action: AbsorbingAction = AbsorbingAction.zero
    rnd: RNDConfig | None = None  # a random-network-distillation bonus added to the reward (sail_rnd)
    ppo: PPOConfig | None = None  # learner=ppo: the PPO generator's settings (gail, pofd)
    sac: SACConfig = field(default_factory=SACConfig)
    bc: BCConfig = field(default_factory=BCConfig)
    nstep: NStepConfig | None = None  # DDPGfD's n-step loss (null: the 1-step TD loss alone)
    # DDPGfD's prioritized replay (null: batches of round(alpha * B) teacher rows, the rest agent rows)
    per: PrioritizedReplayConfig | None = None
    l2_coef: float = 0.0  # DDPGfD's lambda_2: L2 on the actor's and the critic's parameters (Adam weight_decay)


@dataclass
class CollectorConfig:
    # the paper's evaluation point (Figure 2, Table 1); the authors' code runs 3000000
    total_frames: int = 1_000_000
    init_random_frames: int = 10_000  # uniform random actions, then learning starts (authors: learning_starts)
    # and uniform random episodes after them until the actor's first update (Kostrikov et al.'s release;
    # algo=dac_published; one env stream, collector.num_workers=1)
    random_until_actor: bool = False
    frames_per_batch: int = 500  # one collector batch = the discriminator cadence
    num_workers: int = 1  # collector processes / actors; > 1 alone selects backend=process
    # TorchRL's Collector backend: null picks `direct` (one process) for num_workers=1, else
    # `process` (MultiSyncCollector). `ray` runs the workers as Ray actors (pip install ray).
    backend: Backend | None = None
    # forwarded to TorchRL's Collector(backend_options=...) as it is (a mapping or null), e.g. for
    # ray: {ray_init_config: {address: auto}, remote_configs: {num_cpus: 1, num_gpus: 0}}
    backend_options: Any = None
    # ray: how long the learner waits for its actors to join TorchRL's weight-sync group (TorchRL's own
    # 60 s includes Ray starting a worker that imports torch: not enough on a loaded machine)
    weight_sync_timeout_s: float = 300.0


@dataclass
class DiscriminatorOptimConfig:
    lr: float = 1.0e-3  # the authors' effective D learning rate (the TD3 lr)
    every_frames: int = 500
    steps: int = 10  # minibatches per D update ...
    batch_size: int = 256  # ... each of 256 teacher + 256 agent rows
    entropy_coef: float = 0.01  # a PyTorch port reports D saturation at 0.01 and success at 0.05
    gp_coef: float = 10.0
    # Remedies for a saturating D (none is the authors'; each off by default):
    label_smoothing: float = 0.0  # one-sided: the teacher rows' BCE target is 1 - label_smoothing
    instance_noise: float = 0.0  # std of Gaussian noise on D's (normalised) inputs while it trains
    max_accuracy: float | None = None  # skip a D step when its balanced accuracy on the batch is above


@dataclass
class LRDecayConfig:
    """The actor's stepwise learning-rate decay, ``lr * rate ** (frames // every_frames)``: Kostrikov et
    al.'s DAC halves it every 1e5 frames (algo=dac_published)."""

    rate: float = 0.5
    every_frames: int = 100_000


@dataclass
class OptimConfig:
    """TD3 (authors' sail.py / sail.yml) and the discriminator's optimisation."""

    batch_size: int = 256
    lr: float = 1.0e-3
    # the actor's Adam learning rate, where it differs from lr (the critic's); null: lr
    actor_lr: float | None = None
    gamma: float = 0.99
    tau: float = 0.005
    policy_delay: int = 2
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    loss_function: LossFunction = LossFunction.l2
    train_every_frames: int = 1000  # every 1000 env frames ...
    updates_per_train: int = 1000  # ... 1000 gradient steps (critic each, actor every policy_delay)
    # When the TD3 and D blocks run: frames = every train_every_frames (D: discriminator.every_frames)
    # frames | episodes = after each finished episode, the same steps per frame for each of its frames
    # (Kostrikov et al.'s DAC; one env stream, collector.num_workers=1)
    cadence: Cadence = Cadence.frames
    block_order: BlockOrder = BlockOrder.td3_first  # the SAIL authors' order | discriminator_first (DAC's)
    start_frames: int | None = None  # learning starts at this frame count (null: when the random warm-up ends)
    truncation_is_terminal: bool = True  # authors: done = terminated | truncated ends bootstrapping
    discriminator: DiscriminatorOptimConfig = field(default_factory=DiscriminatorOptimConfig)
    # The TD3 step (torchrl_sail.TD3Update): fused = plain tensor operations on the loss's
    # parameters (fast path) | loss = SAILLoss.value_loss/actor_loss + SoftUpdate (reference);
    # both compute the same step (tested equal to float rounding).
    implementation: Implementation = Implementation.fused
    # fp32 | bf16: autocast the TD3 network evaluations, and D's reward of the TD3 batches, to
    # bfloat16 (opt-in; fast on CPUs with AMX and on CUDA). Parameters, optimizer states and losses
    # stay float32.
    precision: Precision = Precision.fp32
    # Replay the fused TD3 step as CUDA graphs (device=cuda; TensorDict's CudaGraphModule, as
    # TorchRL's sota scripts): the step's kernels launched as one graph, the Adam steps capturable.
    cudagraphs: bool = False
    # The actor's extras (all off in the schema; algo=dac_published sets the first three as Kostrikov et al.'s
    # DAC, conf/algo/sail.yaml the pre-tanh penalty):
    # the actor is first updated at this gradient step (then every policy_delay-th); the targets move from the start
    actor_updates_after: int = 0
    actor_max_grad_norm: float | None = None  # clip the actor's gradients to this global norm
    actor_lr_decay: LRDecayConfig | None = None  # {rate, every_frames}: actor lr * rate ** (frames // every_frames)
    # adds coef * sum_j x_j^2 to the actor loss, x its pre-tanh output (rlkit's policy_pre_activation_weight;
    # not the authors'): keeps the tanh out of saturation, where the actor stops moving (docs/training.md)
    actor_preactivation_coef: float = 0.0


@dataclass
class NetworkConfig:
    actor_cells: list[int] = field(default_factory=lambda: [400, 300])
    critic_cells: list[int] = field(default_factory=lambda: [400, 300])
    # LayerNorm after each hidden layer of the critic (Linear -> LayerNorm -> activation), as RLPD
    # (Ball et al. 2023) against Q over-extrapolation when half of each batch is offline data; with
    # algo.l2_coef (DDPGfD's weight decay) the decay reaches the norms' gains and biases too
    critic_layer_norm: bool = False
    activation: Activation = Activation.relu
    # The actor's and critic's linear weights: torch (nn.Linear's own: Kaiming-uniform weights, uniform
    # biases; every committed run used it) | xavier (Glorot-uniform weights, zero biases: the SAIL
    # authors') | orthogonal (gain 1, the actor's output layer 0.01, zero biases: Kostrikov et al.'s DAC release)
    actor_critic_init: LayerInit = LayerInit.torch
    discriminator_cells: list[int] = field(default_factory=lambda: [256, 256])
    discriminator_activation: Activation = Activation.tanh
    normalize_observations: bool = True  # D's running observation normalisation
    discriminator_spectral_norm: bool = False  # spectral normalisation of D's layers (not the authors')
    # D's linear weights: xavier (Glorot-uniform, the SAIL authors') | orthogonal (Kostrikov et al.'s DAC release)
    # | torch (nn.Linear's own, TorchRL's GAIL example)
    discriminator_init: LayerInit = LayerInit.xavier


@dataclass
class LoggerConfig:
    """TorchRL loggers; csv is always on (plots and summary read it)."""

    backends: list[LoggerBackend] = field(  # any of csv, wandb, tensorboard
        default_factory=lambda: [LoggerBackend.csv, LoggerBackend.wandb]
    )
    wandb_mode: WandbMode = WandbMode.offline  # no login or network needed; `wandb sync` later
    project: str = "torchrl_sail"
    log_every_frames: int = 1000


@dataclass
class TeacherConfig:
    # a .npz file (the paper's format), a demonstration folder or minari:<dataset id>; null = the
    # teacher shipped for env.name (examples/teachers/<env.name>)
    path: str | None = None
    k: int = 10  # size K of the window W_k that sets the promotion threshold C (authors: 10)
    # Which trajectories R_T keeps:
    #   topk:  the K best trajectories, demonstrations included (default; the paper's "top-K" reading)
    #   union: every admitted trajectory, R_T <- R_T U tau (the paper's Algorithm 1 read literally)
    #   fifo:  a ring of `capacity` transitions (the authors' code)
    eviction: Eviction = Eviction.topk
    capacity: int = II("env.teacher_capacity")  # ring size for eviction=fifo
    # The teacher's observation columns to keep or to drop (one of the two), e.g. drop_columns=27-110:
    # comma-separated indices and ranges of the file's columns (the time feature included), quoted on
    # Hydra's command line where there is a comma ('0-26,111'); the env must produce the same columns
    # (e.g. env.kwargs.use_contact_forces=false for Ant's 27)
    keep_columns: str | None = None
    drop_columns: str | None = None
    # Before training, a random rollout of the env names the teacher's columns it does not reproduce
    # (constant in the teacher where the env varies, or far outside the env's range): warn | error | off
    column_check: ColumnCheck = ColumnCheck.warn
    column_check_steps: int = 200


@dataclass
class BestPolicyConfig:
    """The policy a run keeps as its best, by the SAIL authors' rule (``train_sail.py``'s callback):
    every ``every_frames`` frames, the mean return of the last ``window`` training episodes; a new
    high keeps the policy (``best_policy.pt``). Beside it, a run keeps the policy at its best periodic
    evaluation (``best_evaluated_policy.pt``, Stable-Baselines3's ``EvalCallback`` rule). At the end,
    ``episodes`` deterministic episodes of each (on the run's seed + 20000, as ``examples/evaluate.py``)
    go into ``summary.json``."""

    every_frames: int = 500
    window: int = 100
    episodes: int = 50  # 0: no final evaluation; also the best evaluated policy's (best_evaluated_policy.pt)


@dataclass
class EvalConfig:
    every_frames: int = 10_000  # deterministic evaluation cadence (the authors' code has none by default)
    episodes: int = 5
    # true: an evaluation's episodes run at once, on a batched env of `episodes` envs seeded
    # seed + i * SEED_STRIDE (torchrl_sail.envs; less time per step where episodes last alike) | false: one env
    vectorized: bool = True
    # the actor a run evaluates, keeps as its best policy and ships: online | target | average
    actor: EvaluatedActor = EvaluatedActor.online
    # also every other actor the run has (eval/return_online, eval/return_target,
    # eval/return_average), each on an env seeded as the evaluation's: all meet the same start states
    other_actor: bool = False
    # 0: none | N: an exponential average of the actor's weights with a memory of N frames, the
    # actor eval.actor=average names (TD3's target actor remembers about policy_delay / tau steps)
    average_frames: int = 0
    best_policy: BestPolicyConfig = field(default_factory=BestPolicyConfig)
    video_every_frames: int = 0  # 0: off | N: every N frames, one deterministic episode to videos/ (and wandb)
    video_format: VideoFormat = VideoFormat.mp4  # mp4 (needs the `video` extra: imageio-ffmpeg) | gif
    # width, height of the offscreen render (MUJOCO_GL=egl without a display)
    video_size: list[int] = field(default_factory=lambda: [320, 240])


@dataclass
class CheckpointConfig:
    every_frames: int = 50_000  # 0 disables; the last checkpoint is also written at the end


@dataclass
class SAILConfig:
    """``conf/config.yaml``: the training scripts' config (``sail_td3.py``, ``gail.py``, ``bc.py``)."""

    env: EnvConfig = field(default_factory=EnvConfig)
    algo: AlgoConfig = field(default_factory=AlgoConfig)
    collector: CollectorConfig = field(default_factory=CollectorConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    logger: LoggerConfig = field(default_factory=LoggerConfig)
    teacher: TeacherConfig = field(default_factory=TeacherConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)
    seed: int = 0
    device: str = "cpu"
    threads: int = 1  # torch intra-op threads; 1 is fastest on 2 shared cores (measured), 0 keeps torch's default
    # flush denormal floats to zero (torch.set_flush_denormal): Adam's moments of units whose
    # gradient is 0 decay through the denormal range, which x86 CPUs compute many times slower
    flush_denormal: bool = True
    # true: continue the run in hydra.run.dir from its last checkpoint | false: start one (refused
    # if the folder holds a checkpoint) | auto: continue if there is a checkpoint, skip a finished
    # run, else start (for matrices that must survive interruption). A union a schema cannot type:
    # check_config checks it.
    resume: Any = False


@dataclass
class EvaluateConfig:
    """``conf/evaluate.yaml``: ``examples/evaluate.py``'s settings."""

    run_dir: str = MISSING  # a run folder written by a training script (config.yaml + checkpoint/)
    episodes: int = 10  # deterministic episodes
    # true: at once, on a batched env whose env i is seeded seed + i * SEED_STRIDE | false: one after another, on
    # one env seeded seed | null: as the run's own evaluations (its eval.vectorized; false for runs
    # saved before it). Episode 0 starts where the video's does either way.
    vectorized: bool | None = None
    # last: the run's last checkpoint | best: the policy it kept as its best by the SAIL authors' rule
    # (best_policy.pt) | best_evaluated: the policy at its best periodic evaluation (best_evaluated_policy.pt)
    policy: EvaluatedPolicy = EvaluatedPolicy.last
    # online: the trained actor; target: its Polyak average (TD3 learners); average: the run's
    # eval.average_frames average; null: the run's eval.actor
    actor: EvaluatedActor | None = None
    seed: int | None = None  # null: the run's seed + 20000 (neither its training nor its eval stream)
    video: bool = False  # true: also record the first episode (replayed on a rendering env)
    video_format: VideoFormat = VideoFormat.mp4  # mp4 (needs the `video` extra: imageio-ffmpeg) | gif
    # width, height of the offscreen render (MUJOCO_GL=egl without a display)
    video_size: list[int] = field(default_factory=lambda: [320, 240])
    out: str | None = None  # the JSON file; null: <run_dir>/evaluation.json (the video beside it)
    # a Minari dataset id (e.g. sail/Hopper-v4/sail-seed0-v0): the episodes, dense rewards
    export: str | None = None
    overwrite: bool = False  # replace an existing dataset of that id
    device: str | None = None  # null: the run's device; e.g. cpu to evaluate a CUDA-trained run here
    threads: int = 1


@dataclass
class MakeTeacherAlgoConfig:
    """The part of ``algo`` that ``make_agent`` reads: TD3's deterministic MLP + tanh actor."""

    learner: Learner = Learner.td3
    absorbing_state: bool = False


@dataclass
class MakeTeacherConfig:
    """``conf/make_teacher.yaml``: ``examples/make_teacher.py``'s settings (TD3 on the dense reward)."""

    env: EnvConfig = field(default_factory=EnvConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    seed: int = 0
    device: str = "cpu"
    threads: int = 1
    flush_denormal: bool = True  # as in the training scripts' config
    frames: int = 100_000  # TD3 budget (dense reward)
    init_random_frames: int = 5000
    frames_per_batch: int = 1000
    updates_per_batch: int = 1000
    batch_size: int = 256
    lr: float = 1.0e-3
    gamma: float = 0.99
    tau: float = 0.005
    policy_delay: int = 2
    eval_every_frames: int = 5000
    stop_at_return: float | None = None  # stop training once a deterministic episode reaches this dense return
    max_return: float | None = None  # only record a trajectory whose return is at most this (keeps the teacher weak)
    out: str = "examples/teachers/${env.name}"  # a directory: see save_demonstrations
    algo: MakeTeacherAlgoConfig = field(default_factory=MakeTeacherAlgoConfig)


def register_config_schema() -> None:
    """Stores the schemas the first entries of the ``conf/`` defaults lists name: :class:`SAILConfig`
    as ``sail_config`` (``config.yaml``), :class:`EvaluateConfig` as ``evaluate_config``
    (``evaluate.yaml``) and :class:`MakeTeacherConfig` as ``make_teacher_config`` (``make_teacher.yaml``)."""
    store = ConfigStore.instance()
    store.store(name="sail_config", node=SAILConfig)
    store.store(name="evaluate_config", node=EvaluateConfig)
    store.store(name="make_teacher_config", node=MakeTeacherConfig)


#: What a run saved before each of these settings existed ran with: not the schema's default
#: (``eval.vectorized``), or not what a method's file sets now (``conf/algo``: ``dac_published``'s
#: release loop and inits, SAIL's settings the campaign decides), so that a command reproducing an
#: older run names them (``benchmarks/aggregate.py``).
SAVED_BEFORE = {
    "eval.vectorized": False,
    "eval.actor": "online",
    "eval.other_actor": False,
    "optim.actor_preactivation_coef": 0.0,
    "algo.rnd.activation": "tanh",
    "optim.cadence": "frames",
    "optim.block_order": "td3_first",
    "optim.start_frames": None,
    "collector.random_until_actor": False,
    "network.actor_critic_init": "torch",
    "network.discriminator_init": "xavier",
    "network.critic_layer_norm": False,
    "optim.actor_lr": None,
}


def with_saved_before(saved: dict) -> dict:
    """A copy of a run's saved config (a plain nested dict) with each setting of :data:`SAVED_BEFORE`
    that its version did not have at the value it ran with, unless it lies under a section the run
    switched off (``null``), or under an optional section (null by default, as ``algo.rnd``) that
    its version did not have."""
    schema = OmegaConf.to_container(OmegaConf.structured(SAILConfig))
    completed = copy.deepcopy(saved)
    for key, value in SAVED_BEFORE.items():
        *sections, name = key.split(".")
        node, default = completed, schema
        for section in sections:
            default = default.get(section) if isinstance(default, dict) else None
            if section not in node and isinstance(default, dict):
                node[section] = {}  # a section every run has: its settings all predate the run
            node = node.get(section)
            if not isinstance(node, dict):
                break
        else:
            node.setdefault(name, value)
    return completed


def saved_run_config(saved: DictConfig) -> DictConfig:
    """A run's saved ``config.yaml`` over the schema's defaults: each setting its version did not have
    takes the value it ran with, :data:`SAVED_BEFORE`'s where recorded (:func:`with_saved_before`), else
    the schema's default; keys removed since are kept, unread."""
    defaults = OmegaConf.structured(SAILConfig)
    OmegaConf.set_struct(defaults, False)
    return OmegaConf.merge(defaults, with_saved_before(OmegaConf.to_container(saved)))


# ----------------------------------------------------------------------------- scripts
#: The script that trains the methods of each ``algo.learner``: one entry point per family.
SCRIPTS = {"td3": "sail_td3.py", "sac": "sail_td3.py", "ppo": "gail.py", "bc": "bc.py"}
_FAMILIES = {
    "sail_td3.py": "the off-policy methods (algo.learner=td3 or sac: sail and its ablations, dac, "
    "dac_published, td3_delayed, ddpgfd, pofd_td3)",
    "gail.py": "the on-policy methods (algo.learner=ppo: gail, pofd)",
    "bc.py": "behaviour cloning (algo.learner=bc: bc)",
}


def check_script(cfg: DictConfig, script: str) -> None:
    """Refuses a method of another family than ``script``'s, naming the script that runs it.

    Raises:
        ValueError: ``algo.learner`` belongs to another script of :data:`SCRIPTS`.
    """
    learner = str(cfg.algo.learner)
    if SCRIPTS[learner] != script:
        raise ValueError(
            f"examples/{script} runs {_FAMILIES[script]}; algo={cfg.algo.name} has "
            f"algo.learner={learner}: run python examples/{SCRIPTS[learner]} algo={cfg.algo.name} "
            f"with the same overrides"
        )


# ----------------------------------------------------------------------------- checks
def masks_absorbing_actions(cfg: DictConfig) -> bool:
    """DAC as published: the actor outputs 0 at the absorbing state, which is bootstrapped through."""
    return bool(cfg.algo.absorbing_state and cfg.algo.absorbing_bootstrap)


#: A check: ``(key, value, ok, why)``, the key and value an error names and whether the value is valid.
Rule = tuple[str, Any, bool, str]


def _check(rules: Iterable[Rule]) -> None:
    """Raises for the first rule that does not hold.

    Args:
        rules: ``(key, value, ok, why)`` tuples, in the order their errors take precedence.

    Raises:
        ValueError: ``config <key>=<value>: <why>`` of the first rule whose ``ok`` is false.
    """
    for key, value, ok, why in rules:
        if not ok:
            raise ValueError(f"config {key}={value!r}: {why}")


def _at_least(key: str, value: int, low: int) -> Rule:
    """The rule ``value >= low`` of a count or a cadence (low 0: 0 disables it).

    Args:
        key: the config key, as the error names it.
        value: its value.
        low: the least valid value.

    Returns:
        The rule, for :func:`_check`.
    """
    return key, value, value >= low, f"must be >= {low}" + (" (0 disables)" if low == 0 else "")


def _cadence(cfg: DictConfig, key: str, every: int, applies: bool) -> Rule:
    """The rule that a cadence of the off-policy loop is a multiple of the collector batch.

    The off-policy loop runs the D steps and TD3 updates of every cadence crossed by a collector
    batch at once, after it: a batch longer than a cadence bunches them, and one that does not
    divide it shifts them, so the reward would come from a D that is behind.

    Args:
        cfg: the config (its ``collector.frames_per_batch``, checked >= 1 before).
        key: the cadence's key.
        every: its value, in frames.
        applies: whether the loop runs these updates (an off-policy learner; for D, a trained D).

    Returns:
        The rule, for :func:`_check`.
    """
    batch = cfg.collector.frames_per_batch  # a synchronous collector's batch is over all its workers
    return (
        key,
        every,
        not applies or cfg.optim.cadence == "episodes" or every % batch == 0,
        f"must be a multiple of collector.frames_per_batch={batch}: a larger "
        f"collector batch, or one that does not divide it, runs these updates late or "
        f"bunched, so D's reward comes from a stale D (lower collector.frames_per_batch)",
    )


def _check_collector(cfg: DictConfig) -> None:
    """``collector.*`` but its backend: its counts (the cadence rules divide by its batch)."""
    c = cfg.collector
    _check(
        [
            _at_least("collector.total_frames", c.total_frames, 1),
            _at_least("collector.frames_per_batch", c.frames_per_batch, 1),
            _at_least("collector.num_workers", c.num_workers, 1),
            _at_least("collector.init_random_frames", c.init_random_frames, 0),
        ]
    )


def _check_collector_backend(cfg: DictConfig) -> None:
    """``collector.backend`` and ``collector.backend_options``: a backend that fits its workers and is installed."""
    c = cfg.collector
    _check(
        [
            (
                "collector.backend",
                c.backend,
                c.backend != "direct" or c.num_workers == 1,
                f"direct runs one worker, but collector.num_workers={c.num_workers}",
            ),
            (
                "collector.backend",
                c.backend,
                c.backend != "ray" or importlib.util.find_spec("ray") is not None,
                "the ray backend needs Ray: pip install ray",
            ),
            (
                "collector.backend_options",
                c.backend_options,
                c.backend_options is None or isinstance(c.backend_options, DictConfig),
                "must be a mapping (forwarded to TorchRL's Collector) or null",
            ),
            (
                "collector.weight_sync_timeout_s",
                c.weight_sync_timeout_s,
                0 < c.weight_sync_timeout_s < math.inf,
                "must be a finite number > 0",
            ),
        ]
    )


def _check_env(cfg: DictConfig) -> None:
    """``env.*``: the replay buffer's size and the exploration noise."""
    _check(
        [
            _at_least("env.replay_size", cfg.env.replay_size, 1),
            ("env.exploration_noise", cfg.env.exploration_noise, cfg.env.exploration_noise >= 0, "must be >= 0"),
        ]
    )


def _check_teacher(cfg: DictConfig) -> None:
    """``teacher.*``: the column check's rollout, and one way to select the teacher's columns."""
    t = cfg.teacher
    _check(
        [
            _at_least("teacher.column_check_steps", t.column_check_steps, 1),
            (
                "teacher.drop_columns",
                t.drop_columns,
                t.drop_columns is None or t.keep_columns is None,
                "and teacher.keep_columns are two ways to say one thing: give one of them",
            ),
        ]
    )


def _check_ppo(cfg: DictConfig) -> None:
    """``algo.ppo``: the PPO learner's settings block and its counts."""
    # across fields: the PPO learner needs its settings block (algo=gail sets it)
    _check(
        [
            (
                "algo.ppo",
                cfg.algo.ppo,
                cfg.algo.learner != "ppo" or cfg.algo.ppo is not None,
                "algo.learner=ppo needs the PPO settings (algo=gail has them)",
            )
        ]
    )
    if cfg.algo.learner == "ppo":
        p = cfg.algo.ppo
        _check(
            [
                _at_least("algo.ppo.frames_per_batch", p.frames_per_batch, 1),
                _at_least("algo.ppo.epochs", p.epochs, 1),
                _at_least("algo.ppo.minibatch_size", p.minibatch_size, 1),
            ]
        )


def _check_algo(cfg: DictConfig) -> None:
    """``algo.*`` but its PPO, n-step and reward settings: alpha, BC, SAC, and what RND and absorbing states need."""
    a = cfg.algo
    _check(
        [
            *(
                (f"algo.alpha.{key}", a.alpha[key], 0 <= a.alpha[key] <= 1, "must be in [0, 1] (a teacher share)")
                for key in ("initial", "final")
            ),
            (
                "algo.alpha.anneal_frames",
                a.alpha.anneal_frames,
                a.alpha.mode != "linear" or (a.alpha.anneal_frames or 0) > 0,
                "algo.alpha.mode=linear anneals over this many frames: set it > 0",
            ),
            _at_least("algo.bc.epochs", a.bc.epochs, 1),
            _at_least("algo.bc.batch_size", a.bc.batch_size, 1),
            ("algo.bc.lr", a.bc.lr, a.bc.lr > 0, "must be > 0"),
            (
                "algo.sac.alpha_init",
                a.sac.alpha_init,
                0 < a.sac.alpha_init < math.inf,
                "must be a finite number > 0 (SAC's entropy temperature; its log is stored)",
            ),
            (
                "algo.rnd",
                a.rnd,
                a.rnd is None or (cfg.collector.num_workers == 1 and cfg.collector.backend in (None, "direct")),
                "the RND bonus keeps its statistics in the training env: use collector.num_workers=1 and "
                "collector.backend=null",
            ),
            (
                "algo.absorbing_state",
                a.absorbing_state,
                not (a.absorbing_state and a.adaptive),
                "absorbing states need a fixed teacher (algo.adaptive=false): promotion reads unrewritten trajectories",
            ),
            (
                "algo.max_promoted",
                a.max_promoted,
                a.max_promoted is None or (a.adaptive and a.max_promoted > 0),
                "promotions stop once this many trajectories were promoted: set it > 0, with algo.adaptive=true",
            ),
        ]
    )


def _check_algo_nstep(cfg: DictConfig) -> None:
    """DDPGfD's loss terms: ``algo.nstep.*`` (the n-step TD loss) and ``algo.l2_coef`` (its lambda_2)."""
    a = cfg.algo
    _check(
        [
            (
                "algo.nstep.n",
                a.nstep and a.nstep.n,
                a.nstep is None or a.nstep.n >= 2,
                "must be >= 2 (algo.nstep=null for the 1-step TD loss alone)",
            ),
            (
                "algo.nstep.lambda1",
                a.nstep and a.nstep.lambda1,
                a.nstep is None or 0 < a.nstep.lambda1 < math.inf,
                "must be a finite number > 0",
            ),
            # The n-step sums are of the stored env reward, made when a transition is stored; other
            # rewards are made at sample time for the 1-step entries only, and promoted, absorbing or
            # SAC/BC/PPO rows have no n-step view.
            (
                "algo.nstep",
                "set",
                a.nstep is None
                or (
                    a.learner == "td3"
                    and a.reward.source == "env"
                    and a.rnd is None
                    and not a.adaptive
                    and not a.absorbing_state
                ),
                "the n-step loss (DDPGfD) needs algo.learner=td3, algo.reward.source=env, algo.rnd=null, "
                "algo.adaptive=false and algo.absorbing_state=false",
            ),
            (
                "algo.l2_coef",
                a.l2_coef,
                0 <= a.l2_coef < math.inf and (a.l2_coef == 0 or a.learner in ("td3", "sac")),
                "must be a finite number >= 0, and 0 unless algo.learner is td3 or sac (the actor's and the critic's "
                "Adam weight decay)",
            ),
        ]
    )


def _check_algo_per(cfg: DictConfig) -> None:
    """DDPGfD's prioritized replay, ``algo.per.*``."""
    a, p = cfg.algo, cfg.algo.per
    _check(
        [
            *(
                (f"algo.per.{key}", p[key], 0 <= p[key] < math.inf, "must be a finite number >= 0")
                for key in ("alpha", "beta", "teacher_eps", "action_grad_coef")
                if p is not None
            ),
            (
                "algo.per.eps",
                p and p.eps,
                p is None or 0 < p.eps < math.inf,
                "must be a finite number > 0 (a row of priority 0 would get an infinite importance weight)",
            ),
            # the priorities span the teacher rows held at the start; each step's batch is drawn
            # after the step before set its rows' priorities, which a CUDA graph's replay cannot see
            (
                "algo.per",
                "set",
                p is None or (a.learner == "td3" and not a.adaptive and not cfg.optim.cudagraphs),
                "prioritized replay (DDPGfD) needs algo.learner=td3, algo.adaptive=false (a fixed teacher buffer) "
                "and optim.cudagraphs=false",
            ),
        ]
    )


def _check_algo_reward(cfg: DictConfig) -> None:
    """``algo.reward.*``: D's clip and shift, and the sources and schedule a learner can use."""
    a, r = cfg.algo, cfg.algo.reward
    _check(
        [
            (
                "algo.reward.clip",
                r.clip,
                r.clip is None or (len(r.clip) == 2 and 0 < r.clip[0] < r.clip[1] < 1),
                "must be [low, high] with 0 < low < high < 1, or null",
            ),
            ("algo.reward.shift", r.shift, math.isfinite(r.shift), "must be a finite number"),
            (
                "algo.reward.source",
                r.source,
                a.learner != "ppo" or (r.source != "env" and a.rnd is None and not a.absorbing_state),
                "the PPO generator (gail, pofd) learns from D's reward (discriminator or shaped), without an RND "
                "bonus or absorbing states",
            ),
            (
                "algo.reward.coef_decay",
                r.coef_decay,
                0 < r.coef_decay <= 1 and (r.coef_decay == 1 or a.learner == "ppo"),
                "must be in (0, 1], and 1 unless algo.learner=ppo (it decays the shaping once per on-policy batch)",
            ),
        ]
    )


def _check_discriminator(cfg: DictConfig) -> None:
    """``optim.discriminator.*``: D's counts, its optimiser's ranges and its cadence in the off-policy loop."""
    d = cfg.optim.discriminator
    trained = cfg.algo.learner in ("td3", "sac") and cfg.algo.reward.source != "env" and bool(d.steps)
    _check(
        [
            _at_least("optim.discriminator.every_frames", d.every_frames, 1),
            _at_least("optim.discriminator.batch_size", d.batch_size, 1),
            _at_least("optim.discriminator.steps", d.steps, 0),
            ("optim.discriminator.lr", d.lr, d.lr > 0, "must be > 0"),
            (
                "optim.discriminator.label_smoothing",
                d.label_smoothing,
                0 <= d.label_smoothing < 0.5,
                "must be in [0, 0.5)",
            ),
            (
                "optim.discriminator.instance_noise",
                d.instance_noise,
                0 <= d.instance_noise < float("inf"),
                "must be a finite number >= 0",
            ),
            (
                "optim.discriminator.max_accuracy",
                d.max_accuracy,
                d.max_accuracy is None or 0.5 <= d.max_accuracy < 1,
                "must be in [0.5, 1) (a balanced accuracy; 1 would never skip), or null",
            ),
            _cadence(cfg, "optim.discriminator.every_frames", d.every_frames, trained),
        ]
    )


def _check_optim_actor(cfg: DictConfig) -> None:
    """``optim.actor_*``: the actor's extras, TD3's where a stochastic actor has no counterpart."""
    o = cfg.optim
    lr_decay = None if o.actor_lr_decay is None else dict(o.actor_lr_decay)
    _check(
        [
            ("optim.actor_updates_after", o.actor_updates_after, o.actor_updates_after >= 0, "must be >= 0"),
            (
                "optim.actor_max_grad_norm",
                o.actor_max_grad_norm,
                o.actor_max_grad_norm is None or o.actor_max_grad_norm > 0,
                "must be > 0, or null (no clipping)",
            ),
            (
                "optim.actor_lr_decay",
                lr_decay,
                o.actor_lr_decay is None or (0 < o.actor_lr_decay.rate <= 1 and o.actor_lr_decay.every_frames >= 1),
                "needs 0 < rate <= 1 and every_frames >= 1, or null",
            ),
            (
                "optim.actor_lr_decay",
                lr_decay,
                o.actor_lr_decay is None or cfg.algo.learner == "td3",
                "is TD3's (algo.learner=td3)",
            ),
            (
                "optim.actor_preactivation_coef",
                o.actor_preactivation_coef,
                0 <= o.actor_preactivation_coef < math.inf
                and (o.actor_preactivation_coef == 0 or cfg.algo.learner == "td3"),
                "must be a finite number >= 0, and 0 unless algo.learner=td3 (a deterministic tanh actor)",
            ),
        ]
    )


def _check_optim_step(cfg: DictConfig) -> None:
    """``optim.precision`` and ``optim.cudagraphs``: options of TD3's fused step, which not every method runs."""
    o = cfg.optim
    # DAC's masked actor (bootstrapped absorbing states) runs the loss's own step, not the fused one
    fused_td3 = o.implementation == "fused" and cfg.algo.learner == "td3" and not masks_absorbing_actions(cfg)
    _check(
        [
            (
                "optim.precision",
                o.precision,
                o.precision == "fp32" or fused_td3,
                "bf16 is TD3's fused step only: optim.implementation=fused, algo.learner=td3, and no bootstrapped "
                "absorbing states (DAC's masked actor runs the loss's own step)",
            ),
            (
                "optim.cudagraphs",
                o.cudagraphs,
                not o.cudagraphs or (str(cfg.device).startswith("cuda") and fused_td3 and o.actor_lr_decay is None),
                "CUDA graphs replay TD3's fused step on a GPU: device=cuda, optim.implementation=fused, "
                "algo.learner=td3, no bootstrapped absorbing states and no optim.actor_lr_decay (a new learning "
                "rate would capture the graph again)",
            ),
        ]
    )


def _check_optim(cfg: DictConfig) -> None:
    """``optim.*`` but D's, the actor's extras and the step's options: TD3's counts, ranges and cadence."""
    o = cfg.optim
    _check(
        [
            _at_least("optim.batch_size", o.batch_size, 2),
            _at_least("optim.train_every_frames", o.train_every_frames, 1),
            _at_least("optim.policy_delay", o.policy_delay, 1),
            _at_least("optim.updates_per_train", o.updates_per_train, 0),
            ("optim.lr", o.lr, o.lr > 0, "must be > 0"),
            ("optim.actor_lr", o.actor_lr, o.actor_lr is None or o.actor_lr > 0, "must be > 0 or null"),
            ("optim.gamma", o.gamma, 0 < o.gamma <= 1, "must be in (0, 1]"),
            ("optim.tau", o.tau, 0 < o.tau <= 1, "must be in (0, 1]"),
            _cadence(cfg, "optim.train_every_frames", o.train_every_frames, cfg.algo.learner in ("td3", "sac")),
            (
                "optim.start_frames",
                o.start_frames,
                o.start_frames is None or o.start_frames >= 0,
                "must be >= 0, or null (learning starts when the random warm-up ends)",
            ),
            (
                "optim.cadence",
                str(o.cadence),
                o.cadence == "frames" or cfg.collector.num_workers == 1,
                "episodes counts the frames of one env stream's episodes: use collector.num_workers=1",
            ),
            (
                "collector.random_until_actor",
                cfg.collector.random_until_actor,
                not cfg.collector.random_until_actor or (cfg.collector.num_workers == 1 and cfg.algo.learner == "td3"),
                "the random episodes end with the TD3 actor's first update, which one collector in the "
                "learner's process sees: use collector.num_workers=1 and a TD3 learner",
            ),
        ]
    )


def _check_eval(cfg: DictConfig) -> None:
    """``eval.*`` but its videos: its counts and cadence, and the TD3 actors it can evaluate."""
    e = cfg.eval
    _check(
        [
            _at_least("eval.episodes", e.episodes, 1),
            _at_least("eval.best_policy.every_frames", e.best_policy.every_frames, 1),
            _at_least("eval.best_policy.window", e.best_policy.window, 1),
            _at_least("eval.best_policy.episodes", e.best_policy.episodes, 0),
            _at_least("eval.every_frames", e.every_frames, 0),
            _at_least("eval.average_frames", e.average_frames, 0),
            (
                "eval.actor",
                str(e.actor),
                e.actor != EvaluatedActor.target or cfg.algo.learner == "td3",
                "target is TD3's (algo.learner=td3): only a TD3 learner keeps a target actor",
            ),
            (
                "eval.actor",
                str(e.actor),
                e.actor != EvaluatedActor.average or e.average_frames > 0,
                "average needs eval.average_frames > 0, the averaged actor's memory in frames",
            ),
            (
                "eval.average_frames",
                e.average_frames,
                not e.average_frames or cfg.algo.learner in ("td3", "sac"),
                "is the off-policy learners' (algo.learner=td3 or sac, examples/sail_td3.py)",
            ),
            (
                "eval.other_actor",
                e.other_actor,
                not e.other_actor or cfg.algo.learner == "td3" or e.average_frames > 0,
                "needs a second actor: a TD3 learner's target actor (algo.learner=td3) or, for an "
                "off-policy learner (td3, sac), an averaged one (eval.average_frames > 0)",
            ),
        ]
    )


def _check_eval_video(cfg: DictConfig) -> None:
    """``eval.video_*``: the videos' cadence and size, and the packages their format and loggers need."""
    e = cfg.eval
    video_size = list(e.video_size)
    _check(
        [
            _at_least("eval.video_every_frames", e.video_every_frames, 0),
            # a list's length and range
            (
                "eval.video_size",
                video_size,
                len(video_size) == 2 and min(video_size) >= 16,
                "must be [width, height], each >= 16",
            ),
            # what the chosen outputs need installed
            (
                "eval.video_format",
                "mp4",
                not (
                    e.video_every_frames
                    and e.video_format == "mp4"
                    and importlib.util.find_spec("imageio_ffmpeg") is None
                ),
                "MP4 videos need imageio-ffmpeg: pip install -e '.[video]' (or use gif)",
            ),
            (
                "eval.video_every_frames",
                e.video_every_frames,
                not (
                    e.video_every_frames
                    and "wandb" in cfg.logger.backends
                    and importlib.util.find_spec("moviepy") is None
                ),
                "wandb encodes videos with moviepy: pip install -e '.[video]' (or drop wandb from logger.backends)",
            ),
        ]
    )


def _check_logger(cfg: DictConfig) -> None:
    """``logger.*``: the packages its backends need."""
    backends = cfg.logger.backends
    _check(
        [
            (
                "logger.backends",
                list(backends),
                "tensorboard" not in backends or importlib.util.find_spec("tensorboard") is not None,
                "the tensorboard backend needs the tensorboard package: pip install -e '.[tensorboard]'",
            ),
        ]
    )


def _check_run(cfg: DictConfig) -> None:
    """The run's own keys: ``checkpoint.every_frames``, ``resume`` and ``device``."""
    import torch  # here: composing a config (e.g. benchmarks/run_matrix.py) needs no torch

    _check(
        [
            _at_least("checkpoint.every_frames", cfg.checkpoint.every_frames, 0),
            # a union the schema cannot type (SAILConfig.resume)
            ("resume", cfg.resume, cfg.resume in (True, False, "auto"), "use true, false or auto"),
            (
                "device",
                cfg.device,
                cfg.device == "cpu" or torch.cuda.is_available(),
                "CUDA is not available on this machine; use device=cpu",
            ),
        ]
    )


# A value can break rules of several sections (algo.learner=sac breaks every TD3-only option set,
# collector.num_workers=2 both algo.rnd and collector.backend=direct); the sections run in the
# order their rules had in the one check they were split from, so such a config is named by the
# same key as before: the collector's counts first (the cadence rules divide by its batch), the PPO
# block, the TD3-only extras, the method, its backend and TD3 step options, its losses and reward,
# the cadences those switch on (D's before TD3's), and last what this machine must have (a device,
# the video and logger packages), so a config error is named before a missing package.
_SECTIONS = (
    _check_collector,
    _check_env,
    _check_teacher,
    _check_ppo,
    _check_optim_actor,
    _check_eval,
    _check_algo,
    _check_collector_backend,
    _check_optim_step,
    _check_algo_nstep,
    _check_algo_per,
    _check_algo_reward,
    _check_discriminator,
    _check_optim,
    _check_run,
    _check_eval_video,
    _check_logger,
)


def check_config(cfg: DictConfig) -> None:
    """Rejects invalid values before anything is built, naming the key and the fix.

    Types, choices and unknown keys are the schema's (Hydra rejects them while composing). What
    is left here is what a type cannot say: ranges, rules across fields, and options that need
    a package or a device this machine lacks. Each section's rules are in its own function
    (:data:`_SECTIONS`); a rule across sections is in the section of the key its error names.

    Raises:
        ValueError: ``config <key>=<value>: <why>`` for the first invalid value.
    """
    for check in _SECTIONS:
        check(cfg)
