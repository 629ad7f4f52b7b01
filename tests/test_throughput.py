"""Pure helpers of ``benchmarks/throughput.py``: aggregation, summary parsing, CLI checks (no training)."""

from __future__ import annotations

import json
import shlex
import sys

import pytest
from benchmark_scripts import load_benchmark

throughput = load_benchmark("throughput")


def rec(trainer, threads, fps, rnd=0, **extra):
    return {
        "trainer": trainer,
        "threads": threads,
        "round": rnd,
        "fps": fps,
        "ms_update": 10.0,
        "ms_frame": 1.0,
        "peak_mb": 500.0,
        "gradient_steps": 5000,
        **extra,
    }


def test_aggregate_medians_and_ratios_per_thread_count():
    records = [
        rec("sail", 1, 40.0, 0),
        rec("sb3", 1, 100.0, 0),
        rec("sail", 2, 30.0, 0),
        rec("sb3", 2, 60.0, 0),
        rec("sail", 1, 60.0, 1),
        rec("sb3", 1, 100.0, 1),
        rec("sail", 2, 30.0, 1),
        rec("sb3", 2, 60.0, 1),
        rec("sail", 1, 20.0, 2),
        rec("sb3", 1, 100.0, 2),
        rec("sail", 2, 30.0, 2),
        rec("sb3", 2, 60.0, 2),
    ]
    rows = {(r["trainer"], r["threads"]): r for r in throughput.aggregate(records)}
    assert list(rows) == [("sail", 1), ("sb3", 1), ("sail", 2), ("sb3", 2)]  # first-seen order
    assert rows["sail", 1]["fps"] == 40.0 and rows["sail", 1]["runs"] == 3  # median of 40, 60, 20
    assert rows["sail", 1]["fps_vs_sb3"] == pytest.approx(0.4)
    assert rows["sail", 2]["fps_vs_sb3"] == pytest.approx(0.5)
    assert rows["sb3", 1]["fps_vs_sb3"] == pytest.approx(1.0)
    assert rows["sail", 1]["ms_update"] == 10.0 and rows["sail", 1]["failed"] == 0


def test_aggregate_skips_missing_values_and_missing_sb3():
    records = [
        rec("sail", 1, None, 0, ms_update=None),
        rec("sail", 1, 50.0, 1, ms_update=None),
        {"trainer": "td3", "threads": 1, "round": 0, "error": "exit 1: boom"},
    ]
    rows = {r["trainer"]: r for r in throughput.aggregate(records)}
    assert rows["sail"]["fps"] == 50.0 and rows["sail"]["ms_update"] is None
    assert rows["sail"]["fps_vs_sb3"] is None  # no sb3 run at this thread count
    assert rows["td3"]["failed"] == 1 and rows["td3"]["fps"] is None and rows["td3"]["fps_vs_sb3"] is None
    table = throughput.markdown(list(rows.values()))
    assert "| td3 | 1 | - | - | - | - | - | - |" in table
    assert "| sail | 1 | 50.0 | - |" in table


def test_record_from_summary_full_and_partial():
    full = {
        "train_frames": 5000,
        "train_seconds": 100.0,
        "train_frames_per_second": 50.0,
        "time_seconds": {"collect": 10.0, "update": 80.0, "sample": 5.0},
        "counts": {"gradient_steps": 5000, "discriminator_steps": 200, "frames": 5000},
        "peak_memory_mb": 900.0,
    }
    assert throughput.record_from_summary(full) == {
        "fps": 50.0,
        "ms_update": pytest.approx(16.0),
        "ms_frame": pytest.approx(2.0),
        "peak_mb": 900.0,
        "gradient_steps": 5000,
    }
    partial = throughput.record_from_summary(
        {"train_frames": 5000, "train_seconds": 50.0, "time_seconds": {"update": 1.0}, "counts": {"gradient_steps": 0}}
    )
    assert partial == {"fps": 100.0, "ms_update": None, "ms_frame": None, "peak_mb": None, "gradient_steps": 0}
    # without counts["gradient_steps"], the call count of the timed "update" phase
    by_phase = throughput.record_from_summary({"time_seconds": {"update": 2.0}, "counts": {"update": 100}})
    assert by_phase["ms_update"] == pytest.approx(20.0) and by_phase["gradient_steps"] == 100
    assert throughput.record_from_summary({}) == dict.fromkeys(
        ["fps", "ms_update", "ms_frame", "peak_mb", "gradient_steps"]
    )


