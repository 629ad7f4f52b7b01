"""``benchmarks/campaign.py``: the order of the campaign's runs and the commands it builds (no training)."""

from __future__ import annotations

import argparse
import json
import re
from collections import Counter
from pathlib import Path

import pytest
import torch
import yaml
from benchmark_scripts import load_benchmark

campaign = load_benchmark("campaign")

ENVS = ["Hopper-v4", "HalfCheetah-v4", "Walker2d-v4", "Swimmer-v4"]


def test_plan_fills_the_table_seed_0_first():
    cells = campaign.plan()
    # seed 0 of SAIL and DAC on every env comes first
    assert [(c.env, c.method, c.seed) for c in cells[:8]] == [
        (env, method, 0) for env in ENVS for method in ("sail", "dac")
    ]
    main = [c for c in cells if c.stage == "main"]
    counts = Counter((c.method, c.seed) for c in main)
    for method in ("sail", "dac", "bc"):  # 3 seeds on 4 envs
        assert all(counts[method, seed] == 4 for seed in (0, 1, 2))
    assert counts["td3_delayed", 0] == counts["dac_published", 0] == 4  # one seed per env
    assert len(main) == 44 and {c.frames for c in main} == {300_000}
    # the main table precedes the 1M-frame runs, which precede the two sweeps (seed 0 of both first)
    order = {
        "main": 0,
        "scale": 1,
        "teachers": 2,
        "buffer": 2,
        "weak": 3,
        "precision": 4,
        "preact": 5,
        "centred": 6,
        "logit": 7,
        "trusted": 8,
        "average": 9,
        "hold": 10,
        "averaged": 11,
        "remedies": 12,
        "ant": 13,
        "comparison": 14,
        "table1": 15,
    }
    stages = [order[c.stage] for c in cells]
    assert stages == sorted(stages)
    sweeps = [c.seed for c in cells if order[c.stage] == 2]
    assert sweeps == sorted(sweeps)
    assert {(c.env, c.frames) for c in cells if c.stage == "scale"} == {
        ("HalfCheetah-v4", 1_000_000),
        ("Hopper-v4", 1_000_000),
    }
    buffer = [c.overrides for c in cells if c.stage == "buffer"]
    replaced = campaign.REPLACED_DEFAULTS  # SAIL's default when these stages ran
    assert sorted(buffer) == sorted([(*replaced, "teacher.eviction=fifo"), (*replaced, "teacher.eviction=union")] * 2)
    assert len(set(cells)) == len(cells)  # no run twice
    # SAIL with each weak teacher, 3 seeds, seed by seed; the near-random Hopper teacher's third seed
    # beside the teachers stage's two, under its label
    weak = [(c.env, c.method, c.seed, c.frames, c.teacher) for c in cells if c.stage == "weak"]
    assert weak == [
        *((env, "sail", seed, 300_000, label) for seed in (0, 1, 2) for env, label in campaign.WEAK_TEACHERS.items()),
        ("Hopper-v4", "sail", 2, 300_000, "random"),
    ]
    teachers_random = {c.seed for c in cells if c.stage == "teachers" and c.teacher == "random"}
    assert teachers_random | {2} == {0, 1, 2}
    # the actor's pre-tanh penalty: each weak teacher, then the paper's on every env, seed by seed
    preact = [(c.env, c.seed, c.teacher) for c in cells if c.stage == "preact"]
    assert preact == [
        cell
        for seed in (0, 1, 2)
        for cell in (
            ("Swimmer-v4", seed, "weak_swimmer-preact"),
            ("HalfCheetah-v4", seed, "early_halfcheetah-preact"),
            ("Hopper-v4", seed, "random-preact"),
            *((env, seed, "paper-preact") for env in campaign.ENVS),
        )
    ]
    assert {(c.method, c.frames, c.overrides) for c in cells if c.stage == "preact"} == {
        ("sail", 300_000, ("eval.actor=online", "optim.actor_preactivation_coef=0.001"))  # the online actor, as then
    }
    # SAIL's reward centred at D = 1/2: each weak teacher, then the paper's on every env, seed by seed,
    # each its own "-centred" label
    centred = [(c.env, c.seed, c.teacher) for c in cells if c.stage == "centred"]
    assert centred == [
        cell
        for seed in (0, 1, 2)
        for cell in (
            ("Swimmer-v4", seed, "weak_swimmer-centred"),
            ("HalfCheetah-v4", seed, "early_halfcheetah-centred"),
            ("Hopper-v4", seed, "random-centred"),
            *((env, seed, "paper-centred") for env in campaign.ENVS),
        )
    ]
    assert {(c.method, c.frames, c.overrides) for c in cells if c.stage == "centred"} == {
        ("sail", 300_000, (*campaign.REPLACED_DEFAULTS, "algo.reward.shift=-0.6931471805599453"))
    }
    # D's logit where no fall ends an episode: each weak teacher, then the paper's on Swimmer and HalfCheetah
    logit = [(c.env, c.seed, c.teacher) for c in cells if c.stage == "logit"]
    assert logit == [
        cell
        for seed in (0, 1, 2)
        for cell in (
            ("Swimmer-v4", seed, "weak_swimmer-logit"),
            ("HalfCheetah-v4", seed, "early_halfcheetah-logit"),
            ("Swimmer-v4", seed, "paper-logit"),
            ("HalfCheetah-v4", seed, "paper-logit"),
        )
    ]
    assert {(c.method, c.frames, c.overrides) for c in cells if c.stage == "logit"} == {
        ("sail", 300_000, (*campaign.REPLACED_DEFAULTS, "algo.reward.kind=airl"))
    }
    # fp32 beside bf16, seed by seed, on the paper's Hopper teacher
    precision = [(c.env, c.seed, c.frames, c.teacher, c.overrides) for c in cells if c.stage == "precision"]
    assert precision == [
        ("Hopper-v4", seed, 100_000, f"paper-{p}", (*campaign.REPLACED_DEFAULTS, f"optim.precision={p}"))
        for seed in (0, 1, 2)
        for p in ("fp32", "bf16")
    ]


