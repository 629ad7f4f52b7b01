"""Every generated table in the repository's Markdown is what ``benchmarks/aggregate.py`` makes from
the committed runs: the blocks between ``<!-- aggregate:<block> START/END -->`` markers of the README,
``docs/results.md``, ``docs/performance.md`` (from the benchmarks' JSON files) and the studies' READMEs
(``aggregate.DOCUMENTS``), and the generated files (the
campaign's report, the trusted-default rule, the fall tables). No training: the runs are read from
``benchmarks/results/``. ``python benchmarks/aggregate.py --update-docs`` writes what differs.
"""

from __future__ import annotations

import difflib
from pathlib import Path

import pytest
from benchmark_scripts import load_benchmark

aggregate = load_benchmark("aggregate")

REPO = Path(__file__).resolve().parents[1]
FIX = "python benchmarks/aggregate.py --update-docs writes them from the committed runs"


@pytest.fixture(scope="module")
def sources() -> dict:
    """The runs each block is made from, read once for the module."""
    return {}


def regenerate(name: str, text: str, sources: dict) -> tuple[str, list[str]]:
    with aggregate.in_folder(REPO):  # the blocks name runs relative to the repository
        return aggregate.regenerate(text, Path(name), aggregate.DOCUMENTS[name], sources)


def block_diff(name: str, old: str, new: str) -> str:
    return "".join(
        difflib.unified_diff(
            old.splitlines(keepends=True), new.splitlines(keepends=True), f"{name} (committed)", f"{name} (made)", n=1
        )
    )


@pytest.mark.parametrize("name", list(aggregate.DOCUMENTS))
def test_generated_blocks_match_the_committed_runs(name, sources):
    text = (REPO / name).read_text()
    new, changed = regenerate(name, text, sources)
    assert not changed, (
        f"{name}: generated block(s) {', '.join(changed)} differ from the committed runs; {FIX}\n"
        + block_diff(name, text, new)[-6000:]
    )


def test_generated_files_match_the_committed_runs(sources):
    stale = []
    with aggregate.in_folder(REPO):
        for name, make in aggregate.generated_files(sources).items():
            made = make()
            committed = aggregate.read_exact(Path(name)) if Path(name).is_file() else ""
            if committed != made:
                stale.append(f"{name}: differs from the committed runs\n" + block_diff(name, committed, made)[-3000:])
    assert not stale, f"{FIX}\n" + "\n".join(stale)


def test_a_changed_number_is_named_with_its_file_and_block(sources):
    name = "docs/results.md"
    text = (REPO / name).read_text()
    start, end = aggregate.markers("campaign")
    block = text[text.index(start) : text.index(end)]
    row = next(line for line in block.splitlines() if line.startswith("| Hopper-v4 | paper"))
    number = row.split(" | ")[3].split()[0].strip("*")  # the row's last-5 mean
    edited = text.replace(row, row.replace(number, f"{float(number) + 0.1:.1f}", 1))
    assert edited != text
    new, changed = regenerate(name, edited, sources)
    assert changed == ["campaign"] and new == regenerate(name, text, sources)[0]  # the figure made again
    # prose outside the blocks is the author's: changing it changes no block
    prose = text.replace("## What the numbers are", "## What the figures are")
    assert regenerate(name, prose, sources)[1] == []


def test_a_block_without_its_markers_or_unknown_is_refused(sources):
    name = "docs/results.md"
    text = (REPO / name).read_text()
    start, end = aggregate.markers("campaign-variants")
    with pytest.raises(ValueError, match=f"docs/results.md must have the line {start}, then the line {end}"):
        regenerate(name, text.replace(end, ""), sources)
    stray = text + "\n<!-- aggregate:nonesuch START -->\n<!-- aggregate:nonesuch END -->\n"
    with pytest.raises(
        ValueError, match="docs/results.md has generated blocks that aggregate.py does not make: nonesuch"
    ):
        regenerate(name, stray, sources)
