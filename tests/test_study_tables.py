"""``benchmarks/study_tables.py``: a study README's tables made from made run folders, each figure
against a hand-computed value (no training)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from benchmark_scripts import load_benchmark

study_tables = load_benchmark("study_tables")


def write_run(folder: Path, seed: int, scalars: dict[str, list[tuple[int, float]]], *, teacher=50.0, promoted=0):
    """A results copy of a run: config.yaml, scalars.csv (tag,frames,value) and summary.json."""
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(
        yaml.safe_dump({"env": {"name": "Swimmer-v4"}, "algo": {"name": "sail"}, "seed": seed, "teacher": {}})
    )
    lines = ["tag,frames,value"] + [f"{tag},{f},{v}" for tag, rows in scalars.items() for f, v in rows]
    (folder / "scalars.csv").write_text("\n".join(lines) + "\n")
    evals = scalars["eval/return"]
    passed = next((f for f, v in evals if v > teacher), None)
    summary = {
        "teacher_return": teacher,
        "frames": evals[-1][0],
        "final_eval_return": evals[-1][1],
        "passed_teacher_at_frame": passed,
        "num_promoted": promoted,
    }
    (folder / "summary.json").write_text(json.dumps(summary))


@pytest.fixture
def study(tmp_path):
    """Two settings of one case: the defaults (seeds 1 and 2) and a penalty (seed 1), six evaluations each."""
    ten = [10_000 * k for k in range(1, 7)]
    write_run(
        tmp_path / "d1",
        1,
        {
            "eval/return": list(zip(ten, [10.0, 20.0, 60.0, 40.0, 80.0, 70.0], strict=True)),
            "teacher/num_promoted": [(27_000, 0.0), (28_500, 2.0), (40_000, 5.0)],
            "d/accuracy_teacher": [(5_000, 0.5), (15_000, 0.7), (25_000, 0.9)],
            "d/accuracy_agent": [(5_000, 0.6), (15_000, 0.8), (25_000, 1.0)],
        },
        promoted=5,
    )
    write_run(tmp_path / "d2", 2, {"eval/return": list(zip(ten, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], strict=True))})
    write_run(
        tmp_path / "p1",
        1,
        {
            "eval/return": list(zip(ten, [55.0, 10.0, 10.0, 10.0, 10.0, 10.0], strict=True)),
            "actor/saturation": [(5_000, 0.25), (25_000, 0.5)],
            "actor/preactivation": [(5_000, 2.0), (25_000, 3.06)],
        },
        promoted=3,  # logged no teacher/num_promoted: the count alone
    )
    tables = {
        "t-seeds": {
            "kind": "seeds",
            "rows": [["Swimmer", "defaults", "d1"], ["Swimmer", "defaults", "d2"], ["Swimmer", "`coef`", "p1"]],
        },
        "t-means": {"kind": "means", "of": "t-seeds"},
        "t-windows": {
            "kind": "windows",
            "window": 20_000,
            "rows": [["d, s1", "d1", ["d"]], ["p, s1", "p1", ["actor"]]],
        },
        "t-evals": {
            "kind": "evaluations",
            "first": 20_000,
            "last": 40_000,
            "header": ["seed", "a", "b"],
            "rows": [["1", "d1", "p1"]],
        },
    }
    (tmp_path / "tables.json").write_text(json.dumps(tables))
    return tmp_path


def rows(text: str) -> list[str]:
    return text.splitlines()[2:]


def test_seeds_table(study):
    # d1: last-5 = (20+60+40+80+70)/5 = 54.0, / 50 = 1.08, final 70, best 80, passed at 30k (60 > 50),
    # 5 promoted, the first at 28.5k; d2 never passed; p1 passed at 10k (55), 3 promoted, no log of when
    assert rows(study_tables.render(study, "t-seeds")) == [
        "| Swimmer (50.0) | defaults | 1 | 54.0 | 1.08 | 70.0 | 80.0 | 30k | 5 (28.5k) |",
        "|  |  | 2 | 4.0 | 0.08 | 6.0 | 6.0 | - | 0 |",
        "|  | `coef` | 1 | 10.0 | 0.20 | 10.0 | 55.0 | 10k | 3 |",
    ]


def test_means_table(study):
    # defaults: mean of 54 and 4 = 29.0, sample std = 50 / sqrt(2) = 35.36; one seed: no std
    assert rows(study_tables.render(study, "t-means")) == [
        "| Swimmer | defaults | 2 | 29.0 ± 35.4 |",
        "| Swimmer | `coef` | 1 | 10.0 |",
    ]


def test_windows_table(study):
    text = study_tables.render(study, "t-windows")
    assert text.splitlines()[0] == "| run | 0-20k | 20-40k | 40-60k |"  # up to the last frame logged, 60k
    # d1's D: (0.5 + 0.7) / 2 = 0.6 and (0.6 + 0.8) / 2 = 0.7 in 0-20k, 0.9 / 1.0 in 20-40k, none after
    # p1's actor: 0.25 / 2.0, then 0.50 / 3.1
    assert rows(text) == [
        "| d, s1: D | 0.600 / 0.700 | 0.900 / 1.000 | - / - |",
        "| p, s1: actor | 0.25 / 2.0 | 0.50 / 3.1 | - / - |",
    ]
    # the other parts: d1's evaluations (10, 20 | 60, 40 | 80, 70), and tags it never logged
    spec = json.loads((study / "tables.json").read_text())
    spec["t-windows"]["rows"] = [["d, s1", "d1", ["eval", "train", "gp"]]]
    (study / "tables.json").write_text(json.dumps(spec))
    assert rows(study_tables.render(study, "t-windows")) == [
        "| d, s1: eval | 15.0 | 50.0 | 75.0 |",
        "| best training episode | - | - | - |",
        "| gradient penalty | - | - | - |",
    ]


def test_evaluations_table(study):
    assert rows(study_tables.render(study, "t-evals")) == ["| 1 | 20, 60, 40 | 10, 10, 10 |"]


def test_bad_tables_are_named(study):
    with pytest.raises(ValueError, match=r"tables.json: no table 'nope' \(it has t-seeds, t-means"):
        study_tables.render(study, "nope")
    spec = json.loads((study / "tables.json").read_text())
    spec["t-odd"] = {"kind": "odd"}
    (study / "tables.json").write_text(json.dumps(spec))
    kinds = "seeds, means, windows, runs, evaluations, run-windows, grid or csv"
    with pytest.raises(ValueError, match=f"'t-odd' has kind 'odd', not {kinds}"):
        study_tables.render(study, "t-odd")
    (study / "d2" / "summary.json").unlink()
    with pytest.raises(ValueError, match=r"d2: no summary.json or no evaluations to show"):
        study_tables.render(study, "t-seeds")
    (study / "tables.json").write_text("{")
    with pytest.raises(ValueError, match="tables.json: Expecting property name"):
        study_tables.render(study, "t-seeds")


def test_runs_table_with_a_run_cut_short(study):
    """A section's teacher return is its finished runs'; a run without summary.json is labelled with
    its last evaluation's frame, passes at its first evaluation above that return (value beside it) and
    shows the promotions it logged."""
    write_run(study / "cut", 3, {"eval/return": [(10_000, 40.0), (20_000, 51.5), (30_000, 52.0)]})
    (study / "cut" / "summary.json").unlink()
    lines = (study / "cut" / "scalars.csv").read_text() + "teacher/num_promoted,25000,0\nteacher/num_promoted,29000,4\n"
    (study / "cut" / "scalars.csv").write_text(lines)
    spec = json.loads((study / "tables.json").read_text())
    spec["t-runs"] = {
        "kind": "runs",
        "columns": ["evaluations", "last-5", "promoted (first at)", "passed at"],
        "rows": [["Swimmer, weak"], ["defaults s1", "d1"], ["cut s3", "cut"]],
    }
    (study / "tables.json").write_text(json.dumps(spec))
    assert rows(study_tables.render(study, "t-runs")) == [
        "| **Swimmer, weak (50.0)** | | | | |",
        "| defaults s1 | 10, 20, 60, 40, 80, 70 | 54.0 | 5 (28.5k) | 30k |",
        # last-5 of three evaluations: their mean, 47.8
        "| cut s3 (to 30k) | 40, 52, 52 | 47.8 | 4 (29k) | 20k (51.5) |",
    ]
    spec["t-runs"]["columns"] = ["median"]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match=r"unknown columns \['median'\]"):
        study_tables.render(study, "t-runs")


def test_runs_table_reads_the_summary(study):
    """final and best are the summary's where a results copy kept rounded evaluations; C, the alpha
    switch, D's last accuracies and its skipped steps come from the summary."""
    write_run(study / "r", 4, {"eval/return": [(10_000, 40.0), (20_000, 88.0), (30_000, 75.0)]}, promoted=2)
    summary = json.loads((study / "r" / "summary.json").read_text())
    summary |= {
        "final_eval_return": 74.6,
        "best_eval_return": 87.9,
        "teacher_threshold": 8.0,
        "alpha_switched_at_frame": 35_000,
        "frames_per_second": 401.6,
        "best_policy": {"eval_return": 91.26},
        "discriminator": {
            "skipped_fraction": 0.574,
            "last_saturated_frame": 28_500,
            "saturated_fraction": 0.1,
            "last": {"accuracy_teacher": 0.976, "accuracy_agent": 0.3249},
        },
    }
    (study / "r" / "summary.json").write_text(json.dumps(summary))
    never = json.loads((study / "d1" / "summary.json").read_text())
    never["discriminator"] = {"last_saturated_frame": None, "skipped_fraction": 0.0}
    (study / "d1" / "summary.json").write_text(json.dumps(never))
    spec = json.loads((study / "tables.json").read_text())
    columns = ["last-5", "/ T", "final", "best", "best policy", "promoted", "C at the end", "alpha switched at"]
    columns += [
        "D accuracy teacher / agent (last)",
        "D steps skipped",
        "D saturated until",
        "D saturated (share of logged points)",
    ]
    columns += ["frames/s"]
    rows_ = [["Swimmer"], ["r", "r"], ["d2", "d2"], ["d1", "d1"]]
    spec["t-runs"] = {"kind": "runs", "columns": columns, "rows": rows_}
    (study / "tables.json").write_text(json.dumps(spec))
    # r: last-5 of its three evaluations 67.67, / 50 = 1.35; d2: no switch, no D record, nothing skipped;
    # r's best policy is the summary's; d1: a D record without a saturated point; last-5 (20+60+40+80+70)/5 = 54.0
    assert rows(study_tables.render(study, "t-runs"))[1:] == [
        "| r | 67.7 | 1.35 | 74.6 | 87.9 | 91.3 | 2 | 8 | 35k | 0.98 / 0.32 | 57% | 28.5k | 10% | 402 |",
        "| d2 | 4.0 | 0.08 | 6.0 | 6.0 | - | 0 | - | - | - | - | - | - | - |",
        "| d1 | 54.0 | 1.08 | 70.0 | 80.0 | - | 5 | - | - | - | 0% | never | - | - |",
    ]