@pytest.mark.parametrize("frames", ["1500", "0", "-1000"])
def test_cli_rejects_frames_not_a_multiple_of_1000(frames, capsys):
    with pytest.raises(SystemExit):
        throughput.parse_args(["--frames", frames])
    assert "--frames" in capsys.readouterr().err


def test_cli_defaults_and_commands(tmp_path):
    args = throughput.parse_args(["--threads", "2", "--sail-overrides", "teacher.k=5 optim.lr=3e-4"])
    assert (args.env, args.warmup, args.frames, args.rounds, args.trainers) == (
        "Hopper-v4",
        2000,
        5000,
        2,
        ["sail", "td3", "sb3"],
    )
    with pytest.raises(SystemExit):
        throughput.parse_args(["--warmup", "1500"])
    sail = throughput.example_command(args, "sail", 2, tmp_path)
    td3 = throughput.example_command(args, "td3", 2, tmp_path)
    assert "collector.total_frames=7000" in sail and "threads=2" in sail and f"hydra.run.dir={tmp_path}" in sail
    assert sail[-2:] == ["teacher.k=5", "optim.lr=3e-4"] and "algo=td3_delayed" not in sail
    assert set(td3) - set(sail) == {"algo=td3_delayed"}
    assert throughput.sb3_command(args, 2)[2:6] == ["--worker", "sb3", "--threads", "2"]
    # the whole-process method's second run: 2 x --frames after the same warm-up
    assert "collector.total_frames=12000" in throughput.example_command(args, "sail", 2, tmp_path, frames=10000)
    sb3 = throughput.sb3_command(args, 2, frames=10000)
    assert sb3[sb3.index("--frames") + 1] == "10000" and sb3[-2:] == ["--device", "cpu"]
    assert "device=cpu" in sail
    cuda = throughput.parse_args(["--device", "cuda"])
    assert throughput.sb3_command(cuda, 1)[-2:] == ["--device", "cuda"]
    assert throughput.example_command(cuda, "sail", 1, tmp_path)[-1] == "device=cuda"


def test_missing_sb3_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # makes the import fail
    with pytest.raises(SystemExit, match=r'pip install -e "\.\[bench\]"'):
        throughput.require_sb3()


def test_phases_ms_per_frame_from_a_synthetic_summary():
    summary = {
        "time_seconds": {"collect": 2.0, "update": 8.0, "sample": 0.5},
        "counts": {"frames": 1000, "update": 1000},
    }
    assert throughput.phases_ms_per_frame(summary) == pytest.approx({"collect": 2.0, "update": 8.0, "sample": 0.5})
    assert throughput.phases_ms_per_frame({"time_seconds": {"collect": 1.0}, "counts": {"frames": 0}}) == {}
    assert throughput.phases_ms_per_frame({}) == {}  # a run that ended within warm-up


def test_labels_group_rows_and_example_root_runs_that_checkout(tmp_path):
    records = [
        rec("sail", 1, 40.0, label="before", phases_ms_per_frame={"update": 20.0}),
        rec("sail", 1, 80.0, label="after", phases_ms_per_frame={"update": 10.0}),
        rec("sb3", 1, 100.0, label="after"),
    ]
    rows = {(r["label"], r["trainer"]): r for r in throughput.aggregate(records)}
    assert rows["before", "sail"]["phases_ms_per_frame"] == {"update": 20.0}
    assert rows["before", "sail"]["fps_vs_sb3"] is None and rows["after", "sail"]["fps_vs_sb3"] == pytest.approx(0.8)
    assert "| before | sail | 1 | 40.0 |" in throughput.markdown(list(rows.values()))
    (tmp_path / "examples").mkdir()
    (tmp_path / "examples" / "sail_td3.py").touch()
    args = throughput.parse_args(["--example-root", str(tmp_path), "--label", "before"])
    assert throughput.example_command(args, "sail", 1, tmp_path)[1] == str(tmp_path / "examples" / "sail_td3.py")
    record = throughput.run_one(args, "td3", 1)  # no conf/algo/td3_delayed.yaml there: skipped, not run
    assert record["label"] == "before" and "td3_delayed" in record["error"]
    with pytest.raises(SystemExit):
        throughput.parse_args(["--example-root", str(tmp_path / "missing")])


