"""Griffe extension: renders the reStructuredText idioms of the docstrings as Markdown.

The package's docstrings are Google style with TorchRL's Sphinx markup inside: roles
(``:class:`~torchrl_sail.SAILLoss```), ``.. note::`` / ``.. warning::`` directives and
``.. math::`` blocks. mkdocstrings renders docstrings as Markdown, where these would show as
raw text. This extension rewrites each docstring before it is parsed (the source files are
not touched):

- a role becomes inline code, and a link to the API reference where its target is a name of
  ``torchrl_sail.__all__`` (``~`` keeps the last component, ``Title <target>`` the title);
- ``.. note::``, ``.. warning::`` (and the other admonitions) become Material admonitions;
- ``.. math::`` becomes a ``$$ ... $$`` block (``pymdownx.arithmatex``, rendered by MathJax).

Configured in ``mkdocs.yml`` (``plugins.mkdocstrings.handlers.python.options.extensions``).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import griffe

PACKAGE_INIT = Path(__file__).resolve().parents[2] / "torchrl_sail" / "__init__.py"
ROLE = re.compile(r":(?:py:)?(class|func|meth|data|attr|mod|obj|exc|const):`([^`]+)`")
TITLED = re.compile(r"^(.*?)\s*<([^>]+)>$", re.DOTALL)
DIRECTIVE = re.compile(r"^(\s*)\.\. (note|warning|tip|important|caution|danger|seealso|math)::\s*(.*)$")
LINKED_ROLES = {"class", "func", "data", "exc", "obj", "const"}
ADMONITIONS = {"seealso": 'info "See also"', "caution": "warning", "important": "note"}


def public_names() -> set[str]:
    """``torchrl_sail.__all__``, read from the source (nothing is imported)."""
    for node in ast.parse(PACKAGE_INIT.read_text()).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            return set(ast.literal_eval(node.value))
    return set()


def convert_roles(text: str, public: set[str]) -> str:
    def replace(match: re.Match) -> str:
        role, content = match.groups()
        titled = TITLED.match(content)
        if titled:
            shown, target = " ".join(titled.group(1).split()), titled.group(2).strip()
        else:
            target = content.strip()
            shown = target.lstrip("~").rsplit(".", 1)[-1] if target.startswith("~") else target
        target = target.lstrip("~")
        name = target.removeprefix("torchrl_sail.")
        if role in LINKED_ROLES and name in public:
            return f"[`{shown}`][torchrl_sail.{name}]"
        return f"`{shown}`"

    return ROLE.sub(replace, text)


def indentation(line: str) -> int:
    return len(line) - len(line.lstrip())


def convert_directives(text: str) -> str:
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        match = DIRECTIVE.match(lines[i])
        if not match:
            out.append(lines[i])
            i += 1
            continue
        indent, kind, first = match.groups()
        i += 1
        block = []
        while i < len(lines) and (not lines[i].strip() or indentation(lines[i]) > len(indent)):
            block.append(lines[i])
            i += 1
        while block and not block[-1].strip():
            block.pop()
        while block and not block[0].strip():
            block.pop(0)
        depth = min((indentation(line) for line in block if line.strip()), default=0)
        body = ([first] if first else []) + [line[depth:] for line in block]
        if out and out[-1].strip():
            out.append("")
        if kind == "math":
            out += [indent + "$$", *(indent + line if line else "" for line in body), indent + "$$"]
        else:
            out.append(f"{indent}!!! {ADMONITIONS.get(kind, kind)}")
            out += [indent + "    " + line if line else "" for line in body]
        out.append("")
    return "\n".join(out)


class RSTMarkup(griffe.Extension):
    """Rewrites every docstring's reStructuredText idioms as Markdown (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self.public = public_names()

    def on_instance(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = convert_roles(convert_directives(obj.docstring.value), self.public)
