"""``benchmarks/aggregate.py`` on synthetic run folders, and the commands ``run_matrix.py`` and
``make_teachers.py`` build (no training)."""

from __future__ import annotations

import csv
import json
import shlex
import shutil
from pathlib import Path

import pytest
import yaml
from benchmark_scripts import load_benchmark

aggregate = load_benchmark("aggregate")
run_matrix = load_benchmark("run_matrix")
make_teachers = load_benchmark("make_teachers")

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def write_run(
    folder: Path,
    *,
    algo: str = "sail",
    seed: int = 0,
    env: str = "Hopper-v4",
    evals: list[tuple[int, float]] = ((1000, 10.0), (2000, 50.0), (3000, 100.0)),
    teacher_return: float = 150.0,
    teacher_path: str | None = "/data/paper.npz",
    total_frames: int = 3000,
    frames: int | None = 3000,
    finished: bool = True,
    offline: bool = False,
    this_version: bool = False,
    **config_extra,
) -> Path:
    """A run folder as ``sail_td3.py`` writes it: config.yaml, the eval CSV, summary.json if finished.
    ``this_version``: its config also holds the settings that older runs lack, as this version saves them."""
    folder.mkdir(parents=True)
    config = {
        "env": {"name": env},
        "algo": {"name": algo},
        "seed": seed,
        "teacher": {"path": teacher_path},
        "collector": {"total_frames": total_frames},
        **config_extra,
    }
    if this_version:
        saved_by_this_version(config)
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    scalars = folder / "logs" / "scalars" / "eval"
    scalars.mkdir(parents=True)
    (scalars / "return.csv").write_text("".join(f"{f},{v}\n" for f, v in evals))
    if finished:
        passed = next((f for f, v in evals if v > teacher_return), None)
        summary = {
            "env": env,
            "algo": algo,
            "seed": seed,
            "teacher_return": teacher_return,
            "teacher_source": teacher_path,
            "frames": frames,
            "final_eval_return": evals[-1][1] if evals else None,
            "passed_teacher_at_frame": passed,
            **({"offline": True} if offline else {}),
        }
        (folder / "summary.json").write_text(json.dumps(summary))
    return folder


def saved_by_this_version(config: dict) -> dict:
    """``config`` (changed in place) with each setting of ``config_schema.SAVED_BEFORE`` it lacks at what
    its method composes now: what a run of this version saves, whatever the defaults are."""
    defaults = aggregate.defaults_of(config["algo"]["name"], config["env"]["name"])
    for key in aggregate.examples_module("config_schema").SAVED_BEFORE:
        *sections, name = key.split(".")
        source, target = defaults, config
        for section in sections:
            source = source[section]
            if source is None:  # a section the method switches off (algo.rnd): the run saves null
                target.setdefault(section, None)
                break
            target = target.setdefault(section, {})
        else:
            target.setdefault(name, source[name])
    return config


def read_csv(path: Path) -> list[dict]:
    with path.open() as file:
        return list(csv.DictReader(file))


def run_aggregate(roots, out, **kwargs) -> tuple[str, dict]:
    text = aggregate.aggregate([Path(root) for root in roots], out, **kwargs)
    return text, {(row["env"], row["teacher"], row["method"]): row for row in read_csv(out / "results.csv")}


def frames_curve(values: list[float]) -> list[tuple[int, float]]:
    """Evals at 1000, 2000, ... frames."""
    return [(1000 * (index + 1), value) for index, value in enumerate(values)]


def test_run_headline_is_the_mean_of_the_last_five_evals(tmp_path):
    run = aggregate.load_run(
        write_run(
            tmp_path / "a",
            evals=frames_curve([1, 2, 3, 4, 5, 6, 7]),
            teacher_return=4.5,
            total_frames=7000,
            frames=7000,
        )
    )
    assert run.problem is None and run.headline_evals == 5
    assert run.headline_return == 5.0  # mean of 3..7
    assert run.final_return == 7.0 and run.best_return == 7.0
    assert run.passed_teacher_at() == 5000  # 5 > 4.5; 4 is not


def test_run_final_best_and_frames_to_pass_differ_on_a_bumpy_curve(tmp_path):
    evals = frames_curve([1, 2, 9, 4, 5, 6, 3])
    run = aggregate.load_run(write_run(tmp_path / "a", evals=evals, teacher_return=8.0, total_frames=7000, frames=7000))
    assert run.headline_return == pytest.approx(27 / 5)  # (9 + 4 + 5 + 6 + 3) / 5
    assert run.final_return == 3.0 and run.best_return == 9.0
    assert run.passed_teacher_at() == 3000
    never = aggregate.load_run(
        write_run(
            tmp_path / "b",
            evals=evals,
            teacher_return=9.0,  # equal is not above
            total_frames=7000,
            frames=7000,
        )
    )
    assert never.passed_teacher_at() is None


def test_run_with_three_evals_averages_all_three_and_says_so(tmp_path):
    write_run(tmp_path / "runs" / "seed0", evals=frames_curve([10, 20, 60]))
    run = aggregate.load_run(tmp_path / "runs" / "seed0")
    assert run.headline_evals == 3 and run.headline_return == 30.0
    assert run.final_return == 60.0 and run.best_return == 60.0
    text, rows = run_aggregate([tmp_path / "runs"], tmp_path / "out")
    row = rows["Hopper-v4", "paper", "sail"]
    assert float(row["last5_mean"]) == 30.0 and row["headline_evals_min"] == "3"
    assert "| sail | 30.0 † | - | n/a | 1 | 60.0 | 60.0 | 0.20 | n/a (0/1 seeds passed) | n/a |" in text
    assert (
        "Hopper-v4 / paper / sail: fewer than 5 evaluations, so the headline averages all of them "
        "(evaluations per seed: seed 0: 3)"
    ) in text


def test_group_headline_mean_std_ci_final_best_and_seeds_passed(tmp_path):
    curves = [
        [0, 500, 90, 110, 100, 80, 120],  # last 5: 100; final 120; best 500; passes 250 at 2000
        [0, 0, 190, 210, 200, 180, 220],  # last 5: 200; final 220; best 220; never passes 250
        [0, 0, 290, 310, 300, 280, 320],
    ]  # last 5: 300; final 320; best 320; passes at 3000
    for seed, curve in enumerate(curves):
        write_run(
            tmp_path / "runs" / f"seed{seed}",
            seed=seed,
            evals=frames_curve(curve),
            teacher_return=250.0,
            total_frames=7000,
            frames=7000,
        )
    text, rows = run_aggregate([tmp_path / "runs"], tmp_path / "out")
    row = rows["Hopper-v4", "paper", "sail"]
    assert float(row["last5_mean"]) == pytest.approx(200.0)
    assert float(row["last5_std"]) == pytest.approx(100.0)  # sample std (ddof=1) of 100, 200, 300
    assert float(row["final_mean"]) == pytest.approx(220.0)  # (120 + 220 + 320) / 3
    assert float(row["best_mean"]) == pytest.approx(1040 / 3)  # (500 + 220 + 320) / 3
    assert float(row["teacher_return"]) == 250.0 and float(row["vs_teacher"]) == pytest.approx(0.8)
    assert float(row["frames_to_teacher_median"]) == 2500.0 and row["seeds_past_teacher"] == "2/3"
    assert row["n_seeds"] == "3" and row["seeds"] == "0 1 2" and row["headline_evals_min"] == "5"
    low, high = float(row["ci95_low"]), float(row["ci95_high"])
    # mean 200 ± t(2) = 4.302653 times std 100 / sqrt(3): 248.41
    assert (low, high) == (pytest.approx(200 - 248.4138, abs=1e-3), pytest.approx(200 + 248.4138, abs=1e-3))
    # two seeds: t(1) = 12.7062; equal values: no spread; one value: none
    assert aggregate.t_ci([10.0, 20.0]) == (
        pytest.approx(15 - 12.7062 * 5, abs=1e-3),
        pytest.approx(15 + 63.531, abs=1e-3),
    )
    assert aggregate.t_ci([7.0, 7.0, 7.0]) == (7.0, 7.0) and aggregate.t_ci([7.0]) == (None, None)
    assert list(read_csv(tmp_path / "out" / "results.csv")[0])[3] == "last5_mean"  # the headline column first
    assert "| method | last-5 mean ± std | best policy | 95% CI |" in text
    # fall share: seed 0 passes at 500, then 5 evals all below; seed 2 passes at 290, then none of 4 below
    assert (
        f"| Hopper-v4 | paper (250.0) | sail | 200.0 ± 100.0 | - | [{low:.1f}, {high:.1f}] | 3 | 220.0 | 346.7 | "
        "0.80 | 2500 (2/3 seeds passed) | 55.6% (5/9) |"
    ) in text
    assert "## Missing or unfinished runs\n\nNone." in text
    assert "## Notes" not in text  # 5 evals per seed, no eval.episodes in the config


