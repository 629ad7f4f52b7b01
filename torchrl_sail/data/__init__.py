"""Data: the teacher buffer and its writers, teacher/agent batch mixing, demonstration files
(the paper's ``.npz``, the project's folders, Minari datasets)."""
from torchrl_sail.data.demonstrations import (
    check_demonstration_dims,
    Demonstrations,
    load_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.data.keys import TRANSITION_KEYS
from torchrl_sail.data.minari import export_minari_dataset, load_minari_demonstrations
from torchrl_sail.data.mixed_buffer import MixedReplayBuffer
from torchrl_sail.data.teacher_buffer import (
    FIFOTrajectoryWriter,
    TeacherReplayBuffer,
    TopKTrajectoryWriter,
    TrajectoryWriter,
    UnionTrajectoryWriter,
)

__all__ = [
    "Demonstrations",
    "FIFOTrajectoryWriter",
    "MixedReplayBuffer",
    "TRANSITION_KEYS",
    "TeacherReplayBuffer",
    "TopKTrajectoryWriter",
    "TrajectoryWriter",
    "UnionTrajectoryWriter",
    "check_demonstration_dims",
    "export_minari_dataset",
    "load_demonstrations",
    "load_minari_demonstrations",
    "load_sb_demonstrations",
    "save_demonstrations",
]
