"""torchrl_sail: Self-Adaptive Imitation Learning (SAIL) as TorchRL components.

Every public name is importable from the top level, e.g.
``from torchrl_sail import DelayedRewardTransform, SAILLoss``.
"""
from torchrl_sail.data import (
    check_demonstration_dims,
    Demonstrations,
    export_minari_dataset,
    FIFOTrajectoryWriter,
    load_demonstrations,
    load_minari_demonstrations,
    load_sb_demonstrations,
    MixedReplayBuffer,
    save_demonstrations,
    TeacherReplayBuffer,
    TopKTrajectoryWriter,
    TrajectoryWriter,
    UnionTrajectoryWriter,
    TRANSITION_KEYS,
)
from torchrl_sail.divergence import DivergenceCheck, DivergenceError
from torchrl_sail.envs import (
    AbsorbingStateTransform,
    DelayedRewardTransform,
    DiscriminatorReward,
    make_sail_env,
    NStepTransform,
    nstep_view,
    observation_normalizer,
    RNDReward,
    TimeFeature,
)
from torchrl_sail.modules import Discriminator, DiscriminatorNet, RunningObsNorm
from torchrl_sail.objectives import AlphaScheduler, DiscriminatorLoss, SAILLoss, TD3Update

__version__ = "0.1.0.dev0"

__all__ = [
    "AbsorbingStateTransform",
    "AlphaScheduler",
    "DelayedRewardTransform",
    "Demonstrations",
    "Discriminator",
    "DiscriminatorLoss",
    "DiscriminatorNet",
    "DiscriminatorReward",
    "DivergenceCheck",
    "DivergenceError",
    "FIFOTrajectoryWriter",
    "MixedReplayBuffer",
    "NStepTransform",
    "RNDReward",
    "RunningObsNorm",
    "SAILLoss",
    "TD3Update",
    "TRANSITION_KEYS",
    "TeacherReplayBuffer",
    "TimeFeature",
    "TopKTrajectoryWriter",
    "TrajectoryWriter",
    "UnionTrajectoryWriter",
    "check_demonstration_dims",
    "export_minari_dataset",
    "load_demonstrations",
    "load_minari_demonstrations",
    "load_sb_demonstrations",
    "make_sail_env",
    "nstep_view",
    "observation_normalizer",
    "save_demonstrations",
]