def test_run_without_eval_csv_falls_back_to_the_summary_and_other_episode_counts_are_noted(tmp_path):
    folder = write_run(tmp_path / "a", evals=frames_curve([10, 20, 30]), eval={"episodes": 5})
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, "best_eval_return": 40.0}))
    (folder / "logs" / "scalars" / "eval" / "return.csv").unlink()  # e.g. logger.backends without csv
    run = aggregate.load_run(folder)
    assert run.problem is None and run.curve == []
    assert (run.headline_return, run.final_return, run.best_return, run.headline_evals) == (30.0, 30.0, 40.0, 1)
    text, _ = run_aggregate([tmp_path], tmp_path / "out")
    assert "seed 0: 1 (no eval CSV: summary.json's final eval)" in text
    assert "Hopper-v4 / paper / sail: evaluations of eval.episodes=5 episodes (the reporting spec asks for 10)" in text


def test_a_seed_continued_with_other_settings_is_noted(tmp_path):
    write_run(tmp_path / "a", evals=frames_curve([10, 20, 30, 40, 50]))
    folder = write_run(tmp_path / "b", seed=1, evals=frames_curve([10, 20, 30, 40, 50]))
    summary = json.loads((folder / "summary.json").read_text())
    resumes = [
        {"frames": 2000, "changes": {"collector.total_frames": [2000, 5000], "threads": [1, 2]}},  # operational
        {"frames": 2500, "changes": {"optim.cudagraphs": [False, True], "collector.backend_options.x": [1, 2]}},
        # `threads_per_worker` is not `threads`: a key is covered by the keys above it, not by a prefix
        {"frames": 3000, "changes": {"optim.lr": [0.001, 0.0005], "logger.backends": [["csv"], ["wandb"]]}},
        {"frames": 4000, "changes": {"threads_per_worker": [1, 2]}},
        # resumed by a newer version: the settings it added, less the operational ones
        {"frames": 4500, "changes": {}, "added": {"optim.coef": 0.001, "logger.new_option": 1}},
        {"frames": 4800, "changes": {}, "removed": {"optim.old": 2}},
    ]
    (folder / "summary.json").write_text(json.dumps({**summary, "resumes": resumes}))
    text, _ = run_aggregate([tmp_path], tmp_path / "out")
    notes = [line for line in text.splitlines() if "went on from" in line]
    assert notes == [
        "- Hopper-v4 / paper / sail: seed 1 went on from frame 3000 with optim.lr 0.001 -> 0.0005",
        "- Hopper-v4 / paper / sail: seed 1 went on from frame 4000 with threads_per_worker 1 -> 2",
        "- Hopper-v4 / paper / sail: seed 1 went on from frame 4500 with optim.coef (new) 0.001",
        "- Hopper-v4 / paper / sail: seed 1 went on from frame 4800 with optim.old (removed) 2",
    ]


def test_frames_to_teacher_from_the_curve_when_the_summary_lacks_it(tmp_path):
    write_run(tmp_path / "a", evals=[(1000, 10.0), (2000, 151.0), (3000, 100.0)])
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    del summary["passed_teacher_at_frame"]
    (tmp_path / "a" / "summary.json").write_text(json.dumps(summary))
    write_run(tmp_path / "b", seed=1, evals=[(1000, 10.0), (2000, 20.0), (3000, 150.0)])  # equal: not above
    _, rows = run_aggregate([tmp_path], tmp_path / "out")
    row = rows["Hopper-v4", "paper", "sail"]
    assert float(row["frames_to_teacher_median"]) == 2000.0 and row["seeds_past_teacher"] == "1/2"


def test_missing_and_half_finished_runs_are_listed_not_averaged(tmp_path):
    runs = tmp_path / "runs"
    write_run(runs / "seed0", seed=0, evals=[(1000, 10.0), (2000, 20.0), (3000, 100.0)])
    write_run(runs / "seed1", seed=1, evals=[(1000, 10.0), (2000, 20.0), (3000, 300.0)])
    # No summary.json: stopped after its 2000-frame eval, with a checkpoint.
    write_run(runs / "seed2", seed=2, evals=[(1000, 10.0), (2000, 9999.0)], finished=False)
    (runs / "seed2" / "checkpoint").mkdir()
    # A summary, but fewer frames than collector.total_frames (e.g. a run extended later).
    write_run(runs / "seed4", seed=4, evals=[(1000, 9999.0)], frames=1000)
    text, rows = run_aggregate([runs], tmp_path / "out", expect_seeds=[0, 1, 2, 3, 4])
    row = rows["Hopper-v4", "paper", "sail"]
    assert row["n_seeds"] == "2" and row["seeds"] == "0 1" and float(row["final_mean"]) == 200.0
    assert float(row["last5_mean"]) == pytest.approx((130 / 3 + 110) / 2)  # 3 evals each: all averaged
    missing = text.split("## Missing or unfinished runs")[1]
    assert f"`{runs / 'seed2'}`: unfinished: no summary.json (last eval at 2000 frames, has checkpoint/)" in missing
    assert f"`{runs / 'seed4'}`: unfinished: 1000 of 3000 frames" in missing
    assert "`env Hopper-v4, teacher paper, method sail, seed 3`: missing: no run folder" in missing
    assert "9999" not in text.split("## Missing")[0]


def test_expected_method_without_any_run_is_listed(tmp_path):
    write_run(tmp_path / "runs" / "sail0")
    text, _ = run_aggregate([tmp_path / "runs"], tmp_path / "out", expect_methods=["sail", "gail"])
    assert "method gail, seed 0`: missing: no run folder" in text
    assert "method sail, seed 0`" not in text


def test_one_seed_has_no_std_or_ci_and_equal_values_a_point_ci(tmp_path):
    write_run(tmp_path / "one" / "seed0")
    for seed in (0, 1):
        write_run(tmp_path / "equal" / f"seed{seed}", algo="td3_delayed", seed=seed)
    text, rows = run_aggregate([tmp_path / "one", tmp_path / "equal"], tmp_path / "out")
    one = rows["Hopper-v4", "paper", "sail"]
    assert (one["last5_std"], one["ci95_low"], one["ci95_high"]) == ("n/a", "n/a", "n/a")
    equal = rows["Hopper-v4", "paper", "td3_delayed"]
    assert float(equal["last5_std"]) == 0.0
    assert float(equal["ci95_low"]) == float(equal["ci95_high"]) == pytest.approx(160 / 3)  # mean of 10, 50, 100
    assert "| sail | **53.3** † | - | n/a | 1 |" in text  # no "± std" for one seed


def test_offline_method_counts_with_zero_frames(tmp_path):
    write_run(tmp_path / "sail0")
    write_run(tmp_path / "bc0", algo="bc", evals=[(0, 120.0)], frames=0, offline=True)
    text, rows = run_aggregate([tmp_path], tmp_path / "out")
    bc = rows["Hopper-v4", "paper", "bc"]
    assert bc["offline"] == "True" and float(bc["last5_mean"]) == 120.0
    assert "| bc | **120.0** † | - | n/a | 1 | 120.0 | 120.0 | 0.80 | offline | offline |" in text
    assert "Hopper-v4 / paper / bc: fewer than 5 evaluations" in text and "seed 0: 1 (offline)" in text
    assert list(rows) == [("Hopper-v4", "paper", "sail"), ("Hopper-v4", "paper", "bc")]  # display order


def test_outputs_written_one_png_per_env_and_teacher(tmp_path):
    for seed in (0, 1):
        write_run(tmp_path / f"hop{seed}", seed=seed)
        write_run(tmp_path / f"hop_weak{seed}", seed=seed, teacher_path="/t/weak.pt", teacher_return=50.0)
        write_run(
            tmp_path / f"walk{seed}",
            seed=seed,
            env="Walker2d-v4",
            teacher_path=None,
            evals=[(1000, 1.0), (2000 + seed * 500, 2.0), (3000, 3.0)],
        )  # different eval frames
        write_run(tmp_path / f"unknown{seed}", seed=seed, algo="zzz_new")
    out = tmp_path / "out"
    text, rows = run_aggregate([tmp_path], out)
    assert (out / "results.md").read_text() == text
    pngs = sorted(path.name for path in out.glob("*.png"))
    assert pngs == ["curves_Hopper-v4_paper.png", "curves_Hopper-v4_weak.png", "curves_Walker2d-v4_shipped.png"]
    assert all((out / name).read_bytes().startswith(PNG_MAGIC) for name in pngs)
    # Teachers by return (weakest first, Table 2), unknown methods after the known ones.
    assert list(rows) == [
        ("Hopper-v4", "weak", "sail"),
        ("Hopper-v4", "paper", "sail"),
        ("Hopper-v4", "paper", "zzz_new"),
        ("Walker2d-v4", "shipped", "sail"),
    ]
    assert list(read_csv(out / "results.csv")[0]) == list(aggregate.CSV_COLUMNS)


