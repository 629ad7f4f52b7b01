"""Shared pytest fixtures for torchrl_sail."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import torch

from torchrl_sail.data import missing_paper_teachers, paper_teachers_dir

# One intra-op thread, here and in every process a test starts (the README's quickstart, Ray actors,
# launchers; the training scripts set theirs with `threads`): on the 2-core CI machine, two threads
# per process contend with the other xdist worker and are slower (the quickstart ~3x with the cores
# busy), and single-threaded math is reproducible. An OMP_NUM_THREADS of your own is kept.
os.environ.setdefault("OMP_NUM_THREADS", "1")
torch.set_num_threads(1)

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def teacher_dir() -> Path:
    """The folder with the paper's teacher ``.npz`` files: ``paper_teachers_dir()``.

    That is ``$TORCHRL_SAIL_TEACHERS`` if set, else the user cache that
    ``python -m torchrl_sail.data.download`` fills. Every pinned file must be there with its
    SHA-256; otherwise the tests that need them skip, saying why (on CI, where the variable
    points at the files, they fail instead).
    """
    path = paper_teachers_dir()
    missing = missing_paper_teachers(path)
    if missing:
        absent = missing_paper_teachers(path, verify=False)
        corrupt = [name for name in missing if name not in absent]
        problems = [f"{len(absent)} missing, e.g. {absent[0]}"] if absent else []
        problems += [f"{len(corrupt)} with another SHA-256, e.g. {corrupt[0]}"] if corrupt else []
        reason = (
            f"the paper's teacher files are not in {path} ({'; '.join(problems)}): get them with "
            f"`python -m torchrl_sail.data.download` or set TORCHRL_SAIL_TEACHERS to a folder that has them"
        )
        if os.environ.get("CI"):
            pytest.fail(reason)
        pytest.skip(reason)
    return path


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)


# The slow lane: whole modules that run the scripts end to end (subprocesses), learn, or build
# the docs; `python -m pytest -m "not slow"` is the unit lane.
SLOW_MODULES = {
    "test_example",
    "test_methods",
    "test_evaluate",
    "test_learning",
    "test_ray",
    "test_readme",
    "test_docs",
    "test_bench_collect",
    "test_fork_server",
}


# The longest modules start first, so that the xdist workers finish together instead of one of them
# starting Ray's minutes-long startup when the other has nothing left to run.
FIRST_MODULES = ("test_ray", "test_learning")


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.path.stem in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
    # a stable sort: each module's tests stay together and in order
    items.sort(
        key=lambda item: FIRST_MODULES.index(item.path.stem) if item.path.stem in FIRST_MODULES else len(FIRST_MODULES)
    )


def pytest_addoption(parser):
    # The learning test's precision: `python -m pytest tests/test_learning.py --precision bf16` checks
    # that optim.precision=bf16 learns too (the paired evidence beside the Hopper runs of
    # `benchmarks/campaign.py --stages precision`); the suite runs fp32.
    parser.addoption("--precision", choices=("fp32", "bf16"), default="fp32", help="optim.precision of test_learning")
    # The device of the scripts' end-to-end runs (tests/example_runner.py): on a GPU machine,
    # `python -m pytest -m slow tests/test_methods.py --device cuda` runs every method there, which
    # CI's CPU runners cannot.
    parser.addoption("--device", default="cpu", help="device=... of the scripts' runs in the end-to-end tests")


def pytest_configure(config):
    # read by example_runner.run in each (xdist) worker
    os.environ["TORCHRL_SAIL_TEST_DEVICE"] = config.getoption("--device")
