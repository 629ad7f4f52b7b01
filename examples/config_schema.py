"""The typed schema of ``conf/config.yaml`` (Hydra structured configs).

``config.yaml`` lists ``sail_config`` first in its defaults, so every YAML file and every
command-line override is merged into these dataclasses: a value of the wrong type
(``optim.lr=abc``), a choice outside its set (``network.activation=gelu``) or an unknown key
is rejected by Hydra with the full key named, before anything is built. The YAML files keep
the values and their comments; the hand-written ``check_config`` keeps only what a type
cannot say (ranges, and rules across fields).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any, List, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING


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
Implementation = Choice("Implementation", {name: name for name in ("fused", "loss")})
Precision = Choice("Precision", {name: name for name in ("fp32", "bf16")})
LossFunction = Choice("LossFunction", {name: name for name in ("l1", "l2", "smooth_l1")})
Activation = Choice("Activation", {name: name for name in ("relu", "tanh", "elu")})
Backend = Choice("Backend", {name: name for name in ("direct", "process", "ray")})
LoggerBackend = Choice("LoggerBackend", {name: name for name in ("csv", "wandb", "tensorboard")})
WandbMode = Choice("WandbMode", {name: name for name in ("offline", "online")})
VideoFormat = Choice("VideoFormat", {name: name for name in ("mp4", "gif")})


@dataclass
class EnvConfig:
    name: str = MISSING
    max_episode_steps: int = 1000
    exploration_noise: float = 0.2
    replay_size: int = 1_000_000
    teacher_capacity: int = 100_000


@dataclass
class AlphaConfig:
    mode: AlphaMode = AlphaMode.dynamic
    initial: float = 0.5
    final: float = 0.0
    anneal_frames: Optional[int] = None


@dataclass
class RewardConfig:
    source: RewardSource = RewardSource.discriminator
    kind: RewardKind = RewardKind.gail
    clip: Optional[List[float]] = None  # [low, high]: D clipped before the reward (the SAIL authors' DAC)
    coef: float = 1.0
    coef_decay: float = 1.0  # coef *= coef_decay after every on-policy batch (POfD's lambda_1 schedule)


@dataclass
class RNDConfig:
    coef: float = 1.0
    lr: float = 1.0e-4
    cells: List[int] = field(default_factory=lambda: [256, 256])
    features: int = 64


@dataclass
class PPOConfig:
    frames_per_batch: int = 2048
    epochs: int = 10
    minibatch_size: int = 64
    lr: float = 3.0e-4
    clip_epsilon: float = 0.2
    gae_lambda: float = 0.95
    entropy_coef: float = 0.0
    critic_coef: float = 0.25
    loss_critic_type: LossFunction = LossFunction.l2
    anneal_lr: bool = True
    anneal_clip_epsilon: bool = False
    normalize_observations: bool = True
    cells: List[int] = field(default_factory=lambda: [64, 64])


@dataclass
class SACConfig:
    alpha_init: float = 1.0
    alpha_lr: float = 3.0e-4


@dataclass
class BCConfig:
    epochs: int = 100
    batch_size: int = 64
    lr: float = 1.0e-3


@dataclass
class NStepConfig:
    """DDPGfD's critic loss L_1 + lambda1 * L_n: the n-step TD loss on the same sampled rows."""

    n: int = 10
    lambda1: float = 1.0


@dataclass
class AlgoConfig:
    name: str = MISSING
    learner: Learner = Learner.td3
    adaptive: bool = True
    alpha: AlphaConfig = field(default_factory=AlphaConfig)
    discriminator_agent_data: AgentData = AgentData.replay
    recent_window: int = 2048
    reward: RewardConfig = field(default_factory=RewardConfig)
    absorbing_state: bool = False
    absorbing_bootstrap: bool = True
    absorbing_action: AbsorbingAction = AbsorbingAction.zero
    rnd: Optional[RNDConfig] = None
    ppo: Optional[PPOConfig] = None
    sac: SACConfig = field(default_factory=SACConfig)
    bc: BCConfig = field(default_factory=BCConfig)
    nstep: Optional[NStepConfig] = None  # DDPGfD's n-step loss (null: the 1-step TD loss alone)
    l2_coef: float = 0.0  # DDPGfD's lambda_2: L2 on the actor's and the critic's parameters (Adam weight_decay)