def test_curves_align_on_common_frames(tmp_path):
    runs = [
        aggregate.load_run(write_run(tmp_path / f"s{seed}", seed=seed, evals=evals))
        for seed, evals in enumerate([[(1000, 1.0), (2000, 2.0), (3000, 3.0)], [(1000, 5.0), (3000, 7.0)]])
    ]
    frames, values = aggregate.aligned_curves(runs)
    assert frames.tolist() == [1000, 3000] and values.tolist() == [[1.0, 3.0], [5.0, 7.0]]


def test_duplicate_run_counted_once_and_config_differences_noted(tmp_path):
    write_run(tmp_path / "a" / "seed0", evals=[(3000, 100.0)])
    write_run(tmp_path / "b" / "seed0", evals=[(3000, 300.0)])
    write_run(tmp_path / "c" / "seed1", seed=1, evals=[(3000, 200.0)], optim={"precision": "bf16"})
    text, rows = run_aggregate([tmp_path], tmp_path / "out")
    assert rows["Hopper-v4", "paper", "sail"]["n_seeds"] == "2"
    assert f"`{tmp_path / 'b' / 'seed0'}`: duplicate of {tmp_path / 'a' / 'seed0'}" in text
    assert 'the configs of seed 0 lack settings the others have: optim.precision ("bf16")' in text


def test_config_differences_and_absences_are_told_apart(tmp_path):
    write_run(tmp_path / "seed0", optim={"lr": 0.001})
    write_run(tmp_path / "seed1", seed=1, optim={"lr": 0.001, "coef": 0.0, "noise": 0.1})
    write_run(tmp_path / "seed2", seed=2, optim={"lr": 0.0003, "coef": 0.0, "noise": 0.2})
    text, _ = run_aggregate([tmp_path], tmp_path / "out")
    assert "Hopper-v4 / paper / sail: the seeds differ in optim.lr (0.0003, 0.001); they are averaged together" in text
    assert (
        "Hopper-v4 / paper / sail: the configs of seed 0 lack settings the others have: "
        "optim.coef (0.0), optim.noise (0.1, 0.2); they are averaged together"
    ) in text
    assert "differ in optim.coef" not in text and "differ in optim.noise" not in text


def test_per_run_details_and_a_frame_logged_twice_counts_once(tmp_path):
    # what benchmarks/summarize_runs.py printed, now aggregate.py --per-run: each finished run's figures
    run = write_run(tmp_path / "runs" / "seed0", evals=[(1000, 10.0), (2000, 160.0), (2000, 170.0), (3000, 120.0)])
    (run / "logs" / "scalars" / "train").mkdir()
    (run / "logs" / "scalars" / "train" / "dense_return.csv").write_text("500,3.0\n1500,240.4\n")
    summary = json.loads((run / "summary.json").read_text())
    summary.update(
        alpha_switched_at_frame=1500,
        num_promoted=3,
        teacher_threshold=21.0,
        frames_per_second=52.25,
        peak_memory_mb=480.4,
    )
    (run / "summary.json").write_text(json.dumps(summary))
    write_run(tmp_path / "runs" / "unfinished", seed=1, finished=False)
    text, rows = run_aggregate([tmp_path / "runs"], tmp_path / "out", per_run=True)
    details = text.split("## Runs\n\n")[1]
    assert details.splitlines() == [
        f"### `{run}`: Hopper-v4, sail, teacher paper, seed 0, 3k frames",
        "",
        "| frames | 1k | 2k | 3k |",
        "|---|---|---|---|",
        "| eval return | 10 | 170 | 120 |",
        "",
        "- teacher return 150.0; eval first above it at 2k frames; later evals below it: 100.0% (1/1)",
        "- best eval 170, final eval 120",
        "- best training-episode mean return logged 240",
        "- alpha switched (first promotion) at 1500 frames; 3 promoted; final threshold C = 21",
        "- 52.2 frames/s (since the last start), peak RSS 480 MB",
    ]
    assert "## Runs" not in run_aggregate([tmp_path / "runs"], tmp_path / "plain")[0]  # only with per_run
    # the last row of a frame logged twice is the one counted (mean of 10, 170, 120)
    assert float(rows["Hopper-v4", "paper", "sail"]["last5_mean"]) == pytest.approx(100.0)


def test_matrix_layout_labels_runs_and_lists_missing_cells(tmp_path):
    out = tmp_path / "matrix"
    teachers = [run_matrix.Teacher("paper", tmp_path / "p.npz"), run_matrix.Teacher("shipped", None)]
    run_matrix.record_matrix(out, teachers, ["sail", "td3_delayed"], ["Hopper-v4"], [0])
    write_run(out / "paper" / "Hopper-v4" / "sail" / "seed0", teacher_path=str(tmp_path / "p.npz"))
    text, rows = run_aggregate([out], tmp_path / "report")
    assert list(rows) == [("Hopper-v4", "paper", "sail")]
    for missing in (
        out / "paper" / "Hopper-v4" / "td3_delayed" / "seed0",
        out / "shipped" / "Hopper-v4" / "sail" / "seed0",
        out / "shipped" / "Hopper-v4" / "td3_delayed" / "seed0",
    ):
        assert f"`{missing}`: missing: no run folder" in text
    # Aggregating one teacher's folder expects that teacher's runs only.
    text, _ = run_aggregate([out / "paper"], tmp_path / "report_paper")
    assert "shipped" not in text.split("## Missing")[1]
    # ... and one method's folder that method's runs only (it has them all: nothing is missing).
    write_run(
        out / "paper" / "Hopper-v4" / "td3_delayed" / "seed0", algo="td3_delayed", teacher_path=str(tmp_path / "p.npz")
    )
    text, _ = run_aggregate([out / "paper" / "Hopper-v4" / "sail"], tmp_path / "report_sail")
    assert text.split("## Missing or unfinished runs")[1].split("##")[0].strip() == "None."
    shutil.rmtree(out / "paper" / "Hopper-v4" / "td3_delayed")
    # Another env with its own teacher file (a second call): its cells only are expected.
    run_matrix.record_matrix(out, [run_matrix.Teacher("walker", tmp_path / "w.npz")], ["dac"], ["Walker2d-v4"], [1])
    run_matrix.record_matrix(out, teachers[:1], ["sail", "td3_delayed"], ["Hopper-v4"], [0])  # a rerun: no change
    assert len(json.loads((out / "matrix.json").read_text())["sweeps"]) == 3
    write_run(out / "walker" / "Walker2d-v4" / "dac" / "seed1", env="Walker2d-v4", algo="dac", seed=1)
    text, rows = run_aggregate([out], tmp_path / "report2")
    assert ("Walker2d-v4", "walker", "dac") in rows
    missing = text.split("## Missing or unfinished runs")[1]
    assert missing.count("missing: no run folder") == 3 and "walker/Hopper-v4" not in missing
    with pytest.raises(ValueError, match="already uses the teacher label 'paper'"):
        run_matrix.record_matrix(
            out, [run_matrix.Teacher("paper", tmp_path / "other.npz")], ["sail"], ["Hopper-v4"], [0]
        )


def test_hidden_folders_skipped_and_bad_inputs_named(tmp_path):
    run = write_run(tmp_path / "runs" / "seed0")
    (run / ".hydra").mkdir()
    (run.parent / ".hydra").mkdir()
    (run.parent / ".hydra" / "config.yaml").write_text("not: a run")
    assert aggregate.find_run_folders([tmp_path / "runs"]) == [run]
    with pytest.raises(FileNotFoundError, match="nowhere is not a folder"):
        aggregate.find_run_folders([tmp_path / "nowhere"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="empty holds no run folder"):
        aggregate.find_run_folders([tmp_path / "empty"])
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "config.yaml").write_text("foo: 1\n")
    with pytest.raises(ValueError, match=r"bad/config.yaml is not a sail_td3.py run config"):
        aggregate.load_run(tmp_path / "bad")