def test_precision_stage_needs_bf16_hardware_and_takes_overrides(tmp_path, monkeypatch, capsys):
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    args = ["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--stages", "precision"]
    monkeypatch.setattr(campaign, "native_bf16_matmul", lambda device: torch.device(device).type == "cuda")
    with pytest.raises(SystemExit):
        campaign.main(args)  # the default device, the CPU here, has no bf16 hardware
    assert "--stages precision runs optim.precision=bf16, which the cpu here emulates" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
    launched = []
    monkeypatch.setattr(
        campaign.subprocess, "run", lambda cmd, **kw: launched.append(cmd) or argparse.Namespace(returncode=0)
    )
    assert campaign.main([*args, "--overrides", "device=cuda", "optim.cudagraphs=true", "--jobs", "1"]) == 0
    assert len(launched) == 6
    assert all(cmd[-3:-1] == ["device=cuda", "optim.cudagraphs=true"] for cmd in launched)
    assert campaign.device_of(["++device=cuda:1"]) == "cuda:1" and campaign.device_of([]) == "cpu"
    assert "optim.precision=bf16" in launched[1]
    assert launched[1][-1].endswith("precision/paper-bf16/Hopper-v4/sail/seed0")


def test_command_is_resumable_single_threaded_and_in_its_own_folder(tmp_path):
    cell = campaign.Cell("main", "Walker2d-v4", "dac", 2, 300_000)
    teacher = tmp_path / campaign.PAPER_TEACHERS["Walker2d-v4"]
    cmd = campaign.command(cell, tmp_path / "out", teacher, python="python")
    examples = campaign.REPO / "examples"
    assert cmd[:2] == ["python", str(examples / "sail_td3.py")]
    for arg in (
        "algo=dac",
        "env=Walker2d-v4",
        "seed=2",
        "collector.total_frames=300000",
        "threads=1",
        "resume=auto",
        "eval.episodes=10",
        "checkpoint.every_frames=25000",
        f"teacher.path={teacher}",
    ):
        assert arg in cmd
    assert cmd[-1] == f"hydra.run.dir={tmp_path / 'out' / 'main' / 'paper' / 'Walker2d-v4' / 'dac' / 'seed2'}"
    shipped = campaign.Cell("teachers", "Hopper-v4", "sail", 0, 300_000, teacher="shipped")
    assert not any(arg.startswith("teacher.path=") for arg in campaign.command(shipped, tmp_path, None))
    # each method runs with its family's script
    bc = campaign.command(campaign.Cell("main", "Hopper-v4", "bc", 0, 300_000), tmp_path, teacher, python="python")
    assert bc[:3] == ["python", str(examples / "bc.py"), "algo=bc"]


def test_dry_run_prints_the_queue_and_checks_the_teachers(tmp_path, capsys):
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    assert (
        campaign.main(
            ["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--stages", "main", "--dry-run"]
        )
        == 0
    )
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 44 and "algo=sail" in lines[0] and "env=Hopper-v4" in lines[0]
    assert not (tmp_path / "out").exists()  # a dry run writes nothing
    (teachers / campaign.PAPER_TEACHERS["Swimmer-v4"]).unlink()
    with pytest.raises(SystemExit):
        campaign.main(["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--dry-run"])
    assert campaign.PAPER_TEACHERS["Swimmer-v4"] in capsys.readouterr().err


def test_collect_copies_finished_runs_compactly_and_aggregate_reads_them(tmp_path):
    out, dest = tmp_path / "runs", tmp_path / "results"
    run_dir = out / "main" / "paper" / "Hopper-v4" / "sail" / "seed0"
    (run_dir / "logs" / "scalars" / "d").mkdir(parents=True)
    (run_dir / "logs" / "scalars" / "eval").mkdir()
    (out / "main" / "matrix.json").write_text(json.dumps({"teachers": {"paper": "/t.npz"}}))
    (run_dir / "config.yaml").write_text(
        yaml.safe_dump(
            {"env": {"name": "Hopper-v4"}, "algo": {"name": "sail"}, "seed": 0, "collector": {"total_frames": 2000}}
        )
    )
    (run_dir / "summary.json").write_text(json.dumps({"frames": 2000, "total_frames": 2000}))
    (run_dir / "logs" / "scalars" / "eval" / "return.csv").write_text("1000,12.5\n2000,30.0\n")
    (run_dir / "logs" / "scalars" / "d" / "accuracy_agent.csv").write_text("1000,0.75\n")
    (run_dir / "logs" / "scalars" / "d" / "loss_discriminator.csv").write_text("1000,0.5\n")  # not a diagnostic
    unfinished = out / "main" / "paper" / "Hopper-v4" / "sail" / "seed1"
    unfinished.mkdir()
    (unfinished / "summary.json").write_text(json.dumps({"frames": 1000, "total_frames": 2000}))

    assert campaign.collect(out, dest) == [dest / run_dir.relative_to(out)]
    target = dest / "main" / "paper" / "Hopper-v4" / "sail" / "seed0"
    assert sorted(p.name for p in target.iterdir()) == ["config.yaml", "scalars.csv", "summary.json"]
    assert (dest / "main" / "matrix.json").exists() and not (
        dest / "main" / "paper" / "Hopper-v4" / "sail" / "seed1"
    ).exists()
    assert (target / "scalars.csv").read_text().splitlines() == [
        "tag,frames,value",
        "eval/return,1000,12.5",
        "eval/return,2000,30.0",
        "d/accuracy_agent,1000,0.75",
    ]
    aggregate = load_benchmark("aggregate")
    assert aggregate.read_scalar(target, "eval/return") == [(1000, 12.5), (2000, 30.0)]
    assert aggregate.read_scalar(target, "d/accuracy_agent") == [(1000, 0.75)]


