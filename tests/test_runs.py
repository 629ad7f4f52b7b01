"""``torchrl_sail.harness``: a run folder's life cycle (start, resume, truncate, summarise, read) on made folders."""

from __future__ import annotations

import importlib.metadata
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from torchrl import timeit
from torchrl.checkpoint import Checkpoint

from torchrl_sail.harness import (
    add_evaluation,
    checkpoint_dir,
    code_label,
    fall_share,
    is_finished,
    last_checkpoint,
    machine,
    new_run,
    plot_learning_curve,
    provenance,
    read_scalar,
    restore_run,
    resume_mode,
    runs,
    start_or_resume,
    train_timing,
    truncate_scalar_logs,
    write_atomic,
    write_summary,
)

REPO = Path(__file__).resolve().parents[1]


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def identity(**changes) -> dict:
    return {"env": "Hopper-v4", "algo": "sail", "seed": 0, "teacher": "/data/paper.npz", **changes}


def saved_run(
    run_dir: Path, *, frames: int = 2000, weight: float = 1.0, lr: float = 1e-3, config: dict | None = None, **changes
) -> None:
    """A checkpoint as a training script saves it: the run dict at ``frames`` (trained with ``config``), a layer
    and its optimizer."""
    run = new_run(**identity(**changes))
    run.update(frames=frames, gradient_steps=frames // 20, evals=[(1000, 5.0), (2000, 30.0)], config=config)
    layer = torch.nn.Linear(2, 1)
    torch.nn.init.constant_(layer.weight, weight)
    optimizer = torch.optim.Adam(layer.parameters(), lr=lr)
    Checkpoint(run=run, layer=layer, optim=optimizer).save(checkpoint_dir(run_dir))


def fresh(lr: float = 1e-3) -> tuple[dict, torch.nn.Linear, torch.optim.Optimizer, Checkpoint]:
    run, layer = new_run(**identity()), torch.nn.Linear(2, 1)
    optimizer = torch.optim.Adam(layer.parameters(), lr=lr)
    return run, layer, optimizer, Checkpoint(run=run, layer=layer, optim=optimizer)


# ----------------------------------------------------------------------------- resume_mode
def test_resume_false_starts_a_new_folder_and_refuses_one_with_a_checkpoint(tmp_path):
    assert resume_mode(tmp_path / "new", False, 1000) is False
    saved_run(tmp_path / "run")
    with pytest.raises(FileExistsError, match="already holds a run .* resume=true"):
        resume_mode(tmp_path / "run", False, 1000)
    assert resume_mode(tmp_path / "run", True, 1000) is True
    # logs without a checkpoint (a run that stopped before its first one): a fresh run would append to them
    log = write(tmp_path / "early" / "logs" / "scalars" / "eval" / "return.csv", "500,1.0\n")
    with pytest.raises(FileExistsError, match="logs of a run that stopped before its first checkpoint.*resume=auto"):
        resume_mode(tmp_path / "early", False, 1000)
    assert log.read_text() == "500,1.0\n"


def test_resume_auto_skips_a_finished_run_only_if_it_trained_with_this_config(tmp_path):
    write(tmp_path / "done" / "summary.json", json.dumps({"frames": 3000}))
    write(tmp_path / "done" / "config.yaml", "seed: 0\nresume: false\neval:\n  episodes: 10\nalgo:\n  alpha: 0.5\n")
    same = {"seed": 0, "resume": "auto", "eval": {"episodes": 5}, "algo": {"alpha": 0.5}}  # only allowed keys differ
    assert resume_mode(tmp_path / "done", "auto", 3000, config=same) is None
    other = {**same, "algo": {"alpha": 0.0}}
    with pytest.raises(ValueError, match=r"finished run trained with algo.alpha=0.5 \(this run: 0.0\)"):
        resume_mode(tmp_path / "done", "auto", 3000, config=other)
    assert resume_mode(tmp_path / "done", "auto", 3000) is None  # no config given: not compared


def test_resume_auto_skips_finished_continues_checkpointed_and_restarts_the_rest(tmp_path):
    # finished (summary at the budget, or offline): skipped
    write(tmp_path / "done" / "summary.json", json.dumps({"frames": 3000}))
    assert resume_mode(tmp_path / "done", "auto", 3000) is None
    write(tmp_path / "bc" / "summary.json", json.dumps({"frames": 0, "offline": True}))
    assert resume_mode(tmp_path / "bc", "auto", 10**6) is None
    # a larger budget: continued from the checkpoint
    saved_run(tmp_path / "done")
    assert resume_mode(tmp_path / "done", "auto", 4000) is True
    # finished but without a checkpoint (a results copy): skipped at its budget, and it cannot be extended
    write(tmp_path / "copy" / "summary.json", json.dumps({"frames": 3000}))
    assert resume_mode(tmp_path / "copy", "auto", 3000) is None
    with pytest.raises(
        FileNotFoundError, match="finished 3000-frame run but no checkpoint to extend it to collector.total_frames=4000"
    ):
        resume_mode(tmp_path / "copy", "auto", 4000)
    # stopped before its first checkpoint: its logs go, it starts afresh
    log = write(tmp_path / "early" / "logs" / "scalars" / "eval" / "return.csv", "500,1.0\n")
    write(tmp_path / "early" / "config.yaml", "seed: 0\n")
    assert resume_mode(tmp_path / "early", "auto", 3000) is False
    assert not log.exists() and (tmp_path / "early" / "config.yaml").exists()


def test_is_finished():
    assert is_finished({"frames": 3000}, 3000) and not is_finished({"frames": 2999}, 3000)
    assert is_finished({"offline": True, "frames": 0}, 10) and not is_finished({}, 1)


# ----------------------------------------------------------------------------- restore and start
def test_restore_checks_the_identity_then_loads_and_truncates_the_logs(tmp_path):
    run_dir = tmp_path / "run"
    saved_run(run_dir, frames=2000, weight=0.5)
    eval_csv = write(run_dir / "logs" / "scalars" / "eval" / "return.csv", "1000,5.0\n2000,30.0\n3000,41.0\n")
    alpha_csv = write(run_dir / "logs" / "scalars" / "alpha.csv", "1000,0.5\n2000,0.5\n")
    run, layer, _, checkpoint = fresh()
    restore_run(checkpoint, run_dir, run)
    # (the checkpoint keeps the run dict as JSON: the evaluations come back as lists)
    assert run["frames"] == 2000 and run["evals"] == [[1000, 5.0], [2000, 30.0]] and run["identity"] == identity()
    assert torch.equal(layer.weight, torch.full((1, 2), 0.5))
    # rows logged after the checkpoint are logged again by the resumed run: dropped, the others kept
    assert eval_csv.read_text() == "1000,5.0\n2000,30.0\n" and alpha_csv.read_text() == "1000,0.5\n2000,0.5\n"
    assert not list(run_dir.rglob(".*.tmp"))


@pytest.mark.parametrize(
    "change, message",
    [
        ({"seed": 1}, "written with seed=1, this run has seed=0"),
        (
            {"teacher": "/data/other.npz"},
            "written with teacher.path='/data/other.npz', this run has teacher.path='/data/paper.npz'",
        ),
        ({"env": "Walker2d-v4"}, "written with env='Walker2d-v4'"),
    ],
)
def test_restore_refuses_another_runs_checkpoint(tmp_path, change, message):
    saved_run(tmp_path / "run", weight=0.5, **change)
    run, layer, _, checkpoint = fresh()
    before = layer.weight.detach().clone()
    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        restore_run(checkpoint, tmp_path / "run", run)
    assert torch.equal(layer.weight, before)  # nothing but the run's identity was read


TRAINED = {"seed": 0, "resume": False, "optim": {"lr": 1e-3, "gamma": 0.99}, "network": {"spectral_norm": False}}


def test_restore_refuses_a_config_change_the_checkpoint_was_not_trained_with(tmp_path):
    saved_run(tmp_path / "run", weight=0.5, config=TRAINED)
    run, layer, _, checkpoint = fresh()
    before = layer.weight.detach().clone()
    config = {**TRAINED, "resume": True, "optim": {"lr": 1e-3, "gamma": 0.9}, "network": {"spectral_norm": True}}
    with pytest.raises(ValueError) as err:
        restore_run(checkpoint, tmp_path / "run", run, config=config)
    assert str(err.value).startswith(
        f"resume: {tmp_path / 'run' / 'checkpoint'} was written with network.spectral_norm=False, this run has "
        "network.spectral_norm=True; with optim.gamma=0.99, this run has optim.gamma=0.9. A resumed run may change "
        "only its length, logging, evaluation, checkpoints, hardware and learning rates"
    )
    assert torch.equal(layer.weight, before)  # refused before the checkpoint was loaded


def test_restore_takes_evaluation_changes_but_not_the_averaged_actors_memory(tmp_path):
    """eval.* may change on resume, but not eval.average_frames: the checkpoint holds that average."""
    trained = {**TRAINED, "eval": {"episodes": 5, "average_frames": 10_000}}
    saved_run(tmp_path / "run", weight=0.5, config=trained)
    run, _, _, checkpoint = fresh()
    config = {**trained, "resume": True, "eval": {"episodes": 10, "average_frames": 0}}
    with pytest.raises(ValueError, match="written with eval.average_frames=10000, this run has eval.average_frames=0"):
        restore_run(checkpoint, tmp_path / "run", run, config=config)
    run, _, _, checkpoint = fresh()
    restore_run(
        checkpoint, tmp_path / "run", run, config={**config, "eval": {"episodes": 10, "average_frames": 10_000}}
    )
    assert run["resumes"] == [{"frames": 2000, "changes": {"eval.episodes": [5, 10]}}]


def test_restore_records_the_allowed_changes_against_the_checkpoints_config(tmp_path, capsys):
    run_dir = tmp_path / "run"
    saved_run(run_dir, config=TRAINED)
    # config.yaml is what the last start went on with (here a diverged resume at lr 1e12 that saved nothing):
    # the comparison is with the config the checkpoint was trained with
    write(run_dir / "config.yaml", "seed: 0\nresume: true\noptim:\n  lr: 1.0e12\n  gamma: 0.99\n")
    run, _, _, checkpoint = fresh()
    restore_run(checkpoint, run_dir, run, config={**TRAINED, "resume": True, "optim": {"lr": 5e-4, "gamma": 0.99}})
    assert run["resumes"] == [{"frames": 2000, "changes": {"optim.lr": [1e-3, 5e-4]}}]  # `resume` itself is not one
    assert "resume at frame 2000: optim.lr=0.001 -> 0.0005" in capsys.readouterr().out
    # a checkpoint without its config (an earlier version's) is compared with config.yaml
    saved_run(run_dir, config=None)
    run, _, _, checkpoint = fresh()
    with pytest.raises(ValueError, match=r"written with optim.gamma=0.99, this run has optim.gamma=0.9\."):
        restore_run(checkpoint, run_dir, run, config={"seed": 0, "optim": {"lr": 1.0e12, "gamma": 0.9}})
    run, _, _, checkpoint = fresh()
    config = {"seed": 0, "optim": {"lr": 1.0e12, "gamma": 0.99, "coef": 0.1}, "new_key": 1}
    restore_run(checkpoint, run_dir, run, config=config)
    # nothing changed; the keys only this run's config has (a newer version's settings) are recorded and said
    assert run["resumes"] == [{"frames": 2000, "changes": {}, "added": {"new_key": 1, "optim.coef": 0.1}}]
    assert "the checkpoint's config lacks new_key=1, optim.coef=0.1 (another version's settings)" in (
        capsys.readouterr().out
    )
    # and the keys only the checkpoint's config has (an older version's settings), at their saved values
    run, _, _, checkpoint = fresh()
    restore_run(checkpoint, run_dir, run, config={"seed": 0, "optim": {"lr": 1.0e12}})
    assert run["resumes"] == [{"frames": 2000, "changes": {}, "removed": {"optim.gamma": 0.99}}]
    assert "the checkpoint's config has, this version does not, optim.gamma=0.99" in capsys.readouterr().out


@pytest.mark.parametrize(
    "saved_kwargs, kwargs",
    [({}, {"ctrl_cost_weight": 5.0}), ({"ctrl_cost_weight": 5.0}, {}), ({"a": 1}, {"a": 2})],
    ids=["added", "removed", "changed"],
)
def test_restore_refuses_any_change_of_the_envs_kwargs(tmp_path, saved_kwargs, kwargs):
    # env.kwargs is the user's open mapping: an entry added or removed changes the env, not the version
    saved_run(tmp_path / "run", config={**TRAINED, "env": {"name": "Hopper-v4", "kwargs": saved_kwargs}})
    run, _, _, checkpoint = fresh()
    config = {**TRAINED, "env": {"name": "Hopper-v4", "kwargs": kwargs}}
    with pytest.raises(ValueError, match=re.escape(f"written with env.kwargs={saved_kwargs!r}, this run has")):
        restore_run(checkpoint, tmp_path / "run", run, config=config)


def test_restore_refuses_a_checkpoint_holding_state_this_run_would_drop(tmp_path):
    saved_run(tmp_path / "run")  # run, layer, optim
    run, layer, _, _ = fresh()
    before = layer.weight.detach().clone()
    with pytest.raises(ValueError, match=r"holds \['optim'\], which this run does not keep"):
        restore_run(Checkpoint(run=run, layer=layer), tmp_path / "run", run)
    assert torch.equal(layer.weight, before)  # refused before the weights load (only the run dict, to check it)


def test_restore_starts_empty_only_the_components_a_newer_version_added(tmp_path, capsys):
    """A checkpoint without a component this run keeps: refused, naming it, unless it is one of
    may_start_empty, which keeps its fresh state while the others load; the resume records it."""
    saved_run(tmp_path / "run", weight=0.5)  # run, layer, optim
    run, layer, optimizer, _ = fresh()
    kept = torch.nn.Linear(2, 1)  # stands in for a newer version's state
    torch.nn.init.constant_(kept.weight, 7.0)
    checkpoint = Checkpoint(run=run, layer=layer, optim=optimizer, kept=kept)
    with pytest.raises(ValueError, match=r"lacks \['kept'\], which this run keeps"):
        restore_run(checkpoint, tmp_path / "run", run)
    restore_run(checkpoint, tmp_path / "run", run, may_start_empty=("kept",))
    assert torch.equal(layer.weight, torch.full((1, 2), 0.5)) and torch.equal(kept.weight, torch.full((1, 2), 7.0))
    assert run["resumes"] == [{"frames": 2000, "changes": {}, "started_empty": ["kept"]}]
    assert "the checkpoint has no ['kept'] (another version's); they start from here" in capsys.readouterr().out


def test_restore_without_or_with_a_damaged_checkpoint(tmp_path):
    run, _, _, checkpoint = fresh()
    with pytest.raises(FileNotFoundError, match="resume=true but there is no checkpoint at"):
        restore_run(checkpoint, tmp_path / "run", run)
    write(tmp_path / "run" / "checkpoint" / "manifest.json", "not a checkpoint")
    with pytest.raises(ValueError, match="checkpoint is unreadable"):
        restore_run(checkpoint, tmp_path / "run", run)


def test_start_or_resume_keeps_the_configured_lr_drops_the_summary_and_writes_the_config(tmp_path):
    from omegaconf import OmegaConf

    run_dir = tmp_path / "run"
    saved_run(run_dir, lr=1e-3)
    write(run_dir / "summary.json", json.dumps({"frames": 2000}))
    run, _, optimizer, checkpoint = fresh(lr=5e-4)
    config = OmegaConf.create({"seed": 0, "optim": {"lr": 5e-4}, "dir": "${seed}"})
    start_or_resume(checkpoint, run_dir, run, True, optimizers=[optimizer], config=config)
    assert run["frames"] == 2000 and optimizer.param_groups[0]["lr"] == 5e-4  # the configured one, not the saved
    assert not (run_dir / "summary.json").exists()  # a continued run is unfinished until it ends
    assert (run_dir / "config.yaml").read_text() == "seed: 0\noptim:\n  lr: 0.0005\ndir: 0\n"  # resolved


def test_a_setting_covers_the_keys_below_it():
    allowed = ("eval", "collector.backend_options", "optim.lr")
    for key in ("eval", "eval.episodes", "collector.backend_options", "collector.backend_options.timeout", "optim.lr"):
        assert runs._may_change(key, allowed), key
    for key in ("evaluation", "collector.backend", "optim.lr_decay", "optim"):
        assert not runs._may_change(key, allowed), key


def test_start_or_resume_takes_the_configured_optimizer_settings_and_places_the_step(tmp_path):
    # saved by a plain Adam after a step; resumed with fused=True (as with CUDA graphs: capturable=True), whose
    # step must be a float32 tensor on the parameter's device: the saved group's flags would keep the old kind
    run_dir = tmp_path / "run"
    run = new_run(**identity())
    layer = torch.nn.Linear(2, 1)
    optimizer = torch.optim.Adam(layer.parameters(), lr=1e-3)
    layer(torch.ones(1, 2)).sum().backward()
    optimizer.step()
    Checkpoint(run=run, layer=layer, optim=optimizer).save(checkpoint_dir(run_dir))
    run, layer = new_run(**identity()), torch.nn.Linear(2, 1)
    optimizer = torch.optim.Adam(layer.parameters(), lr=5e-4, fused=True)
    start_or_resume(Checkpoint(run=run, layer=layer, optim=optimizer), run_dir, run, True, optimizers=[optimizer])
    group = optimizer.param_groups[0]
    assert group["fused"] is True and group["lr"] == 5e-4
    step = optimizer.state[layer.weight]["step"]
    assert step.dtype == torch.float32 and step.device == layer.weight.device and step.item() == 1.0
    layer(torch.ones(1, 2)).sum().backward()
    optimizer.step()  # the fused kernel accepts the restored state
    assert optimizer.state[layer.weight]["step"].item() == 2.0


def test_start_or_resume_offline_keeps_logs_and_summary(tmp_path):
    run_dir = tmp_path / "run"
    saved_run(run_dir, frames=0)
    steps = write(run_dir / "logs" / "scalars" / "bc" / "loss.csv", "10,0.5\n20,0.25\n")  # BC steps, not frames
    write(run_dir / "summary.json", json.dumps({"frames": 0, "offline": True}))
    run, _, optimizer, checkpoint = fresh()
    start_or_resume(checkpoint, run_dir, run, True, optimizers=[optimizer], truncate_logs=False)
    assert steps.read_text() == "10,0.5\n20,0.25\n" and (run_dir / "summary.json").exists()
    assert not (run_dir / "config.yaml").exists()  # no config given


def test_start_writes_only_the_config(tmp_path):
    from omegaconf import OmegaConf

    run, _, _, checkpoint = fresh()
    (tmp_path / "run").mkdir()
    start_or_resume(checkpoint, tmp_path / "run", run, False, config=OmegaConf.create({"seed": 3}))
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == ["config.yaml"]
    starts = run.pop("starts")
    expected = {**new_run(**identity()), "config": {"seed": 3}}  # each checkpoint keeps the config it trained with
    del expected["starts"]
    assert run == expected
    assert len(starts) == 1 and starts[0]["frames"] == 0 and set(provenance()) <= set(starts[0])


def test_every_start_keeps_its_provenance(tmp_path):
    """A resumed run's starts keep each one's code and machine, with the frame it began at."""
    run_dir = tmp_path / "run"
    run, _, _, checkpoint = fresh()
    run_dir.mkdir()
    start_or_resume(checkpoint, run_dir, run, False, code_dir=tmp_path)  # not a git checkout: no commit
    run["frames"] = 2000
    checkpoint.save(checkpoint_dir(run_dir))
    run, _, optimizer, checkpoint = fresh()
    start_or_resume(checkpoint, run_dir, run, True, optimizers=[optimizer])  # the package's checkout
    assert [start["frames"] for start in run["starts"]] == [0, 2000]
    assert run["starts"][0]["commit"] is None and run["starts"][1]["commit"] == provenance()["commit"]


@pytest.mark.parametrize(
    ("evals", "expected"),
    [
        # passed at 2000; after it 12 < 20 falls, 20.0 (not below) and 31 do not: 1 of 3
        (
            [(1000, 5.0), (2000, 30.0), (3000, 12.0), (4000, 20.0), (5000, 31.0)],
            {"share": 1 / 3, "falls": 1, "evaluations": 3},
        ),
        ([(3000, 12.0), (1000, 5.0), (2000, 30.0)], {"share": 1.0, "falls": 1, "evaluations": 1}),  # by frame
        ([[1000, 5.0], (2000, 30.0), [3000, 12.0]], {"share": 1.0, "falls": 1, "evaluations": 1}),  # resumed: lists
        ([(1000, 5.0), (2000, 30.0)], {"share": None, "falls": 0, "evaluations": 0}),  # passed at the last one
        ([(1000, 5.0), (2000, 20.0)], None),  # equal is not above: never passed
        ([], None),
    ],
)
def test_fall_share_counts_the_evaluations_below_the_teacher_after_the_first_pass(evals, expected):
    assert fall_share(evals, teacher_return=20.0) == expected


def test_truncate_scalar_logs_rewrites_only_the_files_with_later_rows(tmp_path):
    late = write(tmp_path / "logs" / "scalars" / "d" / "accuracy.csv", "500,0.5\n1000,0.6\n1500,0.7\n")
    early = write(tmp_path / "logs" / "scalars" / "alpha.csv", "500,0.5\n1000,0.5\n")
    stamp = early.stat().st_mtime_ns
    assert truncate_scalar_logs(tmp_path, 1000) == [late]
    assert late.read_text() == "500,0.5\n1000,0.6\n" and early.stat().st_mtime_ns == stamp
    assert truncate_scalar_logs(tmp_path / "nothing", 0) == []


def test_truncate_scalar_logs_drops_the_rows_a_crash_damaged(tmp_path):
    # a NUL-filled row (power loss) and a last row cut mid-write: the resumed run's next row would be glued to it
    damaged = write(tmp_path / "logs" / "scalars" / "eval" / "return.csv", "500,1.0\n\x00\x00\x00\n1000,2.0\n1500,3")
    assert truncate_scalar_logs(tmp_path, 2000) == [damaged]
    assert damaged.read_text() == "500,1.0\n1000,2.0\n"


def test_last_checkpoint_names_the_saved_frame(tmp_path):
    run = new_run(**identity())
    assert last_checkpoint(tmp_path, run) is None
    saved_run(tmp_path)
    run["frames"] = 2000
    assert last_checkpoint(tmp_path, run) == f"{tmp_path / 'checkpoint'}, frame 2000"


def test_add_evaluation_records_the_first_frame_above_the_teacher():
    run = new_run(**identity())
    for frames, value in [(1000, 200.0), (2000, 150.0), (3000, 90.0)]:
        add_evaluation(run, frames, value, teacher_return=150.0)
    assert run["evals"] == [(1000, 200.0), (2000, 150.0), (3000, 90.0)] and run["passed_teacher_at"] == 1000
    run = new_run(**identity())
    add_evaluation(run, 1000, 150.0, teacher_return=150.0)  # equal is not above
    assert run["passed_teacher_at"] is None


# ----------------------------------------------------------------------------- read_scalar
def test_read_scalar_reads_the_logs_as_logged(tmp_path):
    write(tmp_path / "logs" / "scalars" / "eval" / "return.csv", "1000,12.5\n\n3000,30.0\n2000,20.0\n2000,21.0\n")
    # every row in file order: a frame logged twice shows twice (callers that want one per frame use dict())
    assert read_scalar(tmp_path, "eval/return") == [(1000, 12.5), (3000, 30.0), (2000, 20.0), (2000, 21.0)]
    assert read_scalar(tmp_path, "sail/q_mean") == []
    write(tmp_path / "logs" / "scalars" / "alpha.csv", "1000.0,0.5\n")  # TorchRL may write float steps
    assert read_scalar(tmp_path, "alpha") == [(1000, 0.5)]


def test_read_scalar_reads_a_results_copy(tmp_path):
    # campaign.py --collect keeps one scalars.csv: it is read instead of logs/ (which a copy lacks)
    write(
        tmp_path / "scalars.csv",
        "tag,frames,value\neval/return,1000,12.5\nd/accuracy_agent,1000,0.75\neval/return,2000,30.0\n",
    )
    write(tmp_path / "logs" / "scalars" / "eval" / "return.csv", "1000,99.0\n")
    assert read_scalar(tmp_path, "eval/return") == [(1000, 12.5), (2000, 30.0)]
    assert read_scalar(tmp_path, "d/accuracy_agent") == [(1000, 0.75)] and read_scalar(tmp_path, "alpha") == []


@pytest.mark.parametrize(
    "where, text",
    [
        ("logs/scalars/eval/return.csv", "1000,12.5\nfoo\n"),
        ("logs/scalars/eval/return.csv", "1000,12.5\n2000,1,3\n"),
        ("scalars.csv", "tag,frames,value\neval/return,x,1.0\n"),
    ],
)
def test_read_scalar_names_a_bad_row(tmp_path, where, text):
    write(tmp_path / where, text)
    with pytest.raises(ValueError, match=f"{where}, line 2: expected 'frames,value'"):
        read_scalar(tmp_path, "eval/return")


# ----------------------------------------------------------------------------- summary
def test_write_summary_adds_memory_curve_and_provenance(tmp_path):
    written = write_summary(tmp_path, {"env": "Hopper-v4", "frames": 3000}, code_dir=REPO)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary == written and list(summary)[:2] == ["env", "frames"]
    assert list(summary)[2:] == ["peak_memory_mb", "learning_curve", "provenance"]
    assert summary["peak_memory_mb"] > 0 and summary["learning_curve"] == "learning_curve.png"
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    code = summary["provenance"]
    assert code["commit"] == head and isinstance(code["dirty"], bool) and code["torch_threads"] >= 1
    assert set(code["versions"]) == {"torchrl_sail", "torch", "torchrl", "tensordict", "gymnasium", "mujoco"}


def test_provenance_outside_a_checkout(tmp_path):
    code = machine.provenance(tmp_path)
    assert code["commit"] is None and code["dirty"] is None and code["python"]


def test_provenance_of_a_package_that_is_not_installed(monkeypatch, tmp_path):
    def version(name):
        if name == "torchrl_sail":
            raise importlib.metadata.PackageNotFoundError(name)
        return "1.0"

    monkeypatch.setattr(importlib.metadata, "version", version)
    versions = machine.provenance(tmp_path)["versions"]
    assert versions["torchrl_sail"] is None and versions["torch"] == "1.0"  # the summary is still written


def test_plot_learning_curve_reads_the_logs(tmp_path):
    write(tmp_path / "logs" / "scalars" / "eval" / "return.csv", "1000,12.5\n2000,30.0\n")
    path = plot_learning_curve(tmp_path, teacher_return=20.0, alpha_switch_frame=1500, title="sail")
    assert path == tmp_path / "learning_curve.png" and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_learning_curve_leaves_the_callers_matplotlib_alone(tmp_path):
    # run in a fresh interpreter: the backend is process-wide
    code = f"""
import matplotlib
matplotlib.use("svg")
import matplotlib.pyplot as plt
from pathlib import Path
from torchrl_sail.harness import plot_learning_curve
plt.figure()
plot_learning_curve(Path({str(tmp_path)!r}), teacher_return=1.0, alpha_switch_frame=None, title="t")
print(matplotlib.get_backend(), plt.get_fignums())
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["svg", "[1]"]  # the backend the caller chose, and only the caller's figure
    assert (tmp_path / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_train_timing(tmp_path):
    assert train_timing(None, end=10.0, frames=500) == {
        "train_frames": 0,
        "train_seconds": 0.0,
        "train_frames_per_second": None,
    }
    timeit.erase()
    for _ in range(3):
        with timeit("runs_test_section"):
            pass
    timing = train_timing((100.0, 1000), end=102.0, frames=3000)
    assert (timing["train_frames"], timing["train_seconds"], timing["train_frames_per_second"]) == (2000, 2.0, 1000.0)
    assert timing["counts"]["frames"] == 2000 and timing["counts"]["runs_test_section"] == 3
    assert timing["time_seconds"]["runs_test_section"] >= 0


def test_write_atomic_replaces_whole_files(tmp_path):
    write_atomic(tmp_path / "a.json", "one")
    write_atomic(tmp_path / "a.json", "two")
    assert (tmp_path / "a.json").read_text() == "two" and [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_cpu_flags_reads_proc_cpuinfo(monkeypatch, tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("model name\t: Some CPU\nflags\t\t: fpu avx2 sse amx_tile avx512f amx_bf16\n")
    real_path = machine.Path
    monkeypatch.setattr(machine, "Path", lambda p: cpuinfo if p == "/proc/cpuinfo" else real_path(p))
    assert machine.cpu_flags() == ["avx2", "avx512f", "amx_bf16", "amx_tile"]  # MATMUL_FLAGS' order
    assert machine.cpu_model() == "Some CPU"
    cpuinfo.unlink()
    assert machine.cpu_flags() == [] and machine.cpu_model() is None


def test_code_label_prefers_the_note_then_the_commit():
    assert code_label({"code": "commit abc1234 (a note)", "commit": "f" * 40}) == "commit abc1234 (a note)"
    assert code_label({"commit": "0123456789" * 4, "dirty": False}) == "commit 0123456"
    assert code_label({"commit": "0123456789" * 4, "dirty": True}) == "commit 0123456 (uncommitted changes)"
    assert code_label({"commit": None, "dirty": None}) == "not recorded"
