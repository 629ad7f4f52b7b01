"""Runs ``examples/sail_td3.py`` in a subprocess, as a user would (shared by the example tests)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "examples" / "sail_td3.py"


def start(run_dir: Path, *overrides: str) -> subprocess.Popen:
    """Starts ``sail_td3.py hydra.run.dir=<run_dir> <overrides>`` without waiting (to kill it)."""
    env = {**os.environ, "WANDB_SILENT": "true"}
    return subprocess.Popen([sys.executable, str(SCRIPT), f"hydra.run.dir={run_dir}", *overrides],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=REPO)


def run(run_dir: Path, *overrides: str, check: bool = True, multirun: bool = False,
        env: dict | None = None) -> subprocess.CompletedProcess:
    """``python examples/sail_td3.py hydra.run.dir=<run_dir> <overrides>``; raises on failure if ``check``.

    With ``multirun=True`` it runs ``sail_td3.py -m hydra.sweep.dir=<run_dir> <overrides>`` instead.
    ``env`` adds environment variables.
    """
    env = {**os.environ, "WANDB_SILENT": "true", "HYDRA_FULL_ERROR": "0", **(env or {})}
    where = ["-m", f"hydra.sweep.dir={run_dir}"] if multirun else [f"hydra.run.dir={run_dir}"]
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), *where, *overrides],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
        cwd=REPO,
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"sail_td3.py failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-5000:]}")
    return proc


def scalar(run_dir: Path, tag: str) -> list[tuple[int, float]]:
    """(frames, value) rows of one scalar written by TorchRL's CSV logger."""
    path = run_dir / "logs" / "scalars" / f"{tag}.csv"
    rows = [line.split(",") for line in path.read_text().splitlines() if line.strip()]
    return [(int(float(s)), float(v)) for s, v in rows]


class Captured:
    """Stands in for a state-dict component of a run: keeps the state the checkpoint holds."""

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        self.state = state


def saved(run_dir: Path, *names: str) -> dict:
    """The saved state of a run's checkpoint components: ``run`` (a dict), state-dict components
    (``loss``, ``replay``, ``optim_critic``, ...) as their state dicts, ``teacher`` as a buffer."""
    from torchrl.checkpoint import Checkpoint

    from torchrl_sail import TeacherReplayBuffer, TopKTrajectoryWriter

    def holder(name):
        if name == "run":
            return {}
        if name == "teacher":
            return TeacherReplayBuffer(TopKTrajectoryWriter(k=10))
        return Captured()

    components = {name: holder(name) for name in names}
    Checkpoint(**components).load(run_dir / "checkpoint", components=list(names))
    return {name: value.state if isinstance(value, Captured) else value for name, value in components.items()}
