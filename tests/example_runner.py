"""Runs ``examples/sail_td3.py`` in a subprocess, as a user would (shared by the example tests)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "examples" / "sail_td3.py"


def run(run_dir: Path, *overrides: str, check: bool = True) -> subprocess.CompletedProcess:
    """``python examples/sail_td3.py hydra.run.dir=<run_dir> <overrides>``; raises on failure if ``check``."""
    env = {**os.environ, "WANDB_SILENT": "true", "HYDRA_FULL_ERROR": "0"}
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), f"hydra.run.dir={run_dir}", *overrides],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"sail_td3.py failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}")
    return proc


def scalar(run_dir: Path, tag: str) -> list[tuple[int, float]]:
    """(frames, value) rows of one scalar written by TorchRL's CSV logger."""
    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
    rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
    return [(int(float(s)), float(v)) for s, v in rows]