@dataclass
class CollectorConfig:
    total_frames: int = 1_000_000
    init_random_frames: int = 10_000
    frames_per_batch: int = 500
    num_workers: int = 1
    backend: Optional[Backend] = None
    backend_options: Any = None  # forwarded to TorchRL's Collector as it is (a mapping or null)


@dataclass
class DiscriminatorOptimConfig:
    lr: float = 1.0e-3
    every_frames: int = 500
    steps: int = 10
    batch_size: int = 256
    entropy_coef: float = 0.01
    gp_coef: float = 10.0


@dataclass
class LRDecayConfig:
    rate: float = 0.5
    every_frames: int = 100_000


@dataclass
class OptimConfig:
    batch_size: int = 256
    lr: float = 1.0e-3
    gamma: float = 0.99
    tau: float = 0.005
    policy_delay: int = 2
    policy_noise: float = 0.2
    noise_clip: float = 0.5
    loss_function: LossFunction = LossFunction.l2
    train_every_frames: int = 1000
    updates_per_train: int = 1000
    truncation_is_terminal: bool = True
    discriminator: DiscriminatorOptimConfig = field(default_factory=DiscriminatorOptimConfig)
    implementation: Implementation = Implementation.fused
    precision: Precision = Precision.fp32
    actor_updates_after: int = 0
    actor_max_grad_norm: Optional[float] = None
    actor_lr_decay: Optional[LRDecayConfig] = None


@dataclass
class NetworkConfig:
    actor_cells: List[int] = field(default_factory=lambda: [400, 300])
    critic_cells: List[int] = field(default_factory=lambda: [400, 300])
    activation: Activation = Activation.relu
    discriminator_cells: List[int] = field(default_factory=lambda: [256, 256])
    discriminator_activation: Activation = Activation.tanh
    normalize_observations: bool = True


@dataclass
class LoggerConfig:
    backends: List[LoggerBackend] = field(default_factory=lambda: [LoggerBackend.csv, LoggerBackend.wandb])
    wandb_mode: WandbMode = WandbMode.offline
    project: str = "torchrl_sail"
    log_every_frames: int = 1000


@dataclass
class TeacherConfig:
    path: Optional[str] = None
    k: int = 10
    eviction: Eviction = Eviction.topk
    capacity: int = 100_000


@dataclass
class EvalConfig:
    every_frames: int = 10_000
    episodes: int = 5
    video_every_frames: int = 0
    video_format: VideoFormat = VideoFormat.mp4
    video_size: List[int] = field(default_factory=lambda: [320, 240])


@dataclass
class CheckpointConfig:
    every_frames: int = 50_000


@dataclass
class SAILConfig:
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
    threads: int = 1
    resume: Any = False  # true | false | auto: a union a schema cannot type, checked by check_config


@dataclass
class EvaluateConfig:
    """``conf/evaluate.yaml``: ``examples/evaluate.py``'s settings."""

    run_dir: str = MISSING
    episodes: int = 10
    seed: Optional[int] = None
    video: bool = False
    video_format: VideoFormat = VideoFormat.mp4
    video_size: List[int] = field(default_factory=lambda: [320, 240])
    out: Optional[str] = None
    export: Optional[str] = None
    overwrite: bool = False
    device: Optional[str] = None
    threads: int = 1


def register_config_schema() -> None:
    """Stores :class:`SAILConfig` as ``sail_config`` and :class:`EvaluateConfig` as ``evaluate_config``,
    the first entries of ``conf/config.yaml``'s and ``conf/evaluate.yaml``'s defaults."""
    ConfigStore.instance().store(name="sail_config", node=SAILConfig)
    ConfigStore.instance().store(name="evaluate_config", node=EvaluateConfig)
