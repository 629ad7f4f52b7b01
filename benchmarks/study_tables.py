"""The tables of a study's README, made from the run folders it lists.

    python benchmarks/study_tables.py benchmarks/results/preact_h200 [--table preact-seeds]

A study folder under ``benchmarks/results/`` lists its tables in ``tables.json``: each is a kind and
the runs it shows, by label and folder (relative to the study folder); every figure comes from the
runs' own files (``summary.json``, ``scalars.csv``, ``config.yaml``), none is typed.
``python benchmarks/aggregate.py --update-docs`` writes each table into the README's block of the
same name, and ``--check`` (``tests/test_generated_docs.py``) fails where one differs. The kinds:

- ``seeds``: ``{"rows": [[case, setting, run], ...]}``, one row per run: its case (with the teacher's
  return), setting, seed, last-5 (the mean of its last five evaluations), last-5 over the teacher's
  return, final and best evaluation, the frame it first evaluated above the teacher, and the
  trajectories it promoted (with the frame of the first, where the run logged it). A case or setting
  that repeats the row above is left blank.
- ``means``: ``{"of": <a seeds table>}``: per case and setting of that table, the last-5's mean and
  sample std over its seeds.
- ``windows``: ``{"window": frames, "rows": [[label, run, [part, ...]], ...]}``, per window of frames
  (:func:`windows.windows`), one line per part (:data:`PARTS`): ``d`` (D's accuracy on teacher /
  agent rows), ``actor`` (the actor's saturation / mean pre-tanh ``|x|``), ``eval`` (the mean
  evaluation), ``train`` (the best training episode), ``reward`` (``-log(1 - D)`` on agent rows, mean
  / std), ``logit`` (D's mean logit on teacher / agent rows) and ``gp`` (the gradient penalty);
  ``-`` where the run logged none in a window.
- ``runs``: ``{"columns": [...], "rows": [[section], [label, run], ...]}``: one row per run, its
  label then the columns named (:data:`RUN_COLUMNS`: every evaluation, last-5 and over the teacher,
  final, best, the best policy's evaluation (kept by the authors' rule), passed at, the promotions
  (with the first's frame), the threshold C and the frame alpha switched at, D's last accuracies,
  the share of D steps skipped, the last frame D was saturated (both accuracies >= 0.98; ``never``)
  and the share of logged points it was, and the run's frames per second, from the run's summary;
  ``-`` where it has none); a row of one item starts a section of runs with one teacher, written
  with that teacher's return (their summaries'). A run cut short, without a ``summary.json``, is
  labelled with its last evaluation's frame, passes the teacher at its first evaluation above the
  section's teacher return (written beside it) and promoted what it logged.
- ``evaluations``: ``{"first": frames, "last": frames, "header": [first column, run column, ...],
  "rows": [[label, run, ...], ...]}``: each run's evaluations from ``first`` to ``last`` frames,
  rounded to integers.
- ``run-windows``: ``{"run": run, "window": frames, "columns": [[header, format, [name, ...]], ...]}``:
  one run, one row per window of frames, each column ``format`` filled with the window's values of
  :data:`windows.COLUMNS` named (e.g. ``["D accuracy teacher / agent", "{:.2f} / {:.2f}", ["D acc
  teacher", "D acc agent"]]``); ``-`` where the run logged none of one.
- ``grid``: ``{"header": [...], "labels": n, "cell": [format, [[tag, stat, first, last], ...]],
  "rows": [[label, ..., run, ...], ...]}``: each row's first ``n`` items as written, then one cell
  per run, ``format`` filled with each logged scalar's ``stat`` over the frames from ``first`` to
  ``last``, both included: ``mean``, ``max``, or ``at`` (its value at ``last``).
- ``csv``: ``{"file": csv file, "keys": [column, ...], "header": [...], "cells": [[format, how],
  ...]}``: one row per value of ``keys`` (in the file's order, written first), then each cell's
  ``format`` filled with that group's rows' columns by name (numbers as floats): ``how`` is
  ``join`` (every row, joined by commas) or ``first`` (its first row).
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import Run, load_run, study_spec  # noqa: E402
from windows import COLUMNS as WINDOW_COLUMNS  # noqa: E402
from windows import windows  # noqa: E402

from torchrl_sail.harness import read_scalar  # noqa: E402


def thousands(frames: int | None) -> str:
    """Frames as the tables write them: ``40k``, ``28.5k``; ``-`` for none."""
    if frames is None:
        return "-"
    return f"{frames / 1000:g}k"


def run_at(study: Path, folder: str) -> Run:
    """The run ``folder`` (relative to ``study``) names, read; refused if it is not a finished run."""
    run = load_run(Path(study) / folder)
    if run.summary is None or not run.curve:
        raise ValueError(f"{Path(study) / folder}: no summary.json or no evaluations to show")
    return run


def final_and_best(run: Run) -> tuple[float, float]:
    """``run``'s last and best evaluation: its summary's where it has them (exact where a results copy's
    ``scalars.csv`` holds the progress bar's rounded evaluations), else its curve's."""
    summary = run.summary or {}
    final, best = summary.get("final_eval_return"), summary.get("best_eval_return")
    return (
        run.final_return if final is None else float(final),
        run.best_return if best is None else float(best),
    )


def promotions(run: Run) -> tuple[int, int | None]:
    """The trajectories ``run`` promoted (its summary's count, else the most it logged) and the frame
    it logged the first at (None where it logged none)."""
    logged = read_scalar(run.folder, "teacher/num_promoted")
    first = next((frames for frames, value in logged if value > 0), None)
    if run.summary is not None:
        return int(run.summary["num_promoted"]), first
    return int(max((value for _, value in logged), default=0)), first


def promoted(run: Run) -> str:
    """The trajectories ``run`` promoted, with the frame of the first where it logged them."""
    count, first = promotions(run)
    return f"{count} ({thousands(first)})" if count and first is not None else str(count)


def seeds_table(study: Path, table: dict) -> str:
    lines = [
        "| case | setting | seed | last-5 | / T | final | best | passed at | promoted (first at) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    before = (None, None)
    for case, setting, folder in table["rows"]:
        run = run_at(study, folder)
        teacher = run.teacher_return
        shown_case = "" if case == before[0] else f"{case} ({teacher:.1f})"
        shown_setting = "" if (case, setting) == before else setting
        before = (case, setting)
        last5, (final, best) = run.headline_return, final_and_best(run)
        cells = [
            shown_case,
            shown_setting,
            str(run.seed),
            f"{last5:.1f}",
            f"{last5 / teacher:.2f}",
            f"{final:.1f}",
            f"{best:.1f}",
            thousands(run.passed_teacher_at()),
            promoted(run),
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def means_table(study: Path, table: dict, tables: dict) -> str:
    groups: dict[tuple[str, str], list[float]] = {}
    for case, setting, folder in tables[table["of"]]["rows"]:
        groups.setdefault((case, setting), []).append(run_at(study, folder).headline_return)
    lines = ["| case | setting | seeds | last-5, mean ± std |", "|---|---|---|---|"]
    for (case, setting), values in groups.items():
        spread = f" ± {statistics.stdev(values):.1f}" if len(values) > 1 else ""
        lines.append(f"| {case} | {setting} | {len(values)} | {statistics.fmean(values):.1f}{spread} |")
    return "\n".join(lines)


PARTS = {
    "d": ("D", ("D acc teacher", "D acc agent"), ("{:.3f}", "{:.3f}")),
    "actor": ("actor", ("actor saturated", "actor |pre-tanh|"), ("{:.2f}", "{:.1f}")),
    "eval": ("eval", ("eval",), ("{:.1f}",)),
    "train": ("best training episode", ("train max",), ("{:.1f}",)),
    "reward": ("-log(1 - D) agent mean / std", ("-log(1-D) agent", "-log(1-D) agent std"), ("{:.2f}", "{:.2f}")),
    "logit": ("logit teacher / agent", ("logit teacher", "logit agent"), ("{:.2f}", "{:.2f}")),
    "gp": ("gradient penalty", ("GP",), ("{:.4f}",)),
}


def windows_table(study: Path, table: dict) -> str:
    size = int(table["window"])
    rows = [(label, windows(Path(study) / folder, size), parts) for label, folder, parts in table["rows"]]
    count = max(len(found) for _, found, _ in rows)
    header = [f"{k * size / 1000:g}-{(k + 1) * size / 1000:g}k" for k in range(count)]
    lines = ["| run | " + " | ".join(header) + " |", "|---|" + "---|" * count]
    for label, found, parts in rows:
        for index, part in enumerate(parts):
            name, columns, formats = PARTS[part]
            cells = [
                " / ".join(
                    "-" if math.isnan(window[column]) else form.format(window[column])
                    for column, form in zip(columns, formats, strict=True)
                )
                for window in found
            ]
            cells += ["-"] * (count - len(cells))  # a run that logged fewer windows
            title = f"{label}: {name}" if index == 0 else name
            lines.append(f"| {title} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run_windows_table(study: Path, table: dict) -> str:
    size, columns = int(table["window"]), table["columns"]
    unknown = sorted({name for _, _, names in columns for name in names} - {name for name, _, _ in WINDOW_COLUMNS})
    if unknown:
        raise ValueError(f"{Path(study) / 'tables.json'}: unknown window columns {unknown}")
    lines = ["| frames | " + " | ".join(header for header, _, _ in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for window in windows(Path(study) / table["run"], size):
        cells = [
            "-" if any(math.isnan(window[name]) for name in names) else form.format(*(window[name] for name in names))
            for _, form, names in columns
        ]
        span = f"{(window['frames'] - size) / 1000:g}-{window['frames'] / 1000:g}k"
        lines.append(f"| {span} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: How a grid cell's scalar becomes one number over the frames ``first <= f <= last``
STATS = {"mean": statistics.mean, "max": max, "at": lambda values: values[-1]}


def grid_stat(folder: Path, tag: str, stat: str, first: int, last: int) -> float:
    rows = [(frames, value) for frames, value in read_scalar(folder, tag) if first <= frames <= last]
    if stat == "at":
        rows = [(frames, value) for frames, value in rows if frames == last]
    if not rows:
        raise ValueError(f"{folder}: no {tag} logged from {first} to {last} frames")
    return STATS[stat]([value for _, value in rows])


def grid_table(study: Path, table: dict) -> str:
    form, stats = table["cell"]
    unknown = sorted({stat for _, stat, _, _ in stats} - set(STATS))
    if unknown:
        raise ValueError(f"{Path(study) / 'tables.json'}: unknown stats {unknown} (not {', '.join(STATS)})")
    labels = int(table["labels"])
    lines = ["| " + " | ".join(table["header"]) + " |", "|---" * len(table["header"]) + "|"]
    for row in table["rows"]:
        cells = [form.format(*(grid_stat(Path(study) / folder, *stat) for stat in stats)) for folder in row[labels:]]
        lines.append("| " + " | ".join([*row[:labels], *cells]) + " |")
    return "\n".join(lines)


def csv_table(study: Path, table: dict) -> str:
    path = Path(study) / table["file"]
    with path.open(newline="") as handle:
        records = [{name: _number(value) for name, value in row.items()} for row in csv.DictReader(handle)]
    groups: dict[tuple, list[dict]] = {}
    for record in records:
        groups.setdefault(tuple(str(record[key]) for key in table["keys"]), []).append(record)
    lines = ["| " + " | ".join(table["header"]) + " |", "|---" * len(table["header"]) + "|"]
    for key, rows in groups.items():
        cells = []
        for form, how in table["cells"]:
            try:
                if how == "join":
                    cells.append(", ".join(form.format(**row) for row in rows))
                elif how == "first":
                    cells.append(form.format(**rows[0]))
                else:
                    raise ValueError(f"{path}: a cell is 'join' or 'first', not {how!r}")
            except KeyError as err:
                raise ValueError(f"{path}: no column {err} (it has {', '.join(rows[0])})") from err
        lines.append("| " + " | ".join([*key, *cells]) + " |")
    return "\n".join(lines)


def _number(value: str) -> float | str:
    try:
        return float(value)
    except ValueError:
        return value


def cut_short(study: Path, folder: str) -> Run:
    """A run stopped before its end (no ``summary.json``), read with the evaluations it logged."""
    run = load_run(Path(study) / folder)
    if not run.curve:
        raise ValueError(f"{Path(study) / folder}: no evaluations to show")
    return run


#: The columns of a ``runs`` table
RUN_COLUMNS = (
    "evaluations",
    "last-5",
    "/ T",
    "final",
    "best",
    "best policy",
    "passed at",
    "promoted (first at)",
    "promoted",
    "C at the end",
    "alpha switched at",
    "D accuracy teacher / agent (last)",
    "D steps skipped",
    "D saturated until",
    "D saturated (share of logged points)",
    "frames/s",
)


def runs_row(run: Run, label: str, columns: list[str], teacher: float) -> str:
    if run.summary is not None:
        passed = thousands(run.passed_teacher_at())
    else:
        label += f" (to {thousands(run.curve[-1][0])})"
        first = next(((frames, value) for frames, value in run.curve if value > teacher), None)
        passed = "-" if first is None else f"{thousands(first[0])} ({first[1]:.1f})"
    summary = run.summary or {}
    discriminator = summary.get("discriminator") or {}
    last, skipped = discriminator.get("last") or {}, discriminator.get("skipped_fraction")
    # the last logged point with D's accuracy at 0.98 or more on both sides; "never" where none was
    saturated = thousands(discriminator.get("last_saturated_frame")) if discriminator else "-"
    if discriminator and discriminator.get("last_saturated_frame") is None:
        saturated = "never"
    switched, threshold = summary.get("alpha_switched_at_frame"), summary.get("teacher_threshold")
    values = {
        "evaluations": lambda: ", ".join(f"{value:.0f}" for value in run.eval_returns),
        "last-5": lambda: f"{run.headline_return:.1f}",
        "/ T": lambda: f"{run.headline_return / teacher:.2f}",
        "final": lambda: f"{final_and_best(run)[0]:.1f}",
        "best": lambda: f"{final_and_best(run)[1]:.1f}",
        "best policy": lambda: "-" if run.best_policy_return is None else f"{run.best_policy_return:.1f}",
        "passed at": lambda: passed,
        "promoted (first at)": lambda: promoted(run),
        "promoted": lambda: str(promotions(run)[0]),
        "C at the end": lambda: "-" if threshold is None else f"{threshold:.0f}",
        "alpha switched at": lambda: thousands(switched),
        "D accuracy teacher / agent (last)": lambda: (
            f"{last['accuracy_teacher']:.2f} / {last['accuracy_agent']:.2f}" if last else "-"
        ),
        "D steps skipped": lambda: "-" if skipped is None else f"{skipped:.0%}",
        "D saturated until": lambda: saturated,
        "D saturated (share of logged points)": lambda: (
            "-" if discriminator.get("saturated_fraction") is None else f"{discriminator['saturated_fraction']:.0%}"
        ),
        "frames/s": lambda: "-" if summary.get("frames_per_second") is None else f"{summary['frames_per_second']:.0f}",
    }
    return f"| {label} | " + " | ".join(values[column]() for column in columns) + " |"


def runs_table(study: Path, table: dict) -> str:
    columns = list(table["columns"])
    unknown = sorted(set(columns) - set(RUN_COLUMNS))
    if unknown:
        raise ValueError(f"{Path(study) / 'tables.json'}: unknown columns {unknown}")
    lines = ["| run | " + " | ".join(columns) + " |", "|---|" + "---|" * len(columns)]
    sections: list[tuple[str, list[tuple[str, Run]]]] = []
    for row in table["rows"]:
        if len(row) == 1:
            sections.append((row[0], []))
        elif not sections:
            raise ValueError(f"{Path(study) / 'tables.json'}: the first row of a runs table is a section, [title]")
        else:
            label, folder = row
            sections[-1][1].append((label, cut_short(study, folder)))
    for title, runs in sections:
        returns = [run.teacher_return for _, run in runs if run.teacher_return is not None]
        if not returns:
            raise ValueError(f"{Path(study) / 'tables.json'}: section {title!r} has no run with a summary.json")
        teacher = statistics.median(returns)
        lines.append(f"| **{title} ({teacher:.1f})** |" + " |" * len(columns))
        lines += [runs_row(run, label, columns, teacher) for label, run in runs]
    return "\n".join(lines)


def evaluations_table(study: Path, table: dict) -> str:
    first, last = int(table["first"]), int(table["last"])
    lines = ["| " + " | ".join(table["header"]) + " |", "|---|" + "---|" * (len(table["header"]) - 1)]
    for label, *folders in table["rows"]:
        cells = []
        for folder in folders:
            curve = dict(read_scalar(Path(study) / folder, "eval/return"))
            cells.append(", ".join(f"{curve[frames]:.0f}" for frames in sorted(curve) if first <= frames <= last))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


#: Each kind's table, from the study folder and the table's entry of ``tables.json`` (``means`` apart)
RENDERERS = {
    "seeds": seeds_table,
    "windows": windows_table,
    "runs": runs_table,
    "evaluations": evaluations_table,
    "run-windows": run_windows_table,
    "grid": grid_table,
    "csv": csv_table,
}


def render(study: Path, name: str) -> str:
    """The Markdown of ``study``'s table ``name``.

    Raises:
        ValueError: an unknown table or kind (naming them), or a run folder without a summary or evaluations.
    """
    tables = study_spec(study)
    if name not in tables:
        raise ValueError(f"{Path(study) / 'tables.json'}: no table {name!r} (it has {', '.join(tables)})")
    table, kind = tables[name], tables[name].get("kind")
    if kind == "means":  # the one kind that reads another table
        return means_table(study, table, tables)
    if kind in RENDERERS:
        return RENDERERS[kind](study, table)
    names = ["seeds", "means", *list(RENDERERS)[1:]]
    kinds = f"{', '.join(names[:-1])} or {names[-1]}"
    raise ValueError(f"{Path(study) / 'tables.json'}: table {name!r} has kind {kind!r}, not {kinds}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", type=Path, help="a study folder with a tables.json")
    parser.add_argument("--table", default=None, help="one table (default: all of them)")
    args = parser.parse_args(argv)
    for name in [args.table] if args.table else list(study_spec(args.study)):
        print(f"{name}:\n\n{render(args.study, name)}\n")


if __name__ == "__main__":
    main()