def test_whole_process_fps_from_the_difference_of_process_times():
    # per round: 5000 frames in T(10000) - T(5000) seconds; sail: 100 s and 90 s -> 50 and 55.6 frames/s
    records = [
        rec("sail", 1, 40.0, 0, frames=5000, process_seconds=130.0),
        rec("sail", 1, 41.0, 0, frames=10000, process_seconds=230.0),
        rec("sail", 1, 42.0, 1, frames=5000, process_seconds=120.0),
        rec("sail", 1, 43.0, 1, frames=10000, process_seconds=210.0),
        rec("sb3", 1, 100.0, 0, frames=5000, process_seconds=60.0),
        rec("sb3", 1, 100.0, 0, frames=10000, process_seconds=110.0),
    ]
    rows = {r["trainer"]: r for r in throughput.aggregate(records)}
    assert rows["sail"]["fps"] == 41.0 and rows["sail"]["runs"] == 2  # in-process: the --frames runs only
    assert rows["sail"]["fps_whole_process"] == pytest.approx((50.0 + 5000 / 90) / 2)
    assert rows["sb3"]["fps_whole_process"] == pytest.approx(100.0)
    assert rows["sail"]["fps_whole_process_vs_sb3"] == pytest.approx((50.0 + 5000 / 90) / 200)
    table = throughput.markdown(list(rows.values()))
    assert table.splitlines()[0].endswith("| whole-process frames/s | whole-process vs sb3 |")
    assert "| 52.8 | 0.53 |" in table
    # a round without its 2 x frames run, or a failed one, gives no whole-process figure
    alone = [rec("sail", 1, 40.0, 0, frames=5000, process_seconds=130.0)]
    assert throughput.aggregate(alone)[0]["fps_whole_process"] is None


def test_whole_process_runs_each_trainer_at_frames_and_twice_frames(tmp_path, monkeypatch):
    calls = []

    def fake_run_one(args, trainer, threads, frames=None):
        calls.append((trainer, threads, frames))
        return {"trainer": trainer, "threads": threads, "frames": frames, "fps": 1.0, "process_seconds": frames / 100}

    monkeypatch.setattr(throughput, "run_one", fake_run_one)
    monkeypatch.setattr(throughput, "machine", lambda device: {"load_1min": 0.0})
    out = tmp_path / "t.json"
    throughput.main(
        ["--trainers", "sail", "td3", "--threads", "1", "--rounds", "1", "--whole-process", "--out", str(out)]
    )
    # one untimed 1000-frame run of each trainer first (it pays the cold start), then the timed pairs
    assert calls == [
        ("sail", 1, 1000),
        ("td3", 1, 1000),
        ("sail", 1, 5000),
        ("sail", 1, 10000),
        ("td3", 1, 5000),
        ("td3", 1, 10000),
    ]
    records = json.loads(out.read_text())["records"]
    assert [(r["trainer"], r["frames"]) for r in records] == [c[::2] for c in calls[2:]]  # warm-up runs not kept
    assert throughput.parse_args([]).whole_process is False


def made_invocation(path, records, **args):
    """A file as ``main`` writes it (``--out``), from its records."""
    base = {"env": "Hopper-v4", "warmup": 1000, "frames": 2000, "rounds": 2, "threads": [1], "seed": 0}
    base |= {"trainers": ["sail", "sb3"], "sail_overrides": "", "label": "x", "device": "cpu", "whole_process": True}
    machine = {"cpu_model": "Some CPU", "cpu_flags": ["avx2"], "cpu_count": 2, "load_1min": 0.25, "python": "3.11.7"}
    machine |= {"torch": "2.13.0+cpu", "torchrl": "0.14.1", "stable-baselines3": "2.9.2"}
    data = {"commit": "c" * 40, "dirty": False, "machine": machine, "args": base | args, "records": records}
    path.write_text(json.dumps(data))
    return path


def timed(trainer, threads, fps, rnd, t_frames, t_twice, label="x"):
    """The two runs of a round: ``--frames`` (2000) timed at ``fps``, and the process times of both runs."""
    return [
        rec(trainer, threads, fps, rnd, frames=2000, process_seconds=t_frames, label=label),
        rec(trainer, threads, fps + 1, rnd, frames=4000, process_seconds=t_twice, label=label),
    ]


