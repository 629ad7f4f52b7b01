"""Import a script of ``benchmarks/`` (not a package) as a module, for the tests of its helpers."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module ``benchmarks_<name>``, loaded once."""
    module_name = f"benchmarks_{name}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    spec = importlib.util.spec_from_file_location(module_name, BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def nest(settings: dict, into: dict) -> dict:
    """``into`` with each dotted key of ``settings`` (``"eval.actor": "target"``) set in its sections, as a
    run's ``config.yaml`` holds it; a ``None`` value is left out (a key the run's config lacks)."""
    for key, value in settings.items():
        if value is None:
            continue
        *sections, name = key.split(".")
        target = into
        for part in sections:
            target = target.setdefault(part, {})
        target[name] = value
    return into