def test_run_matrix_commands_for_a_file_teacher_and_the_shipped_one(tmp_path, capsys):
    teacher_file = tmp_path / "teacher, v1.npz"  # a comma would start a Hydra sweep unless quoted
    teacher_file.touch()
    assert (
        run_matrix.main(
            [
                "--out",
                str(tmp_path / "m"),
                "--methods",
                "sail",
                "td3_delayed",
                "--envs",
                "Hopper-v4",
                "--seeds",
                "0",
                "1",
                "--teacher",
                f"paper={teacher_file}",
                "--teacher",
                "shipped",
                "--dry-run",
                "--",
                "collector.total_frames=50000",
            ]
        )
        == 0
    )
    paper, shipped = [shlex.split(line)[2:] for line in capsys.readouterr().out.splitlines()]
    assert paper[:9] == [
        "-m",
        "algo=sail,td3_delayed",
        "env=Hopper-v4",
        "seed=0,1",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        "threads=1",
        "resume=auto",
        "logger.backends=[csv]",
    ]
    assert f"hydra.sweep.dir={tmp_path / 'm' / 'paper'}" in paper
    assert "hydra.sweep.subdir=${env.name}/${algo.name}/seed${seed}" in paper  # left to Hydra
    assert f"teacher.path='{teacher_file}'" in paper  # quoted for Hydra
    assert paper[-1] == "collector.total_frames=50000"  # the user's overrides last
    assert not any(arg.startswith("teacher.path") for arg in shipped)
    assert f"hydra.sweep.dir={tmp_path / 'm' / 'shipped'}" in shipped
    assert not (tmp_path / "m").exists()  # a dry run writes nothing

    command = run_matrix.multirun_command(
        run_matrix.Teacher("shipped", None),
        out=tmp_path,
        methods=["sail"],
        envs=["Hopper-v4"],
        seeds=[0],
        launcher="submitit_slurm",
        jobs=8,
    )
    assert "hydra/launcher=submitit_slurm" in command and "hydra.launcher.array_parallelism=8" in command
    assert "hydra.launcher.n_jobs=8" not in command


def test_run_matrix_runs_each_method_with_its_familys_script(tmp_path, capsys):
    # one multirun per teacher and script, by algo.learner: the off-policy methods, gail/pofd, bc
    assert (
        run_matrix.main(
            [
                "--out",
                str(tmp_path / "m"),
                "--methods",
                "sail",
                "gail",
                "bc",
                "pofd",
                "ddpgfd",
                "--envs",
                "Hopper-v4",
                "--seeds",
                "0",
                "--teacher",
                "shipped",
                "--dry-run",
            ]
        )
        == 0
    )
    commands = [shlex.split(line) for line in capsys.readouterr().out.splitlines()]
    assert [(Path(command[1]).name, command[3]) for command in commands] == [
        ("sail_td3.py", "algo=sail,ddpgfd"),
        ("gail.py", "algo=gail,pofd"),
        ("bc.py", "algo=bc"),
    ]
    assert {command[1] for command in commands} == {
        str(run_matrix.EXAMPLES / name) for name in ("sail_td3.py", "gail.py", "bc.py")
    }
    assert run_matrix.script_for("sail_sac") == run_matrix.SCRIPT  # learner=sac: the off-policy loop too
    with pytest.raises(ValueError, match="one multirun per script"):
        run_matrix.multirun_command(
            run_matrix.Teacher("shipped", None), out=tmp_path, methods=["sail", "gail"], envs=["Hopper-v4"], seeds=[0]
        )


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--teacher", "pa/per=x.npz"], "must be a plain folder name"),
        (["--teacher", "paper=/no/such/file.npz"], "does not exist"),
        (["--teacher", "a", "--methods", "nope"], "unknown algo 'nope'"),
        (["--teacher", "a", "--teacher", "a"], "labels must differ"),
        (["--teacher", "a=README.md", "--envs", "Hopper-v4", "Walker2d-v4"], "a teacher file belongs to one env"),
    ],
)
def test_run_matrix_refuses_bad_arguments(argv, message, capsys):
    base = {"--out": ["/tmp/x"], "--methods": ["sail"], "--envs": ["Hopper-v4"], "--seeds": ["0"]}
    options = {key: value for key, value in base.items() if key not in argv}
    full = [item for key, values in options.items() for item in (key, *values)] + argv + ["--dry-run"]
    with pytest.raises(SystemExit):
        run_matrix.parse_args(full)
    assert message in capsys.readouterr().err


def test_make_teachers_commands_and_labels(tmp_path, capsys):
    assert (
        make_teachers.main(
            [
                "--env",
                "Hopper-v4",
                "--budgets",
                "30000",
                "10000",
                "--max-return",
                "1000",
                "--out",
                str(tmp_path),
                "--dry-run",
            ]
        )
        == 0
    )
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith(
        f"env=Hopper-v4 frames=10000 seed=0 threads=1 out={tmp_path}/Hopper-v4_10000 "
        f"hydra.run.dir={tmp_path}/logs/Hopper-v4_10000 max_return=1000.0"
    )
    assert lines[-1] == (
        f"run_matrix.py arguments: --teacher td3_10k={tmp_path}/Hopper-v4_10000 "
        f"--teacher td3_30k={tmp_path}/Hopper-v4_30000"
    )
    with pytest.raises(SystemExit):
        make_teachers.parse_args(["--env", "Hopper-v4", "--budgets", "1000"])
    assert "below eval_every_frames=5000" in capsys.readouterr().err


def test_runs_at_two_budgets_are_two_cells_not_duplicates(tmp_path):
    # the campaign's 300k and 1M SAIL runs: same env, teacher, method and seed, under two stage folders
    for stage, frames, evals in (("main", 300_000, [10.0] * 5), ("scale", 1_000_000, [90.0] * 5)):
        out = tmp_path / "campaign" / stage
        run_matrix.record_matrix(out, [run_matrix.Teacher("paper", tmp_path / "p.npz")], ["sail"], ["Hopper-v4"], [0])
        write_run(
            out / "paper" / "Hopper-v4" / "sail" / "seed0",
            total_frames=frames,
            frames=frames,
            evals=frames_curve(evals),
        )
    text, rows = run_aggregate([tmp_path / "campaign"], tmp_path / "report")
    assert list(rows) == [("Hopper-v4", "paper", "sail (300k)"), ("Hopper-v4", "paper", "sail (1M)")]
    assert float(rows["Hopper-v4", "paper", "sail (1M)"]["last5_mean"]) == 90.0
    assert "duplicate" not in text and "missing" not in text  # each matrix's cell is there, by its own name
    # an env run at one budget only: its run is named with its budget too, so a row holds one budget
    out = tmp_path / "campaign" / "swimmer"
    run_matrix.record_matrix(out, [run_matrix.Teacher("paper", tmp_path / "p.npz")], ["sail"], ["Swimmer-v4"], [0])
    write_run(
        out / "paper" / "Swimmer-v4" / "sail" / "seed0",
        env="Swimmer-v4",
        total_frames=300_000,
        frames=300_000,
        evals=frames_curve([20.0] * 5),
    )
    _, rows = run_aggregate([tmp_path / "campaign"], tmp_path / "report2")
    assert ("Swimmer-v4", "paper", "sail (300k)") in rows and ("Swimmer-v4", "paper", "sail") not in rows