def test_runs_table_sections_are_checked(study):
    spec = json.loads((study / "tables.json").read_text())
    spec["t-runs"] = {"kind": "runs", "columns": ["last-5"], "rows": [["d1", "d1"]]}
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match=r"the first row of a runs table is a section, \[title\]"):
        study_tables.render(study, "t-runs")
    (study / "d2" / "summary.json").unlink()
    spec["t-runs"]["rows"] = [["Swimmer"], ["d2", "d2"]]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="section 'Swimmer' has no run with a summary.json"):
        study_tables.render(study, "t-runs")


def test_run_windows_table(study):
    """One run per window: d1's evaluations (10, 20 | 60, 40 | 80, 70) and D's accuracies (5k, 15k | 25k)."""
    spec = json.loads((study / "tables.json").read_text())
    columns = [
        ["eval", "{:.1f}", ["eval"]],
        ["D", "{:.2f} / {:.2f}", ["D acc teacher", "D acc agent"]],
        ["Q", "{:.1f}", ["Q"]],
    ]
    spec["t-run-windows"] = {"kind": "run-windows", "run": "d1", "window": 20_000, "columns": columns}
    (study / "tables.json").write_text(json.dumps(spec))
    assert study_tables.render(study, "t-run-windows").splitlines() == [
        "| frames | eval | D | Q |",
        "|---|---|---|---|",
        "| 0-20k | 15.0 | 0.60 / 0.70 | - |",
        "| 20-40k | 50.0 | 0.90 / 1.00 | - |",
        "| 40-60k | 75.0 | - | - |",
    ]
    spec["t-run-windows"]["columns"] = [["x", "{}", ["median eval"]]]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match=r"unknown window columns \['median eval'\]"):
        study_tables.render(study, "t-run-windows")


