"""torchrl_sail: Self-Adaptive Imitation Learning (SAIL) as TorchRL components.

Every public name is importable from the top level, e.g.
``from torchrl_sail import DelayedRewardTransform, SAILLoss``. The run harness of the training
scripts and benchmarks (run folders, resume, summaries) is :mod:`torchrl_sail.harness`, which this
import leaves out (its dependencies are the ``harness`` extra); the private TorchRL APIs the package
relies on are listed in ``torchrl_sail._compat``.
"""

from torchrl_sail.data import (
    TRANSITION_KEYS,
    Demonstrations,
    FIFOTrajectoryWriter,
    MixedReplayBuffer,
    PrioritizedMixedReplayBuffer,
    TeacherReplayBuffer,
    TopKTeacherReplayBuffer,
    TopKTrajectoryWriter,
    TrajectoryWriter,
    UnionTrajectoryWriter,
    check_demonstration_dims,
    export_minari_dataset,
    load_demonstrations,
    load_minari_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.divergence import DivergenceCheck, DivergenceError
from torchrl_sail.envs import (
    AbsorbingStateTransform,
    DelayedRewardTransform,
    DiscriminatorReward,
    NStepTransform,
    RNDReward,
    TimeFeature,
    make_sail_env,
    nstep_view,
    observation_normalizer,
)
from torchrl_sail.modules import Discriminator, DiscriminatorNet, RunningObsNorm, TD3ExplorationPolicy
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
    "PrioritizedMixedReplayBuffer",
    "RNDReward",
    "RunningObsNorm",
    "SAILLoss",
    "TD3ExplorationPolicy",
    "TD3Update",
    "TRANSITION_KEYS",
    "TeacherReplayBuffer",
    "TopKTeacherReplayBuffer",
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