def test_readme_section_in_the_papers_format(tmp_path):
    campaign = tmp_path / "campaign"
    teachers = [run_matrix.Teacher("paper", tmp_path / "teachers")]
    run_matrix.record_matrix(campaign, teachers, ["sail", "dac"], ["Hopper-v4", "Swimmer-v4"], [0, 1])
    for env, method, seed, value in (
        ("Hopper-v4", "sail", 0, 300.0),
        ("Hopper-v4", "sail", 1, 500.0),
        ("Hopper-v4", "dac", 0, 200.0),
        ("Swimmer-v4", "sail", 0, 100.0),
    ):
        folder = write_run(
            campaign / "paper" / env / method / f"seed{seed}",
            env=env,
            algo=method,
            seed=seed,
            evals=frames_curve([value] * 5),
            teacher_path=f"/teachers/{env}.npz",
            teacher_return=150.0,
            total_frames=5000,
            frames=5000,
            threads=1,
            eval={"episodes": 10, "every_frames": 1000},
            this_version=True,
        )
        summary = json.loads((folder / "summary.json").read_text())
        provenance = {"cpu_model": "Test CPU", "torch_threads": 1}
        resumed = (method, seed) == ("sail", 1)
        resumes = [{"frames": 3000, "changes": {"optim.lr": [1e-3, 5e-4]}}] if resumed else []
        # the resumed seed recorded its training time (2 h); the others are estimated from their speed (1 h each)
        wall = {"wall_seconds": 7200.0} if resumed else {}
        (folder / "summary.json").write_text(
            json.dumps(
                {**summary, "frames_per_second": 5000 / 3600, "provenance": provenance, "resumes": resumes, **wall}
            )
        )
    # offline BC: its one evaluation, said once in the section's first line (no note that repeats it)
    bc = write_run(
        campaign / "paper" / "Hopper-v4" / "bc" / "seed0",
        algo="bc",
        evals=[(0, 40.0)],
        teacher_path="/teachers/Hopper-v4.npz",
        offline=True,
        frames=0,
        total_frames=5000,
        eval={"episodes": 10, "every_frames": 1000},
    )
    summary = json.loads((bc / "summary.json").read_text())
    (bc / "summary.json").write_text(
        json.dumps({**summary, "provenance": {"cpu_model": "Test CPU", "torch_threads": 1}})
    )
    readme = tmp_path / "README.md"
    start, end = "<!-- aggregate:campaign-readme START -->", "<!-- aggregate:campaign-readme END -->"
    readme.write_text(f"# Project\n\n## Results\n\nBy hand.\n\n{start}\nold\n{end}\n\n## Tests\n")
    run_aggregate([campaign], tmp_path / "report", write_into=[(readme, "campaign-readme")], teacher="paper")
    text = readme.read_text()
    assert text.startswith(f"# Project\n\n## Results\n\nBy hand.\n\n{start}\n\nPer run,") and text.endswith(
        f"</details>\n\n{end}\n\n## Tests\n"
    )
    assert "old" not in text
    # Table 1's order of envs (Swimmer before Hopper); mean ± sample std over seeds; the teacher; the paper's SAIL
    assert "| method | Swimmer-v4 | Hopper-v4 |" in text
    assert "| sail | 100.0 (1 seed) | 400.0 ± 141.4 (2 seeds) |" in text
    assert "| dac | - | 200.0 (1 seed) |" in text
    assert "| teacher | 150.0 | 150.0 |" in text
    assert "| SAIL in the paper (1M frames, -v2 envs) | 309.5 ± 3.0 | 3302.1 ± 14.2 |" in text
    # budget, CPU, threads, wall time (3 runs of 5000 frames at 5000 frames per hour, one recorded 2 h), commands
    assert (
        "Budget per run: 5k frames. CPUs: Test CPU, 1 torch thread per run; wall time about 5 h in all (recorded "
        "per run; estimated for 3 runs as their frames over their frames per second)." in text
    )
    assert (
        "python examples/sail_td3.py algo=sail env=Hopper-v4 seed=<0|1> collector.total_frames=5000 threads=1 "
        "eval.episodes=10 eval.every_frames=1000 teacher.path=<teachers>/Hopper-v4.npz"
    ) in text
    figure = tmp_path / "report" / "results_paper.png"
    assert figure.read_bytes()[:8] == PNG_MAGIC and "](report/results_paper.png)" in text
    assert (
        "Per run, the mean of its last 5 deterministic evaluations (10 episodes each); offline (bc), its one "
        "evaluation after training; per cell" in text
    )
    assert "| bc | - | 40.0 (1 seed) |" in text
    # the seed continued with another learning rate: the README points to the report's notes
    assert "Notes on these runs (1: fewer evaluations, other settings): [the report](report/results.md)." in text
    for broken in ("no markers\n", f"{end}\n{start}\n", f"{start}\n{end}\n{start}\n{end}\n"):
        readme.write_text(broken)
        with pytest.raises(ValueError, match=f"must have the line {start}, then the line {end}, once each"):
            run_aggregate([campaign], tmp_path / "report2", write_into=[(readme, "campaign-readme")])
        assert readme.read_text() == broken  # nothing written
        assert not (tmp_path / "report2").exists()  # refused before any work
    with pytest.raises(ValueError, match="no generated block named nonesuch; the blocks: campaign-readme, campaign,"):
        run_aggregate([campaign], tmp_path / "report2", write_into=[(readme, "nonesuch")])


def test_variants_set_beside_their_base_of_the_same_env_method_and_budget(tmp_path):
    # the campaign's stages: the defaults under "paper", one setting changed under "paper-<variant>"
    root = tmp_path / "campaign"
    cells = (
        ("main", "paper", 300_000, [[100.0] * 5, [200.0] * 5]),  # base: 150.0 ± 70.7 over 2 seeds
        ("scale", "paper", 1_000_000, [[500.0] * 5]),  # "sail (1M)": the base of no 300k variant
        ("buffer", "paper-fifo", 300_000, [[40.0] * 4 + [90.0], [60.0] * 5]),  # 50.0 and 60.0: 55.0 ± 7.1
        ("precision", "paper-bf16", 100_000, [[75.0] * 5]),  # no base at 100k
        ("other", "my-teacher", 300_000, [[10.0] * 5]),  # "my" is no label: not a variant
    )
    for stage, label, frames, curves in cells:
        out = root / stage
        run_matrix.record_matrix(out, [run_matrix.Teacher(label, tmp_path / "p.npz")], ["sail"], ["Hopper-v4"], [0, 1])
        for seed, evals in enumerate(curves):
            write_run(
                out / label / "Hopper-v4" / "sail" / f"seed{seed}",
                seed=seed,
                total_frames=frames,
                frames=frames,
                evals=frames_curve(evals),
            )
    text, _ = run_aggregate([root], tmp_path / "report")
    section = text.split("## Variants beside their base")[1].split("## Missing")[0]
    table = [line for line in section.splitlines() if line.startswith("| Hopper")]
    assert table == [
        "| Hopper-v4 | paper (150.0) | sail | bf16 | 75.0 (1 seed) | 0.50 | n/a | - | - | - | - |",
        # base seed 1 passes 150 at its first eval (200), then stays above for its 4 others; Welch's t-test of
        # [50, 60] against [100, 200]: t = -95 / sqrt(50 / 2 + 5000 / 2) = -1.89, 1.02 degrees of freedom, p = 0.31
        "| Hopper-v4 | paper (150.0) | sail | fifo | 55.0 ± 7.1 (2 seeds) | 0.37 | n/a | 150.0 ± 70.7 (2 seeds) "
        "| 1.00 | 0.0% (0/4) | 0.31 |",
    ]
    assert "my-teacher" not in section
    # without a variant label the section is left out
    text, _ = run_aggregate([root / "main"], tmp_path / "report_main")
    assert "Variants" not in text


def update_summary(folder: Path, **items) -> None:
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, **items}))


def test_fall_share_is_pooled_over_the_seeds_that_passed(tmp_path):
    # teacher 100: falls are the evals below it after the first one above it (that one excluded)
    cells = (
        ("sail", 0, [50, 120, 90, 110, 80, 130, 100]),  # passes at 120; then 90 and 80 below (100 is not): 2/5
        ("sail", 1, [101, 99, 150, 50, 120]),  # passes at 101; then 99 and 50 below: 2/4
        ("sail", 2, [10, 100, 90, 99, 100]),  # never above 100 (equal is not): left out of the pool
        ("td3_delayed", 0, [10, 20, 30]),  # no seed passed: n/a
        ("dac", 0, [10, 20, 200]),  # passed at its last eval: none after, 0/0
    )
    for method, seed, curve in cells:
        write_run(
            tmp_path / method / f"seed{seed}",
            algo=method,
            seed=seed,
            evals=frames_curve(curve),
            teacher_return=100.0,
            total_frames=3000,
            frames=7000,
        )
    run = aggregate.load_run(tmp_path / "sail" / "seed0")
    assert run.fall_share == {"share": 0.4, "falls": 2, "evaluations": 5}
    assert aggregate.load_run(tmp_path / "sail" / "seed2").fall_share is None
    text, rows = run_aggregate([tmp_path], tmp_path / "out", per_run=True)
    sail = rows["Hopper-v4", "paper", "sail"]
    # pooled 4/9, not the mean of the seeds' shares (0.4 + 0.5) / 2 = 0.45
    assert float(sail["fall_share"]) == pytest.approx(4 / 9)
    assert (sail["falls"], sail["fall_evaluations"]) == ("4", "9")
    td3 = rows["Hopper-v4", "paper", "td3_delayed"]
    assert (td3["fall_share"], td3["falls"], td3["fall_evaluations"]) == ("n/a", "n/a", "n/a")
    dac = rows["Hopper-v4", "paper", "dac"]
    assert (dac["fall_share"], dac["falls"], dac["fall_evaluations"]) == ("n/a", "0", "0")
    table = {line.split(" | ")[2]: line for line in text.split("\n\n")[1].splitlines()[2:]}
    assert table["sail"].endswith("| 1500 (2/3 seeds passed) | 44.4% (4/9) |")  # passed at 2000 and 1000
    assert table["td3_delayed"].endswith("| n/a (0/1 seeds passed) | n/a |")
    assert table["dac"].endswith("| 3000 (1/1 seeds passed) | n/a (0/0) |")
    assert "| frames to pass teacher | fall share |" in text
    details = text.split("## Runs\n\n")[1]
    assert "- teacher return 100.0; eval first above it at 2k frames; later evals below it: 40.0% (2/5)" in details
    assert "- teacher return 100.0; no eval above it within 7k frames\n" in details  # sail seed 2


