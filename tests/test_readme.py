"""The README's quickstart block runs as written, from the repository root."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def quickstart() -> str:
    text = (REPO / "README.md").read_text()
    section = text.split("## Quickstart", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(blocks) == 1, "the quickstart section holds one python block"
    return blocks[0]


@pytest.mark.slow
def test_quickstart_runs():
    proc = subprocess.run([sys.executable, "-c", quickstart()], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # the shipped Hopper teacher (return 463.6) sets C = floor(0.1 R) = 46; random-action episodes fall short
    match = re.search(r"C = ([\d.]+), promoted: (\d+), alpha = ([\d.]+)", proc.stdout)
    assert match, proc.stdout[-2000:]
    threshold, promoted, alpha = float(match[1]), int(match[2]), float(match[3])
    assert threshold >= 46.0 and (alpha == 0.0) == (promoted > 0)


def test_ci_runs_the_readmes_test_commands():
    """``.ci/run`` runs the README's install extra and its pytest lanes, verbatim and in order."""
    section = (REPO / "README.md").read_text().split("## Tests", 1)[1].split("\n## ", 1)[0]
    block = re.findall(r"```bash\n(.*?)```", section, flags=re.S)[0]
    commands = [line.split("#")[0].strip() for line in block.splitlines() if line.startswith("python -m pytest")]
    ci = [line.strip() for line in (REPO / ".ci" / "run").read_text().splitlines()]
    assert commands == [line for line in ci if line.startswith("python -m pytest")]
    assert ".[test" in next(line for line in ci if "pip install" in line and "-e" in line)