def test_grid_table(study):
    """A cell per run from its scalars over a frame range, both ends included."""
    spec = json.loads((study / "tables.json").read_text())
    stats = [["eval/return", "at", 40_000, 40_000], ["eval/return", "mean", 20_000, 40_000]]
    stats.append(["eval/return", "max", 10_000, 60_000])
    spec["t-grid"] = {
        "kind": "grid",
        "header": ["setting", "s1", "s2"],
        "labels": 1,
        "cell": ["{:.0f} ({:.1f}; max {:.0f})", stats],
        "rows": [["defaults", "d1", "d2"]],
    }
    (study / "tables.json").write_text(json.dumps(spec))
    # d1: 40 at 40k, (20 + 60 + 40) / 3 = 40.0, max 80; d2: 4, (2 + 3 + 4) / 3 = 3.0, max 6
    assert rows(study_tables.render(study, "t-grid")) == ["| defaults | 40 (40.0; max 80) | 4 (3.0; max 6) |"]
    spec["t-grid"]["cell"][1] = [["eval/return", "at", 45_000, 45_000]]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="no eval/return logged from 45000 to 45000 frames"):
        study_tables.render(study, "t-grid")
    spec["t-grid"]["cell"][1] = [["eval/return", "median", 0, 60_000]]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match=r"unknown stats \['median'\]"):
        study_tables.render(study, "t-grid")


def test_csv_table(study):
    """Rows grouped by the keys in the file's order: each group's rows joined, or its first."""
    (study / "points.csv").write_text(
        "run,env,frames,sat,reward\na,Hopper,10,1.0,0.75\na,Hopper,11,0.5,0.5\nb,Swimmer,10,0.25,0\n"
    )
    spec = json.loads((study / "tables.json").read_text())
    spec["t-csv"] = {
        "kind": "csv",
        "file": "points.csv",
        "keys": ["env"],
        "header": ["env", "saturation at 10, 11", "first reward"],
        "cells": [["{sat:.2f}", "join"], ["{reward:.3f}", "first"]],
    }
    (study / "tables.json").write_text(json.dumps(spec))
    assert rows(study_tables.render(study, "t-csv")) == [
        "| Hopper | 1.00, 0.50 | 0.750 |",
        "| Swimmer | 0.25 | 0.000 |",
    ]
    spec["t-csv"]["cells"] = [["{q:.1f}", "first"]]
    (study / "tables.json").write_text(json.dumps(spec))
    with pytest.raises(ValueError, match="points.csv: no column 'q'"):
        study_tables.render(study, "t-csv")