def test_best_evaluated_policy_over_the_seeds_that_kept_it(tmp_path):
    """The best evaluated policy's 50-episode figures (CSV columns and each run's details), over the
    seeds whose summary has one."""
    for seed, value in ((0, 320.0), (1, 180.0), (2, None)):
        folder = write_run(tmp_path / "sail" / f"seed{seed}", seed=seed, evals=frames_curve([100.0] * 5))
        if value is not None:  # seed 2: a run from before best_evaluated_policy
            record = {"frames": 30_000, "periodic_eval_return": 410.0, "eval_return": value, "episodes": 50}
            update_summary(folder, best_evaluated_policy=record)
    text, rows = run_aggregate([tmp_path], tmp_path / "out", per_run=True)
    sail = rows["Hopper-v4", "paper", "sail"]
    assert float(sail["best_evaluated_mean"]) == pytest.approx(250.0)
    assert float(sail["best_evaluated_std"]) == pytest.approx(98.994949)  # ddof=1 of 320, 180: 70 * sqrt(2)
    assert sail["best_evaluated_n"] == "2" and sail["n_seeds"] == "3"
    details = text.split("## Runs\n\n")[1]
    assert (
        "- best evaluated policy (kept at 30000 frames, evaluated 410 then): eval 320 over 50 other episodes" in details
    )
    assert details.count("- best evaluated policy") == 2


def test_best_policy_mean_and_std_over_the_seeds_that_evaluated_it(tmp_path):
    def best_policy(value: float | None) -> dict:
        record = {"frames": 2000, "train_return_mean": 280.0, "window": 100}
        if value is None:  # kept, not evaluated (eval.best_policy.episodes=0)
            return record
        return {**record, "eval_return": value, "actor": "online", "episodes": 50, "seed": 20_000}

    for seed, value in ((0, 300.0), (1, 500.0), (2, "no key"), (3, None)):
        folder = write_run(tmp_path / "sail" / f"seed{seed}", seed=seed, evals=frames_curve([100.0] * 5))
        if value != "no key":  # seed 2: a run from before best_policy
            update_summary(folder, best_policy=best_policy(value))
    folder = write_run(tmp_path / "td3" / "seed0", algo="td3_delayed", evals=frames_curve([50.0] * 5))
    update_summary(folder, best_policy=best_policy(250.0))
    write_run(tmp_path / "dac" / "seed0", algo="dac", evals=frames_curve([50.0] * 5))  # no seed has one
    text, rows = run_aggregate([tmp_path], tmp_path / "out", per_run=True)
    sail = rows["Hopper-v4", "paper", "sail"]
    assert float(sail["best_policy_mean"]) == pytest.approx(400.0)
    assert float(sail["best_policy_std"]) == pytest.approx(141.42136)  # ddof=1 of 300, 500: 100 * sqrt(2)
    assert sail["best_policy_n"] == "2" and sail["n_seeds"] == "4"
    td3 = rows["Hopper-v4", "paper", "td3_delayed"]
    assert (float(td3["best_policy_mean"]), td3["best_policy_std"], td3["best_policy_n"]) == (250.0, "n/a", "1")
    dac = rows["Hopper-v4", "paper", "dac"]
    assert (dac["best_policy_mean"], dac["best_policy_std"], dac["best_policy_n"]) == ("n/a", "n/a", "0")
    assert "| method | last-5 mean ± std | best policy | 95% CI |" in text
    assert "| sail | **100.0** ± 0.0 | 400.0 ± 141.4 (2/4 seeds) | [100.0, 100.0] | 4 |" in text
    assert "| td3_delayed | 50.0 | 250.0 | n/a | 1 |" in text
    assert "| dac | 50.0 | - | n/a | 1 |" in text
    assert (
        "- Hopper-v4 / paper / sail: the best policy averages 2 of 4 seeds; seeds 2, 3 did not evaluate one "
        "(runs before best_policy, or eval.best_policy.episodes=0)"
    ) in text
    assert "td3_delayed: the best policy" not in text and "dac: the best policy" not in text
    details = text.split("## Runs\n\n")[1]
    assert details.count("- best policy (kept at 2000 frames, training-return mean 280): eval ") == 3
    assert "eval 500 over 50 episodes" in details


def test_paper_comparison_lays_out_table1_figure2_and_figures34(tmp_path, monkeypatch):
    """SAIL at two budgets and its variants beside the paper's Table 1 rows; the baselines and the
    ablations in their own tables, on the envs where they ran."""
    root = tmp_path / "comparison"
    for env, method, seed, frames, value in (
        ("Hopper-v4", "sail", 0, 1_000_000, 3000.0),
        ("Hopper-v4", "sail", 1, 1_000_000, 3400.0),
        ("Hopper-v4", "sail", 0, 300_000, 2000.0),
        ("Swimmer-v4", "sail", 0, 1_000_000, 300.0),
        ("Hopper-v4", "sail_rnd", 0, 300_000, 1500.0),
        ("Hopper-v4", "dac", 0, 300_000, 1000.0),
        ("Hopper-v4", "dac_published", 0, 300_000, 1100.0),
        ("Hopper-v4", "sail_onpolicy", 0, 300_000, 900.0),
    ):
        write_run(
            root / "stage" / "paper" / env / method / f"seed{seed}-{frames}",
            env=env,
            algo=method,
            seed=seed,
            evals=frames_curve([value] * 5),
            teacher_return=1500.0 if env == "Hopper-v4" else 120.0,
            total_frames=frames,
            frames=frames,
        )
    source = aggregate.Source([root], tmp_path / "out")
    text = aggregate.block_paper_comparison(source, tmp_path / "results.md")
    table1, figure2, figure34 = text.split("\n\n**")[0], text.split("**Figure 2")[1], text.split("**Figures 3")[1]
    assert "| | Swimmer | Hopper |" in table1  # Table 1's column order: HalfCheetah, Swimmer, Hopper, Walker2d
    assert "| SAIL (`sail`), 1M frames | 300.0 (1 seed) | 3200.0 ± 282.8 (2 seeds) |" in table1
    assert "| SAIL (`sail`), 300k frames | - | 2000.0 (1 seed) |" in table1
    assert table1.index("1M frames |") < table1.index("300k frames |")
    assert "| SAIL in the paper, 1M frames | 309.5 ± 3.0 | 3302.1 ± 14.2 |" in table1
    assert "| Curiosity Exploration (`sail_rnd`), 300k frames | - | 1500.0 (1 seed) |" in table1
    assert "| Curiosity Exploration in the paper, 1M frames | 30.9 ± 6.5 | 3075.5 ± 15.6 |" in table1
    assert "| Entropy Exploration in the paper, 1M frames | 65.0 ± 7.7 | 3079.3 ± 53.3 |" in table1
    assert "| teacher | 120.0 | 1500.0 |" in table1 and "| teacher in the paper | 121.16 | 1480.69 |" in table1
    # the baselines and ablations where they ran (Hopper only), SAIL beside them, no paper rows
    assert "| | Hopper |\n" in figure2 and "| `dac`, 300k frames | 1000.0 (1 seed) |" in figure2
    # both DACs, the SAIL authors' then Kostrikov et al.'s release
    assert "| `dac`, 300k frames | 1000.0 (1 seed) |\n| `dac_published`, 300k frames | 1100.0 (1 seed) |" in figure2
    assert "| `sail`, 1M frames | 3200.0 ± 282.8 (2 seeds) |" in figure2 and "paper," not in figure2
    assert "| `sail_onpolicy`, 300k frames | 900.0 (1 seed) |" in figure34
    assert "gail" not in text  # no run, no row
    # each figure's curves linked under its table, drawn from the runs of its methods only
    assert "![Figure 2's methods](out/paper_figure2_paper.png)" in figure2
    assert "![Figures 3 and 4's variants of SAIL](out/paper_figures34_paper.png)" in figure34
    # a page of the docs site cannot link outside docs/: there, the figure's path in the repository
    report = aggregate.REPO / "benchmarks" / "results" / "campaign" / "report" / "paper_figure2_paper.png"
    assert aggregate.figure_in(aggregate.REPO / "docs" / "results.md", "curves", report) == (
        "curves: `benchmarks/results/campaign/report/paper_figure2_paper.png`."
    )
    assert aggregate.figure_in(aggregate.REPO / "README.md", "curves", report) == (
        "![curves](benchmarks/results/campaign/report/paper_figure2_paper.png)"
    )
    drawn, draw_groups = {}, aggregate.draw_groups

    def recorded(ax, groups, colour_of):
        drawn.setdefault(ax.get_figure(), []).append(sorted(group.method for group in groups))
        draw_groups(ax, groups, colour_of)

    monkeypatch.setattr(aggregate, "draw_groups", recorded)
    aggregate.draw_paper_comparison(source)
    assert sorted(p.name for p in (tmp_path / "out").glob("paper_*.png")) == [
        "paper_figure2_paper.png",
        "paper_figures34_paper.png",
    ]
    panels = sorted(drawn.values())  # one figure each, one Hopper panel each
    assert panels == [
        [["dac", "dac_published", "sail (1M)", "sail (300k)"]],
        [["sail (1M)", "sail (300k)", "sail_onpolicy"]],
    ], panels