def test_docs_block_medians_rounds_and_the_command(tmp_path):
    # whole-process per round: 2000 / (T(4000) - T(2000))
    x = [
        *timed("sail", 1, 60.0, 0, 50.0, 70.0),  # whole-process 100
        *timed("sb3", 1, 50.0, 0, 60.0, 100.0),  # 50
        *timed("sail", 1, 64.0, 1, 50.0, 100.0),  # 40
        *timed("sb3", 1, 40.0, 1, 60.0, 140.0),  # 25
        *timed("sail", 2, 90.0, 0, 40.0, 60.0),  # 100
        *timed("sb3", 2, 60.0, 0, 50.0, 90.0),  # 50
        *timed("sail", 2, 80.0, 1, 40.0, 60.0),  # 100
        *timed("sb3", 2, 80.0, 1, 50.0, 90.0),  # 50
    ]
    y = [rec("sail", 1, 30.0, 0, label="y"), rec("sb3", 1, 20.0, 0, label="y"), rec("sail", 1, 34.0, 1, label="y")]
    y.append({"trainer": "sb3", "threads": 1, "round": 1, "label": "y", "error": "exit 1"})  # SB3 failed round 1
    y.append(rec("sb3", 1, 10.0, 1, label="z"))  # another label's run (files merged): not y's peer
    first = made_invocation(tmp_path / "x.json", x, threads=[1, 2], sail_overrides="optim.precision=bf16 a=b")
    second = made_invocation(tmp_path / "y.json", y, label="y", whole_process=False, other_load="two runs")
    lines = throughput.docs_block([first, second]).splitlines()
    rows = [line for line in lines if line.startswith(("| x |", "| y |"))]
    name = "SAIL, `optim.precision=bf16 a=b`"
    # medians, 1 thread: timers 62 against 45; whole-process 70 against 37.5 (the ratio of the medians,
    # 1.87, not the median of the rounds' ratios, 1.80); 2 threads: 85 against 70, 100 against 50
    assert rows[:4] == [
        f"| x | {name} | 1 | 62.0 | 1.38 | 70.0 | 1.87 | 10.00 | 1.00 | 500 |",
        "| x | SB3 TD3 | 1 | 45.0 | 1.00 | 37.5 | 1.00 | 10.00 | 1.00 | 500 |",
        f"| x | {name} | 2 | 85.0 | 1.21 | 100.0 | 2.00 | 10.00 | 1.00 | 500 |",
        "| x | SB3 TD3 | 2 | 70.0 | 1.00 | 50.0 | 1.00 | 10.00 | 1.00 | 500 |",
    ]
    assert rows[4:6] == [
        "| y | SAIL (defaults) | 1 | 32.0 | 1.60 | - | - | 10.00 | 1.00 | 500 |",  # SB3's one round: 20
        "| y | SB3 TD3 | 1 | 20.0 | 1.00 | - | - | 10.00 | 1.00 | 500 |",
    ]
    # round by round, each ratio to SB3's round at the same thread count and in the same file
    assert rows[6] == f"| x | {name} | 1 | 60.0, 64.0 | 1.20, 1.60 | 100.0, 40.0 | 2.00, 1.60 |"
    assert rows[8] == f"| x | {name} | 2 | 90.0, 80.0 | 1.50, 1.00 | 100.0, 100.0 | 2.00, 2.00 |"
    assert rows[10] == "| y | SAIL (defaults) | 1 | 30.0, 34.0 | 1.50, - | -, - | -, - |"  # SB3 failed round 1
    assert rows[11] == "| y | SB3 TD3 | 1 | 20.0, - | 1.00, - | -, - | -, - |"
    # the commands parse back to each file's settings
    commands = [line.strip() for line in lines if line.strip().startswith("python benchmarks/throughput.py")]
    for command, path in zip(commands, (first, second), strict=True):
        recorded = json.loads(path.read_text())["args"]
        parsed = vars(throughput.make_parser().parse_args(shlex.split(command)[2:]))
        assert {key: parsed[key] for key in recorded} == recorded and parsed["out"] == path
    assert "(code: commit ccccccc): Hopper-v4, 2 rounds" in lines[0]
    assert "Some CPU (2 CPUs; CPU flags: avx2); Python 3.11.7" in lines[0]
    assert "at the start; other load: two runs." in next(line for line in lines if "y.json`" in line)


def test_docs_block_one_round_without_sb3_and_on_a_gpu(tmp_path):
    records = [rec("sail", 1, 300.0, 0, label="g")]
    path = made_invocation(tmp_path / "g.json", records, rounds=1, trainers=["sail"], device="cuda", label="g")
    text = throughput.docs_block([path])
    assert "| g | SAIL (defaults) | 1 | 300.0 | - | - | - | 10.00 | 1.00 | 500 |" in text
    assert "Round by round" not in text  # with one round, the medians are the rounds
    assert "--device cuda" in text and "--whole-process" in text
    assert throughput.trainer_name("sb3", {"device": "cuda"}) == 'SB3 TD3, `device="cuda"`'
    assert throughput.trainer_name("td3", {"sail_overrides": ""}) == "TD3, `algo=td3_delayed`"
