"""Rebuild a run's evaluation curve from its progress log, for a run whose ``logs/`` folder is gone.

The example's progress bar shows the last evaluation's mean return, rounded to an integer
(``eval=2888``), and the run evaluates on each collector batch that crosses a multiple of
``eval.every_frames``; so the last progress line at each such frame count holds that evaluation.
This writes the run's results copy (``scalars.csv``, ``tag,frames,value``) with those
``eval/return`` rows alone, so that ``benchmarks/aggregate.py`` reports the run as it reports any
other. The values are rounded to the integer: say so wherever they are reported. A curve whose
highest and last points disagree with ``summary.json``'s ``best_eval_return`` and
``final_eval_return`` (by more than the rounding), or that misses an evaluation, is refused, as
is a run folder that already has a ``scalars.csv`` or its ``logs/``.

Usage::

    python benchmarks/progress_evals.py RUN_DIR [RUN_DIR ...] [--log campaign.log]
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

import yaml

from torchrl_sail.harness import COLLECTED_SCALARS, write_atomic

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
from run_utils import crossings  # noqa: E402  (the example's cadence rule, so the two cannot drift)

# tqdm's line: "  90%|...| 90000/100000 [04:00<00:27, 370.0frames/s, C=281, alpha=0.00, eval=2888, fps=374, ret=323]"
PROGRESS = re.compile(r"(\d+)/\d+ \[.*\beval=(\S+?)[,\]]")


def eval_curve(log_text: str, every_frames: int) -> list[tuple[int, float]]:
    """The ``(frames, return)`` of each evaluation a progress log shows.

    The example evaluates on the first collector batch that crosses a multiple of
    ``every_frames`` and redraws the postfix after ``pbar.update``, so the last progress line at
    such a frame count holds that evaluation. A resumed run appends to the log from its
    checkpoint's frame count on; its later lines replace the earlier ones at each frame count.

    Examples:
        >>> text = "10000/30000 [00:10, eval=-]\\r10000/30000 [00:10, eval=12]\\r15000/30000 [00:15, eval=12]"
        >>> eval_curve(text + "\\r21000/30000 [00:21, eval=12]\\r30000/30000 [00:30, eval=-3]", 10000)
        [(10000, 12.0), (21000, 12.0), (30000, -3.0)]
    """
    shown: dict[int, str] = {}
    for line in re.split(r"[\r\n]", log_text):
        match = PROGRESS.search(line)
        if match:
            shown[int(match.group(1))] = match.group(2)
    curve, before = [], 0
    for frames in sorted(shown):
        if crossings(every_frames, 0, before, frames):
            if shown[frames] == "-":
                raise ValueError(f"the progress line at {frames} frames shows no evaluation")
            curve.append((frames, float(shown[frames])))
        before = frames
    return curve


def rebuild(run_dir: Path, log_name: str) -> list[tuple[int, float]]:
    """Write ``run_dir/scalars.csv`` from ``run_dir/log_name``; returns the curve.

    Raises:
        SystemExit: the run already has its scalars, evaluates never (``eval.every_frames=0``), or
            its log does not show every evaluation, or shows a curve whose last and highest points
            disagree with ``summary.json``.
    """
    if (run_dir / COLLECTED_SCALARS).exists() or (run_dir / "logs").exists():
        raise SystemExit(f"{run_dir} already has its logged scalars: nothing to rebuild")
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    summary = json.loads((run_dir / "summary.json").read_text())
    every = int(config["eval"]["every_frames"])
    if every <= 0:
        raise SystemExit(f"{run_dir / 'config.yaml'}: eval.every_frames={every}, the run never evaluated")
    try:
        curve = eval_curve((run_dir / log_name).read_text(errors="replace"), every)
    except ValueError as error:
        raise SystemExit(f"{run_dir / log_name}: {error}") from None
    expected = summary["frames"] // every
    if len(curve) != expected:
        raise SystemExit(f"{run_dir / log_name} shows {len(curve)} evaluations, the run made {expected}")
    values = [value for _, value in curve]
    for name, value in (("final_eval_return", values[-1]), ("best_eval_return", max(values))):
        if abs(summary[name] - value) > 0.5:
            raise SystemExit(f"{run_dir}: the progress log gives {name} {value}, summary.json {summary[name]:.1f}")
    rows = "".join(f"eval/return,{frames},{value}\n" for frames, value in curve)
    write_atomic(run_dir / COLLECTED_SCALARS, "tag,frames,value\n" + rows)
    return curve


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run folders (config.yaml, summary.json, the log)")
    parser.add_argument("--log", default="campaign.log", help="the progress log's name in each run folder")
    args = parser.parse_args(argv)
    for run_dir in args.runs:
        curve = rebuild(run_dir, args.log)
        print(f"{run_dir}: {len(curve)} evaluations, last {curve[-1][1]:g} at {curve[-1][0]} frames")
    return 0


if __name__ == "__main__":
    sys.exit(main())
