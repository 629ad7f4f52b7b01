"""MkDocs hook: every name of ``torchrl_sail.__all__`` must have its ``::: torchrl_sail.<name>``
entry in ``docs/api/``; a missing one is a warning, so ``mkdocs build --strict`` fails on it.

Configured in ``mkdocs.yml`` (``hooks``).
"""

from __future__ import annotations

import logging
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from griffe_rst import public_names

log = logging.getLogger("mkdocs.hooks.api_coverage")
ENTRY = re.compile(r"^::: torchrl_sail\.(\w+)\s*$", re.MULTILINE)


def on_config(config, **kwargs):
    api = Path(config["docs_dir"]) / "api"
    documented = {name for page in api.glob("*.md") for name in ENTRY.findall(page.read_text())}
    missing = sorted(public_names() - documented)
    if missing:
        log.warning(
            "torchrl_sail.__all__ names without an API entry in docs/api/*.md "
            "(add '::: torchrl_sail.<name>' to the page of their group): %s",
            ", ".join(missing),
        )
    return config
