"""The components stand apart from the run harness: ``import torchrl_sail`` (and every component
module) works without the harness's dependencies, and ``pyproject.toml`` says so."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import tomllib

REPO = Path(__file__).resolve().parents[1]
#: the harness extra's top-level modules, which no component may import (tqdm is one too, but
#: TorchRL imports it itself)
HARNESS_ONLY = ("hydra", "omegaconf", "wandb", "matplotlib")

IMPORT_EVERY_COMPONENT = """
import importlib, sys
from pathlib import Path
import torchrl_sail
root = Path(torchrl_sail.__file__).parent
for path in sorted(root.rglob("*.py")):
    parts = path.relative_to(root.parent).with_suffix("").parts
    if "harness" not in parts:
        importlib.import_module(".".join(p for p in parts if p != "__init__"))
harness = [m for m in sys.modules if m.split(".")[0] in HARNESS_ONLY or m.startswith("torchrl_sail.harness")]
print(sorted(harness))
""".replace("HARNESS_ONLY", repr(HARNESS_ONLY))


def test_components_import_without_the_harness_or_its_dependencies():
    out = subprocess.run([sys.executable, "-c", IMPORT_EVERY_COMPONENT], capture_output=True, text=True, cwd=REPO)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip() == "[]"  # nothing of the harness, nor of its dependencies, was imported


def test_the_harness_dependencies_are_an_extra():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    core = {
        requirement.split(">")[0].split("[")[0].split("=")[0].split("<")[0] for requirement in project["dependencies"]
    }
    assert core == {"torch", "torchrl", "tensordict", "gymnasium", "mujoco", "numpy"}
    extras = project["optional-dependencies"]
    assert {"hydra-core", "wandb", "tqdm", "matplotlib"} <= {r.split(">")[0] for r in extras["harness"]}
    # the test and bench extras name the harness extra instead of repeating it
    assert "torchrl-sail[harness" in " ".join(extras["test"]) and "torchrl-sail[harness" in " ".join(extras["bench"])
