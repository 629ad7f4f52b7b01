"""Shared pytest fixtures for torchrl_sail."""
from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch

# One intra-op thread: on the 2-core CI machine, 2 threads contend with the
# collector/env and are slower, and single-threaded math is reproducible.
torch.set_num_threads(1)

REPO_ROOT = Path(__file__).resolve().parents[1]


def teachers_dir() -> Path:
    """Where the paper's teacher ``.npz`` files live (``../shared/data/teachers``)."""
    env = os.environ.get("TORCHRL_SAIL_TEACHERS")
    return Path(env) if env else REPO_ROOT.parent / "shared" / "data" / "teachers"


@pytest.fixture(scope="session")
def teacher_dir() -> Path:
    path = teachers_dir()
    if not path.is_dir():
        # On CI ../shared is always beside the clone: a missing folder is a failure there.
        if os.environ.get("CI"):
            pytest.fail(f"teacher demonstrations not found at {path}")
        pytest.skip(f"teacher demonstrations not found at {path}")
    return path


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)
