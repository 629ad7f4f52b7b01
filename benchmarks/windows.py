"""A run's training diagnostics per window of frames: what the learner and its discriminator did when.

    python benchmarks/windows.py RUN_DIR [RUN_DIR ...] [--window 20000]

Reads a run's ``logs/scalars`` or its results copy (``scalars.csv``) with
:func:`torchrl_sail.harness.read_scalar` and prints, for each window ``(k * W, (k + 1) * W]``,
one Markdown row (the first window also holds frame 0, e.g. an offline run's one evaluation):
the mean evaluation return, the highest logged training return (``train/dense_return``: the mean
dense return of the episodes that ended in the last collector batch with an ending before each
log; on the 1000-step envs, HalfCheetah and Swimmer, every episode alone), the promotion threshold
``C`` and the promotions so far (their maximum in the window), the mean teacher share alpha,
the mean D reward of the critic's batches (under the method's ``algo.reward``), the means of
the discriminator's accuracy, ``-log(1 - D)`` (SAIL's reward) and mean logit on teacher / agent
rows of its own batches, the agent rows' spread (std) of ``-log(1 - D)`` and of the logit, the critic's mean Q,
the TD3 actor's saturation on the agent's rows (the share of action components with ``|tanh(x)| >= 0.99``)
and mean pre-tanh ``|x|``, the
gradient penalty and the share of D steps ``optim.discriminator.max_accuracy`` skipped. A tag a
run did not log prints ``-``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from statistics import mean

from torchrl_sail.harness import read_scalar

# (column, tag, how a window's values become one number)
COLUMNS = (
    ("eval", "eval/return", mean),
    ("train max", "train/dense_return", max),
    ("C", "teacher/threshold", max),
    ("promoted", "teacher/num_promoted", max),
    ("alpha", "alpha", mean),
    ("D acc teacher", "d/accuracy_teacher", mean),
    ("D acc agent", "d/accuracy_agent", mean),
    ("critic reward", "sail/d_reward_mean", mean),
    ("-log(1-D) teacher", "d/reward_teacher", mean),
    ("-log(1-D) agent", "d/reward_agent", mean),
    ("-log(1-D) agent std", "d/reward_agent_std", mean),
    ("logit teacher", "d/logit_teacher", mean),
    ("logit agent", "d/logit_agent", mean),
    ("logit agent std", "d/logit_agent_std", mean),
    ("Q", "sail/q_mean", mean),
    ("actor saturated", "actor/saturation", mean),
    ("actor |pre-tanh|", "actor/preactivation", mean),
    ("GP", "d/grad_penalty", mean),
    ("D skipped", "d/skipped", mean),
)


def windows(run_dir: Path, window: int) -> list[dict]:
    """One dict per window up to the last logged frame: ``frames`` (the window's end) and each column (nan: none)."""
    series = {name: read_scalar(run_dir, tag) for name, tag, _ in COLUMNS}
    last = max((frame for rows in series.values() for frame, _ in rows), default=0)
    table = []
    for k in range(max(1, math.ceil(last / window))):
        row = {"frames": (k + 1) * window}
        low = -1 if k == 0 else k * window  # the first window holds frame 0
        for name, _, reduce in COLUMNS:
            values = [v for frame, v in series[name] if low < frame <= (k + 1) * window]
            row[name] = reduce(values) if values else math.nan
        table.append(row)
    return table


def markdown(table: list[dict], window: int) -> str:
    def cell(value: float) -> str:
        if math.isnan(value):
            return "-"
        return f"{value:.0f}" if abs(value) >= 100 else f"{value:.3g}"

    names = [name for name, _, _ in COLUMNS]
    lines = ["| frames | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for row in table:
        span = f"{(row['frames'] - window) / 1000:g}-{row['frames'] / 1000:g}k"
        lines.append(f"| {span} | " + " | ".join(cell(row[name]) for name in names) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, nargs="+", help="run directories (logs/scalars or scalars.csv)")
    parser.add_argument("--window", type=int, default=20_000, help="frames per window")
    args = parser.parse_args(argv)
    if args.window <= 0:
        parser.error(f"--window must be > 0, got {args.window}")
    for run_dir in args.runs:
        if not (run_dir / "scalars.csv").is_file() and not (run_dir / "logs" / "scalars").is_dir():
            parser.error(f"{run_dir}: no scalars.csv and no logs/scalars")
        print(f"{run_dir}\n\n{markdown(windows(run_dir, args.window), args.window)}\n")


if __name__ == "__main__":
    main()
