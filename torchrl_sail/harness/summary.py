"""A finished run's summary: ``summary.json`` with D's and the actor's saturation from the logs, the
timed part's speeds, provenance, and ``learning_curve.png``."""

from __future__ import annotations

import json
import resource
from pathlib import Path

from torchrl_sail._compat import timeit_totals
from torchrl_sail.harness.machine import provenance
from torchrl_sail.harness.runs import LEARNING_CURVE, SUMMARY, read_scalar, write_atomic

D_SATURATED = 0.98
_D_LAST = ("accuracy_teacher", "accuracy_agent", "reward_teacher", "reward_agent", "logit_teacher", "logit_agent")


def discriminator_summary(run_dir: Path) -> dict | None:
    """What a run's logged discriminator statistics say, for its ``summary.json``.

    From the ``d/*`` scalars (logged at the logging cadence, the last D step before each log):
    ``saturated_fraction``, the share of logged points where D's accuracy is at least
    :data:`D_SATURATED` on both the teacher's and the agent's rows; ``last_saturated_frame``, the
    last such point (``None``: never); ``skipped_fraction``, the mean of ``d/skipped`` (each the
    share of a logged block's D steps that ``optim.discriminator.max_accuracy`` skipped; ``None``
    if not logged); and
    ``last``, the last logged accuracy, reward and mean logit on each side. Also reads a results
    copy (``scalars.csv``), as :func:`read_scalar` does.

    Returns:
        the summary, or ``None`` when the run logged no discriminator accuracy (no D).

    Examples:
        >>> import tempfile
        >>> run_dir = Path(tempfile.mkdtemp())
        >>> d = run_dir / "logs" / "scalars" / "d"
        >>> d.mkdir(parents=True)
        >>> _ = (d / "accuracy_teacher.csv").write_text("500,1.0\\n1000,0.99\\n1500,0.9\\n")
        >>> _ = (d / "accuracy_agent.csv").write_text("500,0.99\\n1000,0.98\\n1500,1.0\\n")
        >>> summary = discriminator_summary(run_dir)
        >>> summary["saturated_fraction"], summary["last_saturated_frame"], summary["last"]
        (0.6666666666666666, 1000, {'accuracy_teacher': 0.9, 'accuracy_agent': 1.0})
    """
    teacher = read_scalar(run_dir, "d/accuracy_teacher")
    if not teacher:
        return None
    agent = dict(read_scalar(run_dir, "d/accuracy_agent"))
    saturated = [frame for frame, value in teacher if value >= D_SATURATED and agent.get(frame, 0.0) >= D_SATURATED]
    skipped = [value for _, value in read_scalar(run_dir, "d/skipped")]
    last = {}
    for name in _D_LAST:
        rows = read_scalar(run_dir, f"d/{name}")
        if rows:
            last[name] = rows[-1][1]
    return {
        "saturated_fraction": len(saturated) / len(teacher),
        "last_saturated_frame": saturated[-1] if saturated else None,
        "skipped_fraction": sum(skipped) / len(skipped) if skipped else None,
        "last": last,
    }


#: At or above this share of saturated action components the actor is said to be saturated.
ACTOR_SATURATED = 0.9


