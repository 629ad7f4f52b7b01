"""The documentation site builds without a single warning: ``mkdocs build --strict`` (``mkdocs.yml``).

The docs tools are the ``docs`` extra (``pip install -e ".[docs]"``), not the ``test`` one: without
them the test is skipped, saying so (CI builds the site in a job of its own).
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
# mkdocs, Material for MkDocs (the theme), mkdocstrings and its Python handler
MISSING = [
    name
    for name in ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers")
    if importlib.util.find_spec(name) is None
]


@pytest.mark.skipif(
    bool(MISSING), reason=f"the docs tools are not installed (no {', '.join(MISSING)}): pip install -e '.[docs]'"
)
def test_docs_build_strict(tmp_path):
    site = tmp_path / "site"
    # NO_MKDOCS_2_WARNING: Material's end-of-life notice, printed at start-up, is not a build warning
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
        check=False,
    )
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, f"mkdocs build --strict failed:\n{log[-6000:]}"
    assert "WARNING" not in log, log[-6000:]
    for page in ("index.html", "components/index.html", "api/objectives/index.html"):
        assert (site / page).is_file(), f"{page} was not built"
