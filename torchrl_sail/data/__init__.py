"""Data: the teacher buffer and its writers, teacher/agent batch mixing, demonstration files
(the paper's ``.npz``, the project's folders, Minari datasets) and the download of the paper's
teacher files."""

from torchrl_sail.data.columns import keep_columns, parse_columns, unreproduced_columns
from torchrl_sail.data.demonstrations import (
    Demonstrations,
    check_demonstration_dims,
    load_demonstrations,
    load_sb_demonstrations,
    save_demonstrations,
)
from torchrl_sail.data.keys import TRANSITION_KEYS
from torchrl_sail.data.minari import export_minari_dataset, load_minari_demonstrations
from torchrl_sail.data.mixed_buffer import MixedReplayBuffer
from torchrl_sail.data.paper_teachers import (
    download_paper_teachers,
    missing_paper_teachers,
    paper_teachers_dir,
)
from torchrl_sail.data.prioritized_mixed_buffer import PrioritizedMixedReplayBuffer
from torchrl_sail.data.teacher_buffer import (
    FIFOTrajectoryWriter,
    TeacherReplayBuffer,
    TopKTeacherReplayBuffer,
    TopKTrajectoryWriter,
    TrajectoryWriter,
    UnionTrajectoryWriter,
)

__all__ = [
    "Demonstrations",
    "FIFOTrajectoryWriter",
    "MixedReplayBuffer",
    "PrioritizedMixedReplayBuffer",
    "TRANSITION_KEYS",
    "TeacherReplayBuffer",
    "TopKTeacherReplayBuffer",
    "TopKTrajectoryWriter",
    "TrajectoryWriter",
    "UnionTrajectoryWriter",
    "check_demonstration_dims",
    "download_paper_teachers",
    "export_minari_dataset",
    "keep_columns",
    "load_demonstrations",
    "load_minari_demonstrations",
    "load_sb_demonstrations",
    "missing_paper_teachers",
    "paper_teachers_dir",
    "parse_columns",
    "save_demonstrations",
    "unreproduced_columns",
]