def standing_run(env, method, seed, last5, passed=True, frames=300_000):
    """A finished run of the paper's teacher (return 100): five evaluations at ``last5`` (at
    ``min(last5, 90)``, below the teacher, if not ``passed``)."""
    values = [last5] * 5 if passed else [min(last5, 90.0)] * 5
    return aggregate.Run(
        folder=Path(f"/runs/{env}/{method}/seed{seed}"),
        env=env,
        method=method,
        seed=seed,
        teacher="paper",
        config={"collector": {"total_frames": frames}},
        summary={"teacher_return": 100.0},
        curve=[(10_000 * (i + 1), value) for i, value in enumerate(values)],
    )


def test_standing_says_who_passed_and_who_ends_above_from_the_runs():
    runs = [
        # Hopper: sail 300, 500 above dac 200, 250; Walker2d: they overlap (sail 150, 400; dac 300);
        # Swimmer: dac 400 above sail 200; HalfCheetah: sail 1 of 2 passed, dac none of 2, sail's 120 and 90
        # above dac's 80 and 80; Ant: sail alone, not compared
        *(standing_run("Hopper-v4", "sail", s, v) for s, v in ((0, 300.0), (1, 500.0))),
        *(standing_run("Hopper-v4", "dac", s, v) for s, v in ((0, 200.0), (1, 250.0))),
        *(standing_run("Walker2d-v4", "sail", s, v) for s, v in ((0, 150.0), (1, 400.0))),
        standing_run("Walker2d-v4", "dac", 0, 300.0),
        standing_run("Swimmer-v4", "sail", 0, 200.0),
        standing_run("Swimmer-v4", "dac", 0, 400.0),
        standing_run("HalfCheetah-v4", "sail", 0, 120.0),
        standing_run("HalfCheetah-v4", "sail", 1, 90.0, passed=False),
        *(standing_run("HalfCheetah-v4", "dac", s, 80.0, passed=False) for s in (0, 1)),
        standing_run("Ant-v4", "sail", 0, 500.0),
    ]
    envs = ["HalfCheetah-v4", "Swimmer-v4", "Hopper-v4", "Walker2d-v4", "Ant-v4"]
    # a 1M-frame sail run on Hopper below every dac seed: another budget (its label `sail (1M)`), not compared
    budgets = [standing_run("Hopper-v4", "sail", 0, 10.0, passed=False, frames=1_000_000)]
    aggregate.label_budgets(runs + budgets)
    groups, _ = aggregate.group_runs(runs + budgets)
    assert ("Hopper-v4", "paper", "sail (1M)") in groups and ("Hopper-v4", "paper", "sail (300k)") in groups
    assert aggregate.standing(groups, "paper", envs) == [
        "At 300k frames, `sail` passes its teacher on every seed on Swimmer-v4, Hopper-v4 and Walker2d-v4, and "
        "on 1 of 2 seeds on HalfCheetah-v4; `dac` passes its teacher on every seed on Swimmer-v4, Hopper-v4 and "
        "Walker2d-v4, and on none of 2 seeds on HalfCheetah-v4. By last-5, every `sail` seed ends above every "
        "`dac` seed on HalfCheetah-v4 and Hopper-v4; every `dac` seed ends above every `sail` seed on "
        "Swimmer-v4; their seeds overlap on Walker2d-v4.",
        "",
    ]
    # runs of another budget or teacher say nothing
    assert aggregate.standing(groups, "shipped", envs) == []


def test_shipped_teachers_block_in_table1_order_beside_the_papers_v4_teachers(tmp_path):
    for env, ret, steps, frames in (
        ("Swimmer-v5", 41.94, 1000, 30000),
        ("Hopper-v4", 463.604, 165, 65000),
        ("Ant-v4", 900.04, 1000, 50000),
        ("HalfCheetah-v4", 1009.26, 1000, 25000),
    ):
        (tmp_path / env).mkdir()
        meta = {"env_id": env, "episode_returns": [ret], "episode_lengths": [steps], "td3_frames": frames}
        (tmp_path / env / "metadata.json").write_text(json.dumps(meta))
    block = aggregate.block_shipped_teachers(aggregate.Source([tmp_path], tmp_path / "report"), tmp_path / "x.md")
    assert block.splitlines()[2:] == [
        "| HalfCheetah-v4 | 1009.3 | 1000 | 25k | 5646.7 |",
        "| Swimmer-v5 | 41.9 | 1000 | 30k | - |",  # the paper's teachers are run on v4
        "| Hopper-v4 | 463.6 | 165 | 65k | 1480.7 |",
        "| Ant-v4 | 900.0 | 1000 | 50k | - |",  # not one of Table 1's envs: last
    ]


