"""The run harness of the training scripts and benchmarks: run folders and their life cycle (start,
resume, logs), summaries and plots, and the provenance of every start.

It serves ``examples/`` and ``benchmarks/``, not the components: ``import torchrl_sail`` does not
import it, and its dependencies beyond the components' (Hydra's OmegaConf, matplotlib) come with
the ``harness`` extra, ``pip install -e ".[harness]"``.

- :mod:`torchrl_sail.harness.runs`: the run folder, its entries and its life cycle;
- :mod:`torchrl_sail.harness.summary`: ``summary.json`` and ``learning_curve.png``;
- :mod:`torchrl_sail.harness.machine`: what produced a run (commit, versions, CPU, threads).
"""

from torchrl_sail._compat import native_bf16_matmul, render_fps  # what the scripts read through private APIs
from torchrl_sail.harness.machine import MATMUL_FLAGS, code_label, cpu_flags, cpu_model, provenance
from torchrl_sail.harness.runs import (
    BEST_EVALUATED_POLICY,
    BEST_POLICY,
    CHECKPOINT,
    COLLECTED_SCALARS,
    CONFIG,
    LEARNING_CURVE,
    RESUME_MAY_CHANGE,
    SCALARS,
    SUMMARY,
    add_evaluation,
    checkpoint_dir,
    checkpoint_frames,
    config_additions,
    config_changes,
    fall_share,
    is_finished,
    last_checkpoint,
    new_run,
    read_scalar,
    restore_run,
    resume_mode,
    start_or_resume,
    truncate_scalar_logs,
    wall_time,
    write_atomic,
)
from torchrl_sail.harness.summary import (
    ACTOR_SATURATED,
    D_SATURATED,
    actor_summary,
    discriminator_summary,
    plot_learning_curve,
    train_timing,
    write_summary,
)

__all__ = [
    "ACTOR_SATURATED",
    "BEST_EVALUATED_POLICY",
    "BEST_POLICY",
    "CHECKPOINT",
    "COLLECTED_SCALARS",
    "CONFIG",
    "D_SATURATED",
    "LEARNING_CURVE",
    "MATMUL_FLAGS",
    "RESUME_MAY_CHANGE",
    "SCALARS",
    "SUMMARY",
    "actor_summary",
    "add_evaluation",
    "checkpoint_dir",
    "checkpoint_frames",
    "code_label",
    "config_additions",
    "config_changes",
    "cpu_flags",
    "cpu_model",
    "discriminator_summary",
    "fall_share",
    "is_finished",
    "last_checkpoint",
    "native_bf16_matmul",
    "new_run",
    "plot_learning_curve",
    "provenance",
    "read_scalar",
    "render_fps",
    "restore_run",
    "resume_mode",
    "start_or_resume",
    "train_timing",
    "truncate_scalar_logs",
    "wall_time",
    "write_atomic",
    "write_summary",
]
