"""Markdown summary of recorded ``sail_td3.py`` runs, read from their run folders.

    python benchmarks/summarize_runs.py benchmarks/results/hopper-v4_paper-teacher_*

Prints, per run, the deterministic eval curve (from TorchRL's CSV logs), when the eval first
passed the teacher, when the first agent trajectory was promoted (alpha switch), the best
training return, frames/s and peak memory (from ``summary.json``). It only reads files, so
every figure it prints was measured by the run itself.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def read_scalar(run_dir: Path, tag: str) -> list[tuple[int, float]]:
    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
    if not path.exists():
        return []
    rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
    return [(int(float(step)), float(value)) for step, value in rows]


def summarize(run_dir: Path) -> str:
    summary_path = run_dir / "summary.json"
    if not summary_path.exists():
        raise FileNotFoundError(f"{summary_path} not found: is {run_dir} a finished sail_td3.py run?")
    summary = json.loads(summary_path.read_text())
    evals = read_scalar(run_dir, "eval/return")
    train = read_scalar(run_dir, "train/dense_return")
    teacher = summary["teacher_return"]
    passed = next((frame for frame, value in evals if value > teacher), None)
    lines = [
        f"### {run_dir.name}: {summary['env']}, {summary['algo']}, seed {summary['seed']}, "
        f"{summary['frames'] // 1000}k frames",
        "",
        "| frames | " + " | ".join(f"{frame // 1000}k" for frame, _ in evals) + " |",
        "|---|" + "---|" * len(evals),
        "| eval return | " + " | ".join(f"{value:.0f}" for _, value in evals) + " |",
        "",
        f"- teacher return {teacher:.1f}; "
        + (f"eval first above it at {passed // 1000}k frames" if passed is not None
           else f"no eval above it within {summary['frames'] // 1000}k frames"),
        f"- best eval {max(v for _, v in evals):.0f}, final eval {evals[-1][1]:.0f}" if evals else "- no evals",
        f"- best training-episode mean return logged {max(v for _, v in train):.0f}" if train else "- no training returns",
        f"- alpha switched (first promotion) at {summary['alpha_switched_at_frame']} frames; "
        f"{summary['num_promoted']} promoted; final threshold C = {summary['teacher_threshold']:.0f}",
        f"- {summary['frames_per_second']:.1f} frames/s (since the last start), "
        f"peak RSS {summary['peak_memory_mb']:.0f} MB",
    ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", nargs="+", type=Path)
    args = parser.parse_args()
    print("\n\n".join(summarize(run_dir) for run_dir in args.run_dirs))


if __name__ == "__main__":
    main()