def test_readme_shows_the_default_label_as_sail_the_replaced_default_and_their_settings(tmp_path):
    """With the default SAIL's runs under a label of their own (the campaign's TABLE1_LABEL), the README's
    ``sail`` rows are theirs; on each env where they ran, the teacher's own SAIL runs become the replaced
    default's rows, elsewhere they stay ``sail``'s; SAIL and DAC rows carry their best policy and fall
    share; each command holds the settings that differ from what its method composes now."""
    root = tmp_path / "campaign"
    own = {"network": {"actor_cells": [64, 64]}}  # a setting of the default's runs alone
    cells = (  # teacher 150: stage, label, env, method, seed, evals, best policy, settings
        ("main", "paper", "Hopper-v4", "sail", 0, [100.0, 200.0, 100.0, 200.0, 200.0], None, {}),  # 1 fall in 3
        ("main", "paper", "Hopper-v4", "dac", 0, [100.0] * 5, None, {}),  # never passes
        ("main", "paper", "Swimmer-v4", "sail", 0, [300.0] * 5, None, {}),  # no default run on Swimmer
        ("trusted", "paper-trusted", "Hopper-v4", "sail", 0, [200.0] * 5, 300.0, own),
        ("trusted", "paper-trusted", "Hopper-v4", "sail", 1, [160.0, 170.0, 100.0, 180.0, 190.0], 500.0, own),
    )
    for stage, label, env, method, seed, evals, best, settings in cells:
        out = root / stage
        run_matrix.record_matrix(out, [run_matrix.Teacher(label, tmp_path / "p.npz")], [method], [env], [seed])
        folder = write_run(
            out / label / env / method / f"seed{seed}",
            env=env,
            algo=method,
            seed=seed,
            evals=frames_curve(evals),
            total_frames=5000,
            frames=5000,
            threads=1,
            eval={"episodes": 10, "every_frames": 1000},
            this_version=True,
            **settings,
        )
        if best is not None:
            update_summary(folder, best_policy={"eval_return": best, "episodes": 50})
    readme = tmp_path / "README.md"
    start, end = "<!-- aggregate:campaign-readme START -->", "<!-- aggregate:campaign-readme END -->"
    readme.write_text(f"{start}\n{end}\n")
    run_aggregate([root], tmp_path / "report", write_into=[(readme, "campaign-readme")], default_label="paper-trusted")
    text = readme.read_text()
    table = [line for line in text.splitlines() if line.startswith("| ")]
    assert table == [
        "| method | Swimmer-v4 | Hopper-v4 |",
        # 200 and (160 + 170 + 100 + 180 + 190) / 5 = 160: std 40 / sqrt(2); Swimmer's own SAIL run stays sail's
        "| sail (5k) | 300.0 (1 seed) | 180.0 ± 28.3 (2 seeds) |",
        "| sail (5k): best policy | - | 400.0 ± 141.4 |",
        # seed 0 passes at its first eval, 0 falls of 4; seed 1 too, 1 of 4
        "| sail (5k): fall share | 0.0% (0/4) | 12.5% (1/8) |",
        "| sail, replaced default (5k) | - | 160.0 (1 seed) |",
        # passes at its 2nd eval; no best policy, no row
        "| sail, replaced default (5k): fall share | - | 33.3% (1/3) |",
        "| dac | - | 100.0 (1 seed) |",  # never passed: no fall share on any env, no row
        "| teacher | 150.0 | 150.0 |",
        "| SAIL in the paper (1M frames, -v2 envs) | 309.5 ± 3.0 | 3302.1 ± 14.2 |",
    ]
    assert "`sail, replaced default`: SAIL with the defaults that the trusted default replaced" in text
    assert (  # what the rows under SAIL and DAC are, said once
        "Rows `<method>: best policy`, the policy each run kept by the SAIL authors' rule (the best mean return of "
        "its last 100 training episodes), evaluated on 50 episodes, mean ± std over the seeds that kept one; "
        "`<method>: fall share`, of the evaluations after a run first passed its teacher, those below the "
        "teacher's return, pooled over seeds."
    ) in text
    commands = [line for line in text.splitlines() if line.startswith("python ")]
    common = "collector.total_frames=5000 threads=1 eval.episodes=10 eval.every_frames=1000"
    assert commands == [
        f"python examples/sail_td3.py algo=sail env=Swimmer-v4 seed=0 {common} teacher.path=<teachers>/paper.npz",
        f"python examples/sail_td3.py algo=sail env=Hopper-v4 seed=<0|1> {common} network.actor_cells=[64,64] "
        "teacher.path=<teachers>/paper.npz",
        f"python examples/sail_td3.py algo=sail env=Hopper-v4 seed=0 {common} teacher.path=<teachers>/paper.npz",
        f"python examples/sail_td3.py algo=dac env=Hopper-v4 seed=0 {common} teacher.path=<teachers>/paper.npz",
    ]
    # the seed-by-seed comparison with DAC takes the default's runs too
    docs = tmp_path / "results.md"
    docs.write_text("<!-- aggregate:campaign-sail-vs-dac START -->\n<!-- aggregate:campaign-sail-vs-dac END -->\n")
    run_aggregate(
        [root], tmp_path / "report", write_into=[(docs, "campaign-sail-vs-dac")], default_label="paper-trusted"
    )
    assert "| Hopper-v4 | paper (150.0) | 200.0 (0), 160.0 (1) | 100.0 (0) | 2/2 | 0/1 |" in docs.read_text()
    # so does the paper's table in the docs; the teachers' table names the replaced default's rows so, on
    # the envs where the default has runs of its own label, and leaves the default's runs to the variants'
    docs.write_text(
        "<!-- aggregate:campaign START -->\n<!-- aggregate:campaign END -->\n"
        "<!-- aggregate:campaign-teachers START -->\n<!-- aggregate:campaign-teachers END -->\n"
    )
    run_aggregate(
        [root],
        tmp_path / "report",
        write_into=[(docs, "campaign"), (docs, "campaign-teachers")],
        default_label="paper-trusted",
    )
    paper_table, teachers_table = (
        [line.split(" | ")[2] for line in block.splitlines() if line.startswith("| Hopper-v4")]
        for block in docs.read_text().split("<!-- aggregate:campaign-teachers START -->")
    )
    assert paper_table == ["sail (5k)", "sail, replaced default (5k)", "dac"]
    assert teachers_table == ["sail, replaced default"]
    swimmer = [line.split(" | ")[2] for line in docs.read_text().splitlines() if line.startswith("| Swimmer-v4")]
    assert swimmer == ["sail (5k)", "sail"]  # no default run on Swimmer: its SAIL run stays sail's, in both tables
    # without a default label of its own, the teacher's SAIL runs are sail's, as before
    run_aggregate([root / "main"], tmp_path / "report_main", write_into=[(readme, "campaign-readme")])
    text = readme.read_text()
    rows_ = [line for line in text.splitlines() if line.startswith("| sail")]
    assert rows_ == ["| sail | 300.0 (1 seed) | 160.0 (1 seed) |", "| sail: fall share | 0.0% (0/4) | 33.3% (1/3) |"]
    assert "Rows `<method>: fall share`, of the evaluations" in text and "best policy`" not in text


def test_changed_settings_are_the_overrides_from_what_the_method_composes_now():
    def run(method: str, **config) -> aggregate.Run:
        config = saved_by_this_version({"env": {"name": "Hopper-v4"}, "algo": {"name": method}, "seed": 3, **config})
        return aggregate.Run(Path("r"), "Hopper-v4", method, 3, "paper", config, None, [])

    changed = run(
        "sail",
        optim={"lr": 0.001, "tau": 0.01},  # lr is the default, tau not
        network={"actor_cells": [64, 64]},
        eval={"other_actor": True, "episodes": 3},  # episodes: the command shows it anyway
        algo={"name": "sail", "sac": {"alpha_init": 1.0}, "per": None},  # SAC's section: not read by TD3
        checkpoint={"every_frames": 7},  # operational
        logger={"backends": ["csv"]},
        threads=1,
        resume="auto",
        teacher={"path": "/x.npz", "eviction": "fifo"},
        env={"name": "Hopper-v4", "kwargs": {"ctrl_cost_weight": 5.0}},  # an open mapping: whole
        no_longer_a_setting=None,
    )
    assert aggregate.changed_settings(changed) == [
        "env.kwargs={ctrl_cost_weight:5.0}",
        "eval.other_actor=true",
        "network.actor_cells=[64,64]",
        "optim.tau=0.01",
        "teacher.eviction=fifo",
    ]
    # a section switched off where the method has it on, and a learner's own section
    ddpgfd = run("ddpgfd", algo={"name": "ddpgfd", "per": None})
    assert aggregate.changed_settings(ddpgfd) == ["algo.per=null"]
    assert aggregate.changed_settings(run("sail_sac", algo={"name": "sail_sac", "sac": {"alpha_init": 1.0}})) == [
        "algo.sac.alpha_init=1.0"  # SAIL-SAC's own section: the authors' 0.01 is its default
    ]
    # settings a run's version did not have count at the value it ran with (config_schema.SAVED_BEFORE):
    # a dac_published run from before the release's loop and inits, evaluating one episode after another
    old = run("dac_published", algo={"name": "dac_published"})
    old.config = {"env": {"name": "Hopper-v4"}, "algo": {"name": "dac_published"}, "seed": 3}
    assert aggregate.changed_settings(old) == [
        "collector.random_until_actor=false",
        "eval.vectorized=false",
        "network.actor_critic_init=torch",
        "network.discriminator_init=xavier",
        "optim.block_order=td3_first",
        "optim.cadence=frames",
        "optim.start_frames=null",
    ]
    # an RND run from before algo.rnd.activation: its networks were tanh (TorchRL MLP's default)
    rnd = run("sail_rnd", algo={"name": "sail_rnd"})
    rnd.config = {"env": {"name": "Hopper-v4"}, "algo": {"name": "sail_rnd", "rnd": {"coef": 1.0}}}
    assert "algo.rnd.activation=tanh" in aggregate.changed_settings(rnd)
    rnd.config["algo"]["rnd"]["activation"] = "relu"
    # the bonus weight it ran with, 1, is no longer the method's (0.01)
    assert [s for s in aggregate.changed_settings(rnd) if s.startswith("algo.rnd")] == ["algo.rnd.coef=1.0"]
    unknown_env = run("sail", optim={"lr": 0.5})
    unknown_env.env = "NoSuchEnv-v0"
    assert aggregate.changed_settings(unknown_env) == []  # nothing to compare with


def test_override_values_as_hydra_parses_them_and_the_default_label_option():
    assert [aggregate.override_value(v) for v in (True, None, 0.001, [64, 64], {"a": 1.0}, "fifo", "a b,c")] == [
        "true",
        "null",
        "0.001",
        "[64,64]",
        "{a:1.0}",
        "fifo",
        "'a b,c'",  # quoted: a comma or space would split the override
    ]
    args = aggregate.parse_args(["runs", "--out", "report", "--default-label", "paper-trusted"])
    assert args.default_label == "paper-trusted" and aggregate.parse_args(["runs", "--out", "r"]).default_label is None
