"""Data: the top-K teacher buffer, teacher/agent batch mixing, demonstration files."""
from torchrl_sail.data.demonstrations import (
    check_demonstration_dims,
    Demonstrations,
    load_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.data.mixed_buffer import MixedReplayBuffer
from torchrl_sail.data.teacher_buffer import TopKTeacherReplayBuffer

__all__ = [
    "Demonstrations",
    "MixedReplayBuffer",
    "TopKTeacherReplayBuffer",
    "check_demonstration_dims",
    "load_demonstrations",
    "load_sb_demonstrations",
    "save_demonstrations",
]
