"""What produced a run: the code's commit, the library versions, the CPU and torch's threads."""

from __future__ import annotations

import importlib.metadata
import platform
import subprocess
from pathlib import Path

import torch


def provenance(code_dir: Path | None = None) -> dict:
    """What produced a run: the git commit of ``code_dir`` (default: this package's folder;
    ``None`` outside a git checkout), whether tracked files differed from it (``dirty``), the
    library versions, the Python version, the CPU and torch's thread count."""
    cwd = Path(code_dir) if code_dir is not None else Path(__file__).resolve().parent

    def git(*args):
        try:
            out = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.SubprocessError):
            return None
        return out.stdout.strip() if out.returncode == 0 else None

    commit = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no") if commit else None
    versions = {
        name: _version(name) for name in ("torchrl_sail", "torch", "torchrl", "tensordict", "gymnasium", "mujoco")
    }
    return {
        "commit": commit,
        "dirty": None if status is None else bool(status),
        "versions": versions,
        "python": platform.python_version(),
        "cpu": platform.processor() or platform.machine(),
        "cpu_model": cpu_model(),
        "torch_threads": torch.get_num_threads(),
    }


def code_label(record: dict) -> str:
    """The code a benchmark record measured, as a report names it.

    Args:
        record: a record's setup: a ``code`` note where it has one, else the ``commit`` and ``dirty`` of
            :func:`provenance`.

    Returns:
        The ``code`` note; else ``commit <7 hex digits>``, with ``(uncommitted changes)`` when ``dirty``;
        else ``not recorded``.
    """
    if record.get("code"):
        return record["code"]
    if record.get("commit"):
        return f"commit {record['commit'][:7]}" + (" (uncommitted changes)" if record.get("dirty") else "")
    return "not recorded"


def _version(package: str) -> str | None:
    """The installed version of ``package`` (``None`` when it runs from a checkout without being installed)."""
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def cpu_model() -> str | None:
    """The CPU's model name (Linux ``/proc/cpuinfo``), ``None`` where it cannot be read."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


#: The CPU flags that decide the matrix-product speed of fp32 and bfloat16 on x86.
MATMUL_FLAGS = ("avx2", "avx512f", "avx512_bf16", "amx_bf16", "amx_tile")


def cpu_flags() -> list[str]:
    """Which of :data:`MATMUL_FLAGS` the CPU has (Linux ``/proc/cpuinfo``), ``[]`` where it cannot be read."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
                return [flag for flag in MATMUL_FLAGS if flag in flags]
    except OSError:
        pass
    return []