def actor_summary(run_dir: Path) -> dict | None:
    """What a TD3 run's logged actor saturation says, for its ``summary.json``.

    From the ``actor/saturation`` and ``actor/preactivation`` scalars (the share of the agent
    rows' action components with ``|tanh(x)| >= 0.99`` and the mean ``|x|`` of the actor's
    pre-tanh output, on the last TD3 batch before each log): ``saturated_fraction``, the share
    of logged points with a saturation of at least :data:`ACTOR_SATURATED`;
    ``last_saturated_frame``, the last such point (``None``: never); and ``last``, the last
    logged saturation and pre-activation. Also reads a results copy (``scalars.csv``).

    Returns:
        the summary, or ``None`` when the run logged no actor saturation (SAC, PPO, BC).

    Examples:
        >>> import tempfile
        >>> run_dir = Path(tempfile.mkdtemp())
        >>> actor = run_dir / "logs" / "scalars" / "actor"
        >>> actor.mkdir(parents=True)
        >>> _ = (actor / "saturation.csv").write_text("1000,0.2\\n2000,0.95\\n3000,1.0\\n4000,0.5\\n")
        >>> _ = (actor / "preactivation.csv").write_text("1000,1.0\\n2000,6.0\\n3000,11.0\\n4000,2.5\\n")
        >>> summary = actor_summary(run_dir)
        >>> summary["saturated_fraction"], summary["last_saturated_frame"], summary["last"]
        (0.5, 3000, {'saturation': 0.5, 'preactivation': 2.5})
    """
    saturation = read_scalar(run_dir, "actor/saturation")
    if not saturation:
        return None
    saturated = [frame for frame, value in saturation if value >= ACTOR_SATURATED]
    preactivation = read_scalar(run_dir, "actor/preactivation")
    return {
        "saturated_fraction": len(saturated) / len(saturation),
        "last_saturated_frame": saturated[-1] if saturated else None,
        "last": {
            "saturation": saturation[-1][1],
            **({"preactivation": preactivation[-1][1]} if preactivation else {}),
        },
    }


def train_timing(train_clock: tuple[float, int] | None, *, end: float, frames: int) -> dict:
    """Summary entries on the part of a run after warm-up: its frames, seconds and frames per
    second, and TorchRL ``timeit``'s total seconds and call counts per section since
    ``train_clock`` (``(time, frames)`` when the timed part began, after a ``timeit.erase()``;
    ``None``: the run ended within warm-up)."""
    if train_clock is None:
        return {"train_frames": 0, "train_seconds": 0.0, "train_frames_per_second": None}
    t0, frames0 = train_clock
    seconds = end - t0
    sections = timeit_totals()
    return {
        "train_frames": frames - frames0,
        "train_seconds": seconds,
        "train_frames_per_second": (frames - frames0) / max(seconds, 1e-9),
        "time_seconds": {name: total for name, (total, _) in sections.items()},
        "counts": {"frames": frames - frames0, **{name: count for name, (_, count) in sections.items()}},
    }


def plot_learning_curve(run_dir: Path, *, teacher_return: float, alpha_switch_frame: int | None, title: str) -> Path:
    """``learning_curve.png`` (the paper's Figure 2 style): the logged training and evaluation
    returns against frames, the teacher's return dashed and the alpha switch dotted."""
    # A Figure of its own (savefig renders a .png with Agg): no pyplot, so the caller's backend and
    # figures are left alone
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4))
    ax = fig.subplots()
    for tag, label, style in (
        ("train/dense_return", "training return (noisy actions)", {"alpha": 0.35}),
        ("eval/return", "eval return (deterministic)", {"marker": "o", "ms": 3}),
    ):
        rows = read_scalar(run_dir, tag)
        if rows:
            ax.plot([frames for frames, _ in rows], [value for _, value in rows], label=label, **style)
    ax.axhline(teacher_return, ls="--", c="gray", label=f"teacher ({teacher_return:.0f})")
    if alpha_switch_frame is not None:
        ax.axvline(alpha_switch_frame, ls=":", c="red", label="alpha -> 0 (first promotion)")
    ax.set(xlabel="environment frames", ylabel="dense episode return", title=title)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path = Path(run_dir) / LEARNING_CURVE
    fig.savefig(path, dpi=100)
    return path


def write_summary(run_dir: Path, summary: dict, *, code_dir: Path | None = None) -> dict:
    """Writes ``summary.json`` (atomically): ``summary``, then the process's peak memory
    (``peak_memory_mb``), the ``learning_curve`` file name and the :func:`provenance` of
    ``code_dir``. Returns what it wrote."""
    summary = {
        **summary,
        "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,  # Linux: KiB
        "learning_curve": LEARNING_CURVE,
        "provenance": provenance(code_dir),
    }
    write_atomic(Path(run_dir) / SUMMARY, json.dumps(summary, indent=2))
    return summary