def test_collect_keeps_the_stages_envs_and_seeds_asked_and_refuses_a_summary_alone(tmp_path, capsys):
    out, dest = tmp_path / "runs", tmp_path / "results"
    runs = [
        ("scale", "paper", "Hopper-v4", 0),
        ("scale", "paper", "HalfCheetah-v4", 0),
        ("weak", "weak_swimmer", "Swimmer-v4", 1),
        ("weak", "weak_swimmer", "Swimmer-v4", 2),
        ("trusted", "paper", "Hopper-v4", 3),
    ]
    for stage, teacher, env, seed in runs:
        run_dir = out / stage / teacher / env / ("dac" if stage == "trusted" else "sail") / f"seed{seed}"
        run_dir.mkdir(parents=True)
        (run_dir / "logs" / "scalars").mkdir(parents=True)
        (run_dir / "config.yaml").write_text("seed: 0\n")
        (run_dir / "summary.json").write_text(json.dumps({"frames": 10, "total_frames": 10}))
    base = ["--out", str(out), "--collect", str(dest)]

    assert campaign.main([*base, "--stages", "scale", "--envs", "Hopper-v4"]) == 0
    assert capsys.readouterr().out.split() == [str(dest / "scale" / "paper" / "Hopper-v4" / "sail" / "seed0")]
    assert campaign.main([*base, "--seeds", "2"]) == 0  # --stages unset: every stage
    assert capsys.readouterr().out.split() == [str(dest / "weak" / "weak_swimmer" / "Swimmer-v4" / "sail" / "seed2")]
    assert campaign.main([*base, "--methods", "dac"]) == 0
    assert capsys.readouterr().out.split() == [str(dest / "trusted" / "paper" / "Hopper-v4" / "dac" / "seed3")]
    assert len(campaign.collect(out, dest)) == 5

    # a finished run's summary.json copied alone (e.g. to make resume=auto skip the run) is not a run folder
    (out / "weak" / "weak_swimmer" / "Swimmer-v4" / "sail" / "seed1" / "config.yaml").unlink()
    with pytest.raises(FileNotFoundError, match="seed1 has a summary.json but no config.yaml"):
        campaign.collect(out, tmp_path / "other")
    assert not (tmp_path / "other").exists()  # checked before anything is copied
    assert len(campaign.collect(out, tmp_path / "other", seeds=[0, 2])) == 3
    assert len(campaign.collect(out, tmp_path / "other", methods=["sail"], seeds=[0, 2, 3])) == 3


def test_collect_keeps_a_results_copy_put_back_as_it_is_and_refuses_one_without_its_curve(tmp_path):
    # A finished cell's results copy (config.yaml, summary.json, scalars.csv) put back under --out
    # marks the cell done for resume=auto; collecting again must give the same scalars.csv, not an
    # empty one rebuilt from the logs it does not have.
    out, dest = tmp_path / "runs", tmp_path / "results"
    copy = out / "preact" / "paper-preact" / "Hopper-v4" / "sail" / "seed0"
    copy.mkdir(parents=True)
    (copy / "config.yaml").write_text("seed: 0\n")
    (copy / "summary.json").write_text(json.dumps({"frames": 10, "total_frames": 10}))
    curve = "tag,frames,value\neval/return,10,3.5\n"
    (copy / "scalars.csv").write_text(curve)
    assert campaign.collect(out, dest) == [dest / copy.relative_to(out)]
    assert (dest / copy.relative_to(out) / "scalars.csv").read_text() == curve

    (copy / "scalars.csv").unlink()  # summary.json and config.yaml alone: no curve to collect
    (dest / copy.relative_to(out) / "summary.json").unlink()
    with pytest.raises(FileNotFoundError, match="seed0 has neither logs/scalars nor a scalars.csv"):
        campaign.collect(out, dest)
    assert (dest / copy.relative_to(out) / "scalars.csv").read_text() == curve  # refused before writing
    assert not (dest / copy.relative_to(out) / "summary.json").exists()


def test_matrix_records_every_stage_and_label(tmp_path, monkeypatch):
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    launched = []
    monkeypatch.setattr(
        campaign.subprocess, "run", lambda cmd, **kw: launched.append(cmd) or argparse.Namespace(returncode=0)
    )
    assert campaign.main(["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--jobs", "1"]) == 0
    never = (
        "weak",
        "precision",
        "preact",
        "centred",
        "logit",
        "average",
        "hold",
        "averaged",
        "remedies",
        "ant",
        "comparison",
        "table1",
    )
    default = [c for c in campaign.plan() if c.teacher != "random" and c.stage not in never]
    assert len(launched) == len(default)  # not the weak, precision and remedy stages: never defaults
    main = json.loads((tmp_path / "out" / "main" / "matrix.json").read_text())
    assert main["teachers"] == {"paper": str(teachers)}  # the authors' folder: one file per env
    assert {(s["envs"][0], s["methods"][0], s["seeds"][0]) for s in main["sweeps"]} == {
        (c.env, c.method, c.seed) for c in campaign.plan() if c.stage == "main"
    }
    buffer = json.loads((tmp_path / "out" / "buffer" / "matrix.json").read_text())
    assert set(buffer["teachers"]) == {"paper-fifo", "paper-union"}
    assert json.loads((tmp_path / "out" / "teachers" / "matrix.json").read_text())["teachers"] == {"shipped": None}


