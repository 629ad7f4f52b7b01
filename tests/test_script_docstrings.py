"""The docstring examples of the scripts' modules (``examples/``, ``benchmarks/``), which pytest's
``--doctest-modules`` does not reach: it collects the package and the tests alone."""

from __future__ import annotations

import doctest
import sys
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

WITH_EXAMPLES = sorted(
    path.relative_to(REPO).as_posix()
    for folder in ("examples", "benchmarks")
    for path in (REPO / folder).glob("*.py")
    if ">>> " in path.read_text()
)


def test_the_scripts_have_docstring_examples():
    assert "examples/run_utils.py" in WITH_EXAMPLES  # the glob finds them


@pytest.mark.parametrize("path", WITH_EXAMPLES)
def test_docstring_examples_run(path):
    folder, name = path.removesuffix(".py").split("/")
    module = load_benchmark(name) if folder == "benchmarks" else __import__(name)
    flags = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS
    result = doctest.testmod(module, optionflags=flags, verbose=False)
    assert result.attempted > 0 and result.failed == 0, f"{path}: {result.failed} of {result.attempted} failed"