def test_weak_stage_runs_each_weak_teacher_and_refuses_a_missing_one(tmp_path, capsys):
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    weak = tmp_path / "weak"
    for label in campaign.WEAK_TEACHERS.values():
        (weak / label).mkdir(parents=True)
    args = ["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--stages", "weak", "--dry-run"]
    assert campaign.main([*args, "--weak-teachers-dir", str(weak)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 6
    assert f"teacher.path={weak / 'weak_swimmer'}" in lines[0] and "env=Swimmer-v4" in lines[0]
    assert lines[0].endswith(
        f"hydra.run.dir={tmp_path / 'out' / 'weak' / 'weak_swimmer' / 'Swimmer-v4' / 'sail' / 'seed0'}"
    )
    assert "seed=2" in lines[-1] and "env=HalfCheetah-v4" in lines[-1]
    # with --random-teacher, the near-random Hopper teacher's seed 2 (its label's folder under the weak stage)
    random = tmp_path / "random_hopper"
    assert campaign.main([*args, "--weak-teachers-dir", str(weak), "--random-teacher", str(random)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 7
    assert f"teacher.path={random} " in lines[-1] and "env=Hopper-v4" in lines[-1] and "seed=2" in lines[-1]
    assert lines[-1].endswith(f"hydra.run.dir={tmp_path / 'out' / 'weak' / 'random' / 'Hopper-v4' / 'sail' / 'seed2'}")
    (weak / "early_halfcheetah").rmdir()
    with pytest.raises(SystemExit):
        campaign.main([*args, "--weak-teachers-dir", str(weak)])
    assert "lacks early_halfcheetah" in capsys.readouterr().err
    # the default stages need no weak teacher
    assert campaign.main([*args[:-3], "--weak-teachers-dir", str(weak), "--dry-run"]) == 0
    # and the weak stage alone needs no paper teacher; the others still do
    (weak / "early_halfcheetah").mkdir()
    capsys.readouterr()
    assert campaign.main(args[2:] + ["--weak-teachers-dir", str(weak)]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 6
    with pytest.raises(SystemExit):
        campaign.main(["--out", str(tmp_path / "out"), "--dry-run"])
    assert "--teachers-dir is required by --stages main scale teachers buffer" in capsys.readouterr().err


@pytest.mark.parametrize(
    "stage, override, runs, third",
    [
        ("preact", "optim.actor_preactivation_coef=0.001", 18, "Hopper-v4"),
        ("centred", "algo.reward.shift=-0.6931471805599453", 18, "Hopper-v4"),
        ("logit", "algo.reward.kind=airl", 12, "Swimmer-v4"),
    ],
)
def test_reward_stages_give_the_weak_and_the_paper_teachers_and_the_override(
    tmp_path, capsys, monkeypatch, stage, override, runs, third
):
    teachers, weak, out = tmp_path / "teachers", tmp_path / "weak", tmp_path / "out"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    for label in campaign.WEAK_TEACHERS.values():
        (weak / label).mkdir(parents=True)
    args = ["--teachers-dir", str(teachers), "--weak-teachers-dir", str(weak), "--out", str(out), "--stages", stage]
    assert campaign.main([*args, "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == runs and all(override in line for line in lines)
    # a weak teacher's label drops the stage's suffix for its folder; the paper's label gives the authors' file
    assert f"teacher.path={weak / 'weak_swimmer'} " in lines[0]
    assert lines[0].endswith(f"hydra.run.dir={out / stage / f'weak_swimmer-{stage}' / 'Swimmer-v4' / 'sail' / 'seed0'}")
    assert f"teacher.path={teachers / campaign.PAPER_TEACHERS[third]} " in lines[2]
    assert lines[2].endswith(f"hydra.run.dir={out / stage / f'paper-{stage}' / third / 'sail' / 'seed0'}")
    assert "seed=2" in lines[-1]
    # the stage's matrix gives each label its teacher, for aggregate.py
    monkeypatch.setattr(campaign.subprocess, "run", lambda cmd, **kw: argparse.Namespace(returncode=0))
    assert campaign.main(args) == 0
    matrix = json.loads((out / stage / "matrix.json").read_text())
    assert matrix["teachers"] == {
        f"weak_swimmer-{stage}": str(weak / "weak_swimmer"),
        f"early_halfcheetah-{stage}": str(weak / "early_halfcheetah"),
        f"paper-{stage}": str(teachers),
    }
    # with --random-teacher, the near-random Hopper teacher too, where a fall may end an episode's reward
    random = tmp_path / "random_hopper"
    capsys.readouterr()
    assert campaign.main([*args, "--random-teacher", str(random), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    with_random = [line for line in lines if f"teacher.path={random} " in line]
    assert len(lines) == runs + len(with_random)
    if stage == "logit":
        assert not with_random
    else:
        assert len(with_random) == 3 and with_random[0] == lines[2]
        assert lines[2].endswith(f"hydra.run.dir={out / stage / f'random-{stage}' / 'Hopper-v4' / 'sail' / 'seed0'}")
    (weak / "weak_swimmer").rmdir()
    with pytest.raises(SystemExit):
        campaign.main([*args, "--dry-run"])
    assert "lacks weak_swimmer" in capsys.readouterr().err


def test_trusted_stage_confirms_the_candidate_on_eight_teachers_beside_its_comparisons(tmp_path, capsys):
    """Seeds 0-4: the candidate on the paper's and the shipped teachers (40 runs); the defaults on the
    shipped teachers where the teachers stage has no run (18); the defaults and DAC with the paper's
    teachers, seeds 3-4 (16); each seed's candidate runs before its comparisons."""
    cells = [c for c in campaign.plan() if c.stage == "trusted"]
    candidate = [c for c in cells if c.teacher.endswith("-trusted")]
    assert len(cells) == 74 and len(set(cells)) == 74 and {c.frames for c in cells} == {300_000}
    assert Counter((c.teacher, c.seed) for c in candidate) == {
        (label, seed): 4 for label in ("paper-trusted", "shipped-trusted") for seed in range(5)
    }
    assert {c.overrides for c in candidate} == {campaign.TRUSTED} and all(c.method == "sail" for c in candidate)
    assert "eval.actor=target" in campaign.TRUSTED and "optim.actor_preactivation_coef=0.001" in campaign.TRUSTED
    shipped = {(c.env, c.seed) for c in cells if c.teacher == "shipped"}
    assert len(shipped) == 18 and ("Hopper-v4", 1) not in shipped and ("Hopper-v4", 2) in shipped
    paper = Counter((c.method, c.seed) for c in cells if c.teacher == "paper")
    assert paper == {(method, seed): 4 for method in ("sail", "dac") for seed in (3, 4)}
    # the defaults' runs name the default they ran with, which the candidate replaced
    replaced = {"sail": campaign.REPLACED_DEFAULTS, "dac": ()}
    assert all(c.overrides == replaced[c.method] for c in cells if c not in candidate)
    seeds = [c.seed for c in cells]
    assert seeds == sorted(seeds) and cells[0] == campaign.Cell(
        "trusted", "Swimmer-v4", "sail", 0, 300_000, "shipped-trusted", campaign.TRUSTED
    )
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    out = tmp_path / "out"
    assert campaign.main(["--teachers-dir", str(teachers), "--out", str(out), "--stages", "trusted", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 74 and "teacher.path=" not in lines[0]  # the shipped teacher: the env's default
    assert lines[0].endswith(f"hydra.run.dir={out / 'trusted' / 'shipped-trusted' / 'Swimmer-v4' / 'sail' / 'seed0'}")
    assert f"teacher.path={teachers / campaign.PAPER_TEACHERS['HalfCheetah-v4']} " in lines[1]


def test_average_stage_tunes_the_averaged_actors_memory_on_tuning_seeds(tmp_path, capsys):
    """Tuning seeds only, each memory on seeds of its own (the training does not depend on it);
    Hopper with the paper's teacher and Walker2d with the shipped one; the candidate's training,
    every actor evaluated; the averaged actor's curve collected."""
    cells = [c for c in campaign.plan() if c.stage == "average"]
    assert len(cells) == 8 and len(set(cells)) == 8
    assert Counter((c.env, c.teacher, c.seed) for c in cells) == {
        (env, f"{label}-average{memory}k", seed): 1
        for env, label in (("Hopper-v4", "paper"), ("Walker2d-v4", "shipped"))
        for memory, seeds in ((10, (100, 101)), (30, (102, 103)))
        for seed in seeds
    }
    assert [c.seed for c in cells[:4]] == [100, 100, 102, 102]  # a seed of each memory first
    for cell in cells:
        memory = int(cell.teacher.split("average")[1].removesuffix("k")) * 1000
        assert cell.overrides == (*campaign.TRUSTED, f"eval.average_frames={memory}")
    assert "eval.other_actor=true" in campaign.TRUSTED and "eval/return_average" in campaign.DIAGNOSTICS
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    (teachers / campaign.PAPER_TEACHERS["Hopper-v4"]).touch()
    out = tmp_path / "out"
    assert campaign.main(["--teachers-dir", str(teachers), "--out", str(out), "--stages", "average", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 8 and f"teacher.path={teachers / campaign.PAPER_TEACHERS['Hopper-v4']}" in lines[0]
    assert "teacher.path=" not in lines[1] and lines[1].endswith(
        f"hydra.run.dir={out / 'average' / 'shipped-average10k' / 'Walker2d-v4' / 'sail' / 'seed100'}"
    )


def test_remedies_stage_tunes_three_remedies_of_the_falls_beside_the_average_stages_runs(tmp_path, capsys):
    """The critic's LayerNorm, the authors' FIFO ring and the actor's lr at 3e-4, each with the candidate,
    on the average stage's seeds and teachers (its runs train the candidate alone on them: the
    baseline), seed by seed."""
    cells = [c for c in campaign.plan() if c.stage == "remedies"]
    average = [c for c in campaign.plan() if c.stage == "average"]
    assert len(cells) == 24 and len(set(cells)) == 24
    assert {(c.env, c.teacher.split("-")[0], c.seed) for c in cells} == {
        (c.env, c.teacher.split("-")[0], c.seed) for c in average
    }
    assert [c.seed for c in cells] == [seed for seed in (100, 101, 102, 103) for _ in range(6)]
    for cell in cells:
        remedy = cell.teacher.rsplit("-", 1)[1]
        assert cell.teacher == f"{'paper' if cell.env == 'Hopper-v4' else 'shipped'}-trusted-{remedy}"
        assert cell.overrides == (
            *campaign.TRUSTED,
            {
                "ln": "network.critic_layer_norm=true",
                "fifo": "teacher.eviction=fifo",
                "actor_lr": "optim.actor_lr=0.0003",
            }[remedy],
        )
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    (teachers / campaign.PAPER_TEACHERS["Hopper-v4"]).touch()
    out = tmp_path / "out"
    args = ["--teachers-dir", str(teachers), "--out", str(out), "--stages", "remedies", "--seeds", "100", "--dry-run"]
    assert campaign.main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 6 and f"teacher.path={teachers / campaign.PAPER_TEACHERS['Hopper-v4']}" in lines[0]
    assert "network.critic_layer_norm=true" in lines[0] and "teacher.eviction=fifo" in lines[3]
    assert "optim.actor_lr=0.0003" in lines[4] and "-trusted-actor_lr" in lines[5]
    assert "teacher.path=" not in lines[3] and lines[3].endswith(
        f"hydra.run.dir={out / 'remedies' / 'shipped-trusted-fifo' / 'Walker2d-v4' / 'sail' / 'seed100'}"
    )


def test_averaged_stage_reruns_the_trusted_candidate_runs_with_the_averaged_actor_shipped(tmp_path, capsys):
    """The trusted stage's 40 candidate cells (seeds 0-4, the eight teachers, in its order), the averaged
    actor at the chosen memory evaluated and shipped, the other actors beside it."""
    plan = campaign.plan()
    cells = [c for c in plan if c.stage == "averaged"]
    trusted = [c for c in plan if c.stage == "trusted" and c.teacher.endswith("-trusted")]
    assert len(cells) == 40 and len(set(cells)) == 40
    assert [(c.env, c.seed, c.frames) for c in cells] == [(c.env, c.seed, c.frames) for c in trusted]
    assert [c.teacher.removesuffix("-averaged") for c in cells] == [c.teacher.removesuffix("-trusted") for c in trusted]
    memory = campaign.AVERAGED_MEMORY
    assert all(
        c.overrides
        == (
            "optim.actor_preactivation_coef=0.001",
            "eval.actor=average",
            "eval.other_actor=true",
            f"eval.average_frames={memory}",
        )
        for c in cells
    )
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    out = tmp_path / "out"
    args = ["--teachers-dir", str(teachers), "--out", str(out), "--stages", "averaged", "--seeds", "0", "--dry-run"]
    assert campaign.main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 8 and "teacher.path=" not in lines[0]  # the shipped Swimmer teacher first
    folder = out / "averaged" / "paper-averaged" / "HalfCheetah-v4" / "sail" / "seed0"
    assert lines[1].endswith(f"hydra.run.dir={folder}")
    assert f"teacher.path={teachers / campaign.PAPER_TEACHERS['HalfCheetah-v4']}" in lines[1]
    assert "eval.actor=average" in lines[1] and f"eval.average_frames={memory}" in lines[1]


def test_hold_stage_reruns_the_average_stages_hopper_runs_with_the_teacher_buffer_held():
    """The same cells as the average stage's Hopper runs (their seeds, teacher and overrides: the same
    training up to the tenth promotion) plus algo.max_promoted=10, at 200k frames."""
    plan = campaign.plan()
    cells = [c for c in plan if c.stage == "hold"]
    average = {c.seed: c for c in plan if c.stage == "average" and c.env == "Hopper-v4"}
    assert sorted(c.seed for c in cells) == sorted(average) == [100, 101, 102, 103]
    for cell in cells:
        base = average[cell.seed]
        assert (cell.env, cell.method, cell.frames) == ("Hopper-v4", "sail", 200_000)
        assert cell.teacher == f"{base.teacher}-hold" and cell.teacher.startswith("paper-average")
        assert cell.overrides == (*base.overrides, "algo.max_promoted=10")


def test_status_counts_done_started_and_waiting_runs_and_refuses_an_unreadable_checkpoint(tmp_path, capsys):
    """The ant stage (12 runs: SAIL and DAC, 2 teacher labels, seeds 0-2): one run done, one with a
    checkpoint at 50k and evaluations logged after it, one whose summary says 100k of 300k (interrupted,
    so not done) and whose checkpoint is at 75k; the other nine not started."""
    out = tmp_path / "out"
    run = out / "ant" / "{}" / "Ant-v4" / "{}" / "seed{}"
    done = Path(str(run).format("paper", "sail", 0))
    done.mkdir(parents=True)
    (done / "summary.json").write_text(json.dumps({"frames": 300_000, "total_frames": 300_000}))
    checkpoints = {("paper", "dac", 0): 50_000, ("paper-nocontact", "sail", 1): 75_000}
    for (teacher, method, seed), frames in checkpoints.items():
        started = Path(str(run).format(teacher, method, seed))
        (started / "checkpoint" / "components" / "0009-run").mkdir(parents=True)
        (started / "checkpoint" / "manifest.json").write_text(
            json.dumps({"components": {"run": {"path": "components/0009-run"}}})
        )
        (started / "checkpoint" / "components" / "0009-run" / "value.json").write_text(json.dumps({"frames": frames}))
    (Path(str(run).format("paper", "dac", 0)) / "logs" / "scalars" / "eval").mkdir(parents=True)
    (Path(str(run).format("paper", "dac", 0)) / "logs" / "scalars" / "eval" / "return.csv").write_text(
        "50000,812.25\n60000,901.5\n"
    )
    (Path(str(run).format("paper-nocontact", "sail", 1)) / "summary.json").write_text(
        json.dumps({"frames": 100_000, "total_frames": 300_000})
    )

    assert campaign.main(["--out", str(out), "--stages", "ant", "--status"]) == 0  # no --teachers-dir needed
    assert capsys.readouterr().out.splitlines() == [
        "ant: 12 runs, 1 done, 2 started, 9 not started",
        "  paper sail: 3 runs, 1 done, 2 not started",
        "  paper dac: 3 runs, 1 started, 2 not started",
        "  paper-nocontact sail: 3 runs, 1 started, 2 not started",
        "  paper-nocontact dac: 3 runs, 3 not started",
        "started (resume=auto continues each from its checkpoint):",
        "  ant/paper/Ant-v4/dac/seed0: checkpoint at 50000 of 300000 frames, evaluated 901.5 at 60000",
        "  ant/paper-nocontact/Ant-v4/sail/seed1: checkpoint at 75000 of 300000 frames",
        # 9 runs of 300k, and 250k and 225k left of the started ones; the done run records no start
        "left: 3175000 frames in 11 runs (no finished run here records a single start and its frames_per_second)",
    ]
    # timed by the done run, trained in one start at 50 frames/s: 3175000 / (50 * 2) s = 8.8 h
    (done / "summary.json").write_text(
        json.dumps({"frames": 300_000, "total_frames": 300_000, "starts": [{"frames": 0}], "frames_per_second": 50.0})
    )
    assert campaign.main(["--out", str(out), "--stages", "ant", "--status", "--jobs", "2"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        "left: 3175000 frames in 11 runs; about 8.8 h at 2 runs at a time, each at 50.0 frames/s "
        "(the median frames_per_second of the 1 run here that finished in one start)"
    )
    (Path(str(run).format("paper", "dac", 0)) / "checkpoint" / "manifest.json").write_text("{")
    with pytest.raises(ValueError, match=r"dac/seed0/checkpoint/manifest.json: no readable run component"):
        campaign.main(["--out", str(out), "--stages", "ant", "--status"])


def test_time_left_is_never_less_than_the_longest_run_alone():
    # median pace 50: two runs (of the 4 --jobs allows) train 400k frames in 4000 s, but the 300k run
    # alone takes 6000 s
    assert campaign.time_left([300_000, 100_000], [40.0, 60.0, 50.0], jobs=4) == [
        "left: 400000 frames in 2 runs; about 1.7 h at 2 runs at a time, each at 50.0 frames/s "
        "(the median frames_per_second of the 3 runs here that finished in one start)"
    ]
    # four equal runs, two at a time: 4 * 90k / (2 * 50) s = 1.0 h
    assert "about 1.0 h at 2 runs" in campaign.time_left([90_000] * 4, [50.0], jobs=2)[0]
    # one run left: one at a time, whatever --jobs says
    assert "about 0.5 h at 1 run at a time" in campaign.time_left([90_000], [50.0], jobs=2)[0]
    assert campaign.time_left([], [50.0], jobs=2) == []


def test_status_leaves_offline_runs_out_of_the_frames_left_and_refuses_jobs_below_one(tmp_path, capsys):
    """The main stage's HalfCheetah seed 0: SAIL, DAC, BC, TD3 on the delayed reward and the published
    DAC, none started; BC trains on the demonstrations alone, so the other four runs' 300k frames each
    are left."""
    args = ["--out", str(tmp_path), "--stages", "main", "--envs", "HalfCheetah-v4", "--seeds", "0", "--status"]
    assert campaign.main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "  paper bc: 1 runs, 1 not started" in lines
    assert (
        lines[-1]
        == "left: 1200000 frames in 4 runs (no finished run here records a single start and its frames_per_second)"
    )
    with pytest.raises(SystemExit):
        campaign.main([*args, "--jobs", "0"])
    assert "argument --jobs: '0': at least 1 run at a time" in capsys.readouterr().err


def test_ant_stage_runs_sail_and_dac_on_the_recorded_and_the_reproduced_columns(tmp_path, capsys):
    """Seeds 0-2, seed by seed: SAIL and DAC with the authors' Ant teacher as recorded (111 columns) and
    with its contact-force columns dropped on Ant-v4 without contact forces; the Ant file is checked."""
    cells = [c for c in campaign.plan() if c.stage == "ant"]
    assert Counter((c.method, c.teacher) for c in cells) == {
        (method, teacher): 3 for method in ("sail", "dac") for teacher in ("paper", "paper-nocontact")
    }
    assert {c.env for c in cells} == {"Ant-v4"} and {c.frames for c in cells} == {300_000}
    assert [c.seed for c in cells] == sorted(c.seed for c in cells)
    assert {c.teacher: c.overrides for c in cells} == {
        "paper": (),
        "paper-nocontact": ("env.kwargs.use_contact_forces=false", "teacher.drop_columns=27-110"),
    }
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():  # the paper's four alone: the Ant file is missing
        (teachers / name).touch()
    args = ["--teachers-dir", str(teachers), "--out", str(tmp_path / "out"), "--stages", "ant", "--dry-run"]
    with pytest.raises(SystemExit):
        campaign.main(args)
    assert "lacks expert_data_no_img_Ant_scores_1200_episodes_1.npz" in capsys.readouterr().err
    (teachers / campaign.OTHER_TEACHERS["Ant-v4"]).touch()
    assert campaign.main([*args, "--seeds", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4 and all(f"teacher.path={teachers / campaign.OTHER_TEACHERS['Ant-v4']} " in x for x in lines)
    assert ["teacher.drop_columns=27-110" in line for line in lines] == [False, False, True, True]
    run_dir = tmp_path / "out" / "ant" / "paper-nocontact" / "Ant-v4" / "dac" / "seed0"
    assert lines[3].endswith(f"hydra.run.dir={run_dir}")
    # the paper's teachers are not needed for Ant alone, and --envs takes Ant-v4
    (teachers / campaign.PAPER_TEACHERS["Hopper-v4"]).unlink()
    assert campaign.main([*args, "--envs", "Ant-v4"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == 12


def test_table1_runs_the_scale_stages_cells_only_under_another_defaults_label(monkeypatch):
    """Under the label of the replaced default's runs ("paper"), Table 1's 1M-frame SAIL cells leave out
    the scale stage's two runs (seed 0 of HalfCheetah and Hopper), which are the same runs."""
    monkeypatch.setattr(campaign, "TABLE1_LABEL", "paper")
    cells = campaign.plan()
    table1 = [(c.env, c.method, c.seed, c.frames, c.teacher) for c in cells if c.stage == "table1"]
    scale = [("HalfCheetah-v4", "sail", 0, 1_000_000, "paper"), ("Hopper-v4", "sail", 0, 1_000_000, "paper")]
    assert sorted(table1 + scale) == sorted(
        (env, "sail", seed, 1_000_000, "paper") for env in ENVS for seed in (0, 1, 2)
    )
    assert [(c.env, c.seed, c.frames) for c in cells if c.stage == "scale"] == [(e, s, f) for e, _, s, f, _ in scale]


def test_comparison_stages_run_every_row_of_the_papers_comparison_on_three_seeds():
    """Table 1's variants and Figure 2's baselines on the four envs, Figures 3-4's variants on Hopper and
    HalfCheetah (300k frames, seed by seed), then SAIL at 1M frames on the four envs."""
    cells = campaign.plan()
    comparison = [c for c in cells if c.stage == "comparison"]
    counts = Counter((c.method, c.env) for c in comparison)
    for method in ("sail_rnd", "sail_sac", "gail", "pofd", "ddpgfd", "dac_published"):
        assert all(counts[method, env] == 3 for env in ENVS)
    for method in ("sail_onpolicy", "sail_no_lfd", "sail_no_adapt"):
        assert {env: counts[method, env] for env in ENVS} == {
            "Hopper-v4": 3,
            "HalfCheetah-v4": 3,
            "Walker2d-v4": 0,
            "Swimmer-v4": 0,
        }
    assert len(comparison) == 90 and {c.frames for c in comparison} == {300_000}
    assert [c.seed for c in comparison] == sorted(c.seed for c in comparison)
    assert all(c.teacher == "paper" and not c.overrides for c in comparison)
    # Table 1's 12 cells under the default's label (the trusted stage's), the scale stage's runs of the
    # replaced default not among them, each evaluating the online actor beside the target actor
    table1 = [(c.env, c.method, c.seed, c.frames, c.teacher, c.overrides) for c in cells if c.stage == "table1"]
    assert sorted(table1) == sorted(
        (env, "sail", seed, 1_000_000, "paper-trusted", ("eval.other_actor=true",))
        for env in ENVS
        for seed in (0, 1, 2)
    )
    scripts = {c.method: campaign.script_for(c.method).name for c in comparison}
    assert scripts["gail"] == scripts["pofd"] == "gail.py" and scripts["ddpgfd"] == "sail_td3.py"


def test_envs_and_seeds_keep_only_their_cells(tmp_path, capsys):
    teachers, weak = tmp_path / "teachers", tmp_path / "weak"
    teachers.mkdir()
    for name in campaign.PAPER_TEACHERS.values():
        (teachers / name).touch()
    for label in campaign.WEAK_TEACHERS.values():
        (weak / label).mkdir(parents=True)
    args = ["--teachers-dir", str(teachers), "--weak-teachers-dir", str(weak), "--out", str(tmp_path / "out")]
    # the 1M stage's Hopper run alone
    assert campaign.main([*args, "--stages", "scale", "--envs", "Hopper-v4", "--dry-run"]) == 0
    (line,) = capsys.readouterr().out.splitlines()
    assert "env=Hopper-v4" in line and "collector.total_frames=1000000" in line
    # seed 0 of the weak teachers' before and after rows, in the plan's order: 2 weak + 2 + 4 paper preact
    assert campaign.main([*args, "--stages", "weak", "preact", "--seeds", "0", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 8 and all("seed=0 " in line for line in lines)
    assert ["-preact/" in line for line in lines] == [False] * 2 + [True] * 6
    # the trusted stage's DAC runs alone: seeds 3-4 on the four envs
    assert campaign.main([*args, "--stages", "trusted", "--methods", "dac", "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 8 and all("algo=dac " in line for line in lines)
    assert sorted(re.search(r"seed=(\d)", line).group(1) for line in lines) == ["3"] * 4 + ["4"] * 4
    # a filter that leaves nothing is an error, not a silent no-op
    with pytest.raises(SystemExit):
        campaign.main([*args, "--stages", "weak", "--seeds", "7", "--dry-run"])
    assert "--stages weak has no cell with these --envs, --seeds and --methods" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        campaign.main([*args, "--envs", "Ant-v4", "--dry-run"])  # no default stage runs Ant
    assert "--stages main scale teachers buffer trusted has no cell with these --envs" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        campaign.main([*args, "--envs", "Humanoid-v4", "--dry-run"])
    assert "invalid choice: 'Humanoid-v4'" in capsys.readouterr().err


def test_a_restarted_queue_resumes_its_started_runs_before_it_starts_new_ones(tmp_path, capsys):
    """The ant stage's 12 runs: one finished and one started (a checkpoint at 50k) late in the plan;
    the started one goes first, the rest in the plan's order, the finished one included (its run
    skips itself in seconds)."""
    out = tmp_path / "out"
    teachers = tmp_path / "teachers"
    teachers.mkdir()
    (teachers / campaign.TEACHER_FILES["Ant-v4"]).touch()
    args = ["--teachers-dir", str(teachers), "--out", str(out), "--stages", "ant", "--dry-run"]
    assert campaign.main(args) == 0
    planned = [re.search(r"hydra.run.dir=(\S+)", line).group(1) for line in capsys.readouterr().out.splitlines()]
    assert len(planned) == 12
    done, started = Path(planned[5]), Path(planned[9])
    done.mkdir(parents=True)
    (done / "summary.json").write_text(json.dumps({"frames": 300_000, "total_frames": 300_000}))
    (started / "checkpoint" / "components" / "0009-run").mkdir(parents=True)
    (started / "checkpoint" / "manifest.json").write_text(
        json.dumps({"components": {"run": {"path": "components/0009-run"}}})
    )
    (started / "checkpoint" / "components" / "0009-run" / "value.json").write_text(json.dumps({"frames": 50_000}))
    assert campaign.main(args) == 0
    queued = [re.search(r"hydra.run.dir=(\S+)", line).group(1) for line in capsys.readouterr().out.splitlines()]
    assert queued == [planned[9], *planned[:9], *planned[10:]]
    # a half-written checkpoint does not stop the queue: that run reports it when its turn comes
    (started / "checkpoint" / "manifest.json").write_text("{")
    assert campaign.main(args) == 0
    queued = [re.search(r"hydra.run.dir=(\S+)", line).group(1) for line in capsys.readouterr().out.splitlines()]
    assert queued == planned


def test_every_planned_run_composes_a_valid_config_and_baselines_keep_their_references(tmp_path):
    """Each distinct (method, env, overrides) of every stage passes the scripts' config checks, so a
    queue never stops on a config error hours in; and a default changed for SAIL never reaches the
    baselines, which keep the settings of the references they are named after."""
    import sys

    from hydra import compose, initialize_config_dir

    sys.path.insert(0, str(campaign.REPO / "examples"))
    from config_schema import check_config, register_config_schema

    register_config_schema()
    runs = {}
    for cell in campaign.plan():
        args = campaign.command(cell, tmp_path, tmp_path / "teacher.npz")[2:-1]  # no script, no run folder
        # seeds and budgets (args 2-3) change no check
        runs.setdefault(tuple(args[:2] + args[4:]), (cell, args))
    assert len(runs) > 50
    baselines = {"dac", "dac_published", "ddpgfd", "td3_delayed", "gail", "pofd", "bc"}
    with initialize_config_dir(config_dir=str(campaign.REPO / "conf"), version_base="1.3"):
        for cell, args in runs.values():
            cfg = compose(config_name="config", overrides=list(args))
            check_config(cfg)
            if cell.method in baselines:
                assert cfg.optim.actor_preactivation_coef == 0 and cfg.eval.actor == "online", cell
            elif cell.method in campaign.SAIL_FAMILY and not set(args) & {*campaign.TRUSTED, *campaign.PREACT}:
                # SAIL's runs before the trusted default ran with the replaced default; those after, with it
                before = cell.stage not in campaign.AFTER_TRUSTED
                assert cfg.optim.actor_preactivation_coef == (0 if before else 0.001), cell
                assert cfg.eval.actor == ("online" if before else "target"), cell
