"""End-to-end runs of ``examples/sail_td3.py`` with tiny budgets: outputs, resume, bad input."""

from __future__ import annotations

import importlib.metadata
import json
import signal
import subprocess
import sys
import time

import pytest
import torch
from example_runner import REPO, evaluate, fail_in_process, read_scalar, run, saved, start

from torchrl_sail import make_sail_env

HOPPER = "expert_data_no_img_Hopper_scores_1500_episodes_1.npz"
CHEETAH = "expert_data_no_img_HalfCheetah_scores_5600_episodes_1.npz"

# Warm-up 1000 frames, then 50 SAIL updates per 1000 frames and 2 D steps per 500 frames.
TINY = [
    "collector.init_random_frames=1000",
    "collector.frames_per_batch=500",
    "optim.updates_per_train=50",
    "optim.discriminator.steps=2",
    "eval.every_frames=1000",
    "eval.episodes=1",
    "logger.log_every_frames=500",
    "eval.best_policy.episodes=2",  # the kept policies' final evaluation: 2 envs, not 50, per run
]


def test_smoke_hopper_outputs(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=3000",
        "checkpoint.every_frames=2000",
        "logger.backends=[csv,wandb]",
        *TINY,
    )

    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 3000 and summary["env"] == "Hopper-v4"
    assert summary["teacher_return"] == pytest.approx(1480.688, abs=1e-2)
    # 3 training blocks (at 1000, 2000 and 3000 frames) of 50 updates each
    assert summary["gradient_steps"] == 150
    assert summary["num_promoted"] == 0 and summary["teacher_threshold"] == 148.0
    assert summary["frames_per_second"] > 0 and summary["peak_memory_mb"] > 0
    # the code that made the run: this checkout's commit and whether tracked files differed
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    code = summary["provenance"]
    assert code["commit"] == head and isinstance(code["dirty"], bool) and code["torch_threads"] >= 1
    assert code["versions"]["torchrl"] == importlib.metadata.version("torchrl")
    assert len(read_scalar(run_dir, "eval/return")) == 3  # at 1000, 2000, 3000 frames
    # one episode per evaluation (TINY): its return is also the minimum, and below the teacher's 1480.7
    assert read_scalar(run_dir, "eval/min_return") == read_scalar(run_dir, "eval/return")
    assert [value for _, value in read_scalar(run_dir, "eval/below_teacher")] == [1.0, 1.0, 1.0]
    for tag in [
        "train/dense_return",
        "teacher/threshold",
        "alpha",
        "d/accuracy_teacher",
        "d/accuracy_agent",
        "d/loss_discriminator",
        "d/logit_agent_std",
        "sail/loss_qvalue",
        "sail/d_reward_mean",
        "actor/saturation",
        "actor/preactivation",
        "time/fps",
        "replay/size",
    ]:
        rows = read_scalar(run_dir, tag)
        assert rows, tag
    assert read_scalar(run_dir, "alpha")[-1][1] == 0.5
    assert read_scalar(run_dir, "replay/size")[-1] == (3000, 3000.0)
    # D's saturation in the summary, from the logged accuracies
    d = summary["discriminator"]
    assert 0 <= d["saturated_fraction"] <= 1 and d["skipped_fraction"] == 0.0  # no max_accuracy: none skipped
    assert d["last"]["accuracy_teacher"] == read_scalar(run_dir, "d/accuracy_teacher")[-1][1]
    assert set(d["last"]) == {
        "accuracy_teacher",
        "accuracy_agent",
        "reward_teacher",
        "reward_agent",
        "logit_teacher",
        "logit_agent",
    }
    # the actor's tanh saturation in the summary, from the logged values
    actor = summary["actor"]
    assert 0 <= actor["saturated_fraction"] <= 1
    assert actor["last"] == {
        "saturation": read_scalar(run_dir, "actor/saturation")[-1][1],
        "preactivation": read_scalar(run_dir, "actor/preactivation")[-1][1],
    }
    png = (run_dir / "learning_curve.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    assert (run_dir / "config.yaml").exists()
    assert any((run_dir / "wandb").glob("offline-run-*"))
    state = saved(run_dir, "run", "replay")
    assert state["run"]["frames"] == 3000 and state["run"]["gradient_steps"] == 150
    assert state["replay"]["size"] == 3000 and len(state["replay"]["data"]["action"]) == 3000


def test_discriminator_remedies_run_and_skip(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=2000",
        "checkpoint.every_frames=0",
        "logger.backends=[csv]",
        "optim.discriminator.label_smoothing=0.1",
        "optim.discriminator.instance_noise=0.1",
        "optim.discriminator.max_accuracy=0.5",  # skips every step whose balanced accuracy is above chance
        "network.discriminator_spectral_norm=true",
        # 3 blocks of 20 D steps (at 1000, 1500 and 2000 frames), so that D leaves chance on some batch:
        # with TINY's 2 steps per block, D on CUDA never did on seed 0.
        *(o for o in TINY if not o.startswith("optim.discriminator.steps=")),
        "optim.discriminator.steps=20",
    )
    skipped = read_scalar(run_dir, "d/skipped")
    assert skipped and all(0.0 <= value <= 1.0 for _, value in skipped)
    assert any(value > 0 for _, value in skipped)  # D above chance on a batch: its step was skipped
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["discriminator"]["skipped_fraction"] == pytest.approx(sum(v for _, v in skipped) / len(skipped))
    state = saved(run_dir, "discriminator")["discriminator"]
    assert any("parametrizations.weight.original" in key for key in state)  # spectral norm, saved


def test_resume_restores_state(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    common = [
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "checkpoint.every_frames=1000",
        "logger.backends=[csv]",
        "eval.average_frames=1000",
        *TINY,
    ]
    run(run_dir, *common, "collector.total_frames=2000")
    names = (
        "run",
        "replay",
        "teacher",
        "alpha",
        "loss",
        "discriminator",
        "optim_actor",
        "optim_critic",
        "optim_discriminator",
        "best_policy",
        "best_evaluated_policy",
        "actor_average",
    )
    before = saved(run_dir, *names)

    # A run folder with a checkpoint is never silently overwritten.
    proc = run(run_dir, *common, "collector.total_frames=2000", check=False)
    assert proc.returncode != 0 and "resume=true" in proc.stderr

    # Resuming with nothing left to collect restores and re-saves the same state.
    first_wall = json.loads((run_dir / "summary.json").read_text())["wall_seconds"]
    run(run_dir, *common, "collector.total_frames=2000", "resume=true")
    after = saved(run_dir, *names)
    walls = before["run"].pop("wall_seconds"), after["run"].pop("wall_seconds")
    assert walls[0] == first_wall and walls[1] > walls[0] > 0  # each start's training loop adds to it
    starts = before["run"].pop("starts"), after["run"].pop("starts")
    assert starts[1][:1] == starts[0] and [start["frames"] for start in starts[1]] == [0, 2000]  # each start kept
    assert after["run"] == before["run"] and before["run"]["frames"] == 2000
    for name in ("best_policy", "best_evaluated_policy"):  # the kept policies are part of the checkpoint
        kept = before[name], after[name]
        assert kept[0]["frames"] == kept[1]["frames"] is not None and kept[0]["score"] == kept[1]["score"]
        for actor in ("actor", "target_actor", "average_actor"):
            torch.testing.assert_close(kept[1][actor], kept[0][actor], rtol=0, atol=0)
    torch.testing.assert_close(after["replay"], before["replay"], rtol=0, atol=0)
    teachers = before["teacher"].writer, after["teacher"].writer
    assert teachers[0].window == teachers[1].window and teachers[0].threshold == teachers[1].threshold == 148.0
    assert teachers[0].num_offered == teachers[1].num_offered > 0
    assert torch.equal(
        before["teacher"].storage.get(teachers[0].stored_rows()).to_tensordict().get("observation"),
        after["teacher"].storage.get(teachers[1].stored_rows()).to_tensordict().get("observation"),
    )
    assert after["alpha"] == before["alpha"] == {"alpha": 0.5, "switched_at_frame": None}
    for name in ("loss", "discriminator", "actor_average"):
        torch.testing.assert_close(after[name], before[name], rtol=0, atol=0)
    for name in ("optim_actor", "optim_critic", "optim_discriminator"):
        steps = [s["step"] for s in before[name]["state"].values()]
        assert steps and steps == [s["step"] for s in after[name]["state"].values()]

    # Resuming with a larger budget continues the same curve.
    run(run_dir, *common, "collector.total_frames=3000", "resume=true")
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 3000 and summary["gradient_steps"] == 150 and summary["wall_seconds"] > walls[1]
    evals = read_scalar(run_dir, "eval/return")
    assert [f for f, _ in evals] == [1000, 2000, 3000]
    # the best evaluation over both starts (the first of equals), its periodic figure, then its own episodes
    best = max(evals, key=lambda e: e[1])
    evaluated = summary["best_evaluated_policy"]
    assert (evaluated["frames"], evaluated["periodic_eval_return"]) == (best[0], pytest.approx(best[1]))
    assert evaluated["episodes"] == 2 and evaluated["seed"] == summary["seed"] + 20_000  # TINY's
    # the figure is the kept weights' own: evaluate.py loads them from best_evaluated_policy.pt
    evaluate(f"run_dir={run_dir}", "policy=best_evaluated", "episodes=2", f"out={tmp_path / 'best.json'}")
    result = json.loads((tmp_path / "best.json").read_text())
    assert result["policy_frames"] == evaluated["frames"] and result["seed"] == evaluated["seed"]
    assert result["dense_return"]["mean"] == pytest.approx(evaluated["eval_return"], rel=1e-6)
    assert summary["resumes"] == [{"frames": 2000, "changes": {"collector.total_frames": [2000, 3000]}}]


def test_resume_after_kill_continues_the_same_curve(tmp_path, teacher_dir):
    # SIGKILL a run after its 2000-frame checkpoint, once it has logged past it (eval at
    # 3000), then resume: the rows logged after the checkpoint are dropped and logged again,
    # so the curve has each frame once, and wandb keeps the same run id.
    run_dir = tmp_path / "run"
    common = [
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "checkpoint.every_frames=2000",
        "logger.backends=[csv,wandb]",
        "collector.total_frames=5000",
        *TINY,
    ]
    proc = start(run_dir, *common)
    eval_csv = run_dir / "logs" / "scalars" / "eval" / "return.csv"
    deadline = time.time() + 600
    while proc.poll() is None and time.time() < deadline:
        if eval_csv.exists() and any(line.startswith("3000,") for line in eval_csv.read_text().splitlines()):
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.02)
    assert proc.wait(60) == -signal.SIGKILL, f"the run ended before it could be killed: {proc.stderr.read()[-3000:]}"
    killed_at = saved(run_dir, "run")["run"]["frames"]
    assert killed_at == 2000, "the kill must land between the 2000- and 4000-frame checkpoints"
    assert [f for f, _ in read_scalar(run_dir, "eval/return")] == [1000, 2000, 3000]

    run(run_dir, *common, "resume=true")
    assert [f for f, _ in read_scalar(run_dir, "eval/return")] == [1000, 2000, 3000, 4000, 5000]
    for tag in ("alpha", "replay/size", "time/fps"):
        frames = [f for f, _ in read_scalar(run_dir, tag)]
        assert frames == sorted(set(frames)), tag  # no frame logged twice
    assert read_scalar(run_dir, "replay/size")[-1] == (5000, 5000.0)
    runs = sorted((run_dir / "wandb").glob("offline-run-*"))
    assert len(runs) == 2 and len({path.name.rsplit("-", 1)[1] for path in runs}) == 1


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["env=Hopper-v4", "env.name=Hoper-v4"], "Unknown gymnasium env 'Hoper-v4'"),
        (["env=Hopper-v4", "teacher.path={teachers}/" + CHEETAH], "'observation' has 18 dims, env has 12"),
        (["env=Hopper-v4", "teacher.path={teachers}/missing.npz"], "missing.npz"),
        (["env=Hopper-v4", "teacher.path={teachers}/README.md"], "README.md"),
        (["env=Hopper-v4", "optim.batch_size=0"], "optim.batch_size=0"),
        (["env=Hopper-v4", "optim.gamma=1.5"], "optim.gamma=1.5"),
        (["env=Hopper-v4", "logger.backends=[csv,mlflowx]"], "mlflowx"),
        (["env=Hopper-v4", "env.name=Swimer-v4"], "Did you mean 'Swimmer-v4'"),
        (
            ["env=Hopper-v4", "collector.backend=spark"],
            "Invalid value 'spark', expected one of [direct, process, ray]\n    full_key: collector.backend",
        ),
        (["env=Hopper-v4", "collector.backend=direct", "collector.num_workers=2"], "collector.num_workers=2"),
    ],
)
def test_bad_input_fails_before_training(tmp_path, teacher_dir, overrides, message):
    overrides = [o.format(teachers=teacher_dir) for o in overrides]
    if not any(o.startswith("teacher.path") for o in overrides):
        overrides.append(f"teacher.path={teacher_dir / HOPPER}")
    error = fail_in_process(tmp_path / "run", *overrides, "collector.total_frames=1000")
    assert message in error, error
    assert not (tmp_path / "run" / "checkpoint").exists()


def test_wrong_type_is_rejected_by_hydra_naming_the_key(tmp_path):
    # the script as a user types it: `optim.lr=abc` once ended in a bare TypeError
    proc = run(tmp_path / "run", "optim.lr=abc", check=False)
    assert proc.returncode != 0
    assert "Value 'abc' of type 'str' could not be converted to Float\n    full_key: optim.lr" in proc.stderr
    assert not (tmp_path / "run").exists()


def test_resume_with_other_env_is_refused(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=1000",
        "logger.backends=[csv]",
        *TINY,
    )
    proc = run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=1000",
        "logger.backends=[csv]",
        "seed=1",
        "resume=true",
        *TINY,
        check=False,
    )
    assert proc.returncode != 0 and "written with seed=0" in proc.stderr
    assert (run_dir / "summary.json").exists()  # a refused resume leaves the finished run as it was


def test_make_teacher_records_a_demonstration(tmp_path):
    """``examples/make_teacher.py`` (TD3 on the dense reward, then the best deterministic episode)."""
    from example_runner import REPO

    from torchrl_sail import load_demonstrations

    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "examples" / "make_teacher.py"),
            "env=InvertedPendulum-v4",
            "frames=1000",
            "init_random_frames=500",
            "frames_per_batch=500",
            "updates_per_batch=10",
            "eval_every_frames=500",
            f"out={tmp_path / 'teacher'}",
            f"hydra.run.dir={tmp_path / 'run'}",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    demos, meta = load_demonstrations(tmp_path / "teacher")
    assert meta["env_id"] == "InvertedPendulum-v4" and demos.numel() == meta["episode_lengths"][0]
    assert f"return {meta['episode_returns'][0]:.1f}" in proc.stdout


def test_corrupt_checkpoint_is_reported(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    (run_dir / "checkpoint").mkdir(parents=True)
    (run_dir / "checkpoint" / "manifest.json").write_text("not a checkpoint")
    proc = run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "resume=true",
        "collector.total_frames=1000",
        check=False,
    )
    assert proc.returncode != 0 and "checkpoint is unreadable" in proc.stderr


def test_multiprocess_collector(tmp_path, teacher_dir):
    # collector.num_workers > 1: TorchRL's multi-process collector, weights synced per batch.
    run_dir = tmp_path / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.num_workers=2",
        "collector.total_frames=2000",
        "logger.backends=[csv]",
        "checkpoint.every_frames=0",
        *TINY,
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 2000 and summary["gradient_steps"] == 100
    assert read_scalar(run_dir, "replay/size")[-1] == (2000, 2000.0)
    # A [2 workers, 250] batch is flattened worker by worker: rows 0 and 250 are each
    # worker's first reset. Worker i is seeded by collector.set_seed(seed=0): 0, then the
    # seed env.set_seed returns, so both starts are reproducible and differ.
    obs = saved(run_dir, "replay")["replay"]["data"]["observation"]
    seed = 0
    for row in (0, 250):
        env = make_sail_env("Hopper-v4", max_episode_steps=1000)
        seed = env.set_seed(seed)
        torch.testing.assert_close(obs[row].cpu(), env.reset()["observation"], msg=f"worker start at row {row}")


@pytest.mark.parametrize("algo", ["sail_no_lfd", "sail_no_adapt", "sail_onpolicy"])
def test_ablations_run(tmp_path, teacher_dir, algo):
    run_dir = tmp_path / algo
    run(
        run_dir,
        "env=Hopper-v4",
        f"algo={algo}",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=2000",
        "logger.backends=[csv]",
        "checkpoint.every_frames=0",
        *TINY,
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["algo"] == algo and summary["frames"] == 2000
    alphas = {value for _, value in read_scalar(run_dir, "alpha")}
    if algo == "sail_no_lfd":
        assert alphas == {0.0}  # no teacher rows in the TD3 batches
    else:
        assert alphas == {0.5}
    if algo == "sail_no_adapt":  # the teacher buffer never changes: still the one demo
        assert {value for _, value in read_scalar(run_dir, "teacher/size")} == {425.0}


@pytest.mark.parametrize("launcher", ["joblib", "submitit_local"])
def test_seed_sweep_with_launcher(tmp_path, teacher_dir, launcher):
    # `-m seed=0,1`: joblib runs the seeds in parallel processes; submitit_local runs them
    # as submitit jobs, the path a Slurm sweep (submitit_slurm) takes. Submitit jobs unpickle
    # the task in a fresh interpreter, so examples/ must be importable: PYTHONPATH=examples.
    sweep = tmp_path / "sweep"
    launcher_options = (
        ["hydra.launcher.n_jobs=2"]
        if launcher == "joblib"
        else ["hydra.launcher.cpus_per_task=1", "hydra.launcher.timeout_min=10"]
    )
    run(
        sweep,
        f"hydra/launcher={launcher}",
        *launcher_options,
        "seed=0,1",
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=1000",
        "logger.backends=[csv]",
        "checkpoint.every_frames=0",
        *TINY,
        multirun=True,
        env={"PYTHONPATH": "examples"},
    )
    summaries = [json.loads((sweep / f"seed{seed}" / "summary.json").read_text()) for seed in (0, 1)]
    assert [s["seed"] for s in summaries] == [0, 1]
    assert all(s["frames"] == 1000 and s["gradient_steps"] == 50 for s in summaries)
    # Different seeds, different data: the random warm-up episodes differ.
    returns = [read_scalar(sweep / f"seed{seed}", "train/dense_return") for seed in (0, 1)]
    assert returns[0] != returns[1]


def test_max_promoted_holds_the_teacher_buffer(tmp_path):
    """A 3-step InvertedPendulum teacher (r_e = 0.1 R = 0.3, ``env.reward_rounding=none``) that random
    episodes beat: with ``algo.max_promoted=3`` promotions stop at the first batch that reaches 3 (a
    batch of 50 frames may promote several), and the count and C hold from there; without, they go on."""
    from torchrl_sail import TRANSITION_KEYS, save_demonstrations

    env = make_sail_env("InvertedPendulum-v4", delayed_reward=False)
    env.set_seed(0)
    shortest = min((env.rollout(1000, break_when_any_done=True) for _ in range(50)), key=lambda r: r.numel())
    assert shortest.numel() <= 4
    save_demonstrations(
        tmp_path / "teacher", shortest.select(*TRANSITION_KEYS, "step_count"), {"env_id": "InvertedPendulum-v4"}
    )
    common = [
        "env=InvertedPendulum-v4",
        f"teacher.path={tmp_path / 'teacher'}",
        "env.reward_rounding=none",
        "collector.total_frames=1000",
        "collector.init_random_frames=1000",
        "collector.frames_per_batch=50",
        "optim.updates_per_train=5",
        "optim.discriminator.steps=1",
        "eval.every_frames=0",
        "eval.best_policy.episodes=0",
        "checkpoint.every_frames=0",
        "logger.backends=[csv]",
        "logger.log_every_frames=50",
    ]
    run(tmp_path / "held", *common, "algo.max_promoted=3")
    run(tmp_path / "free", *common)
    held = [value for _, value in read_scalar(tmp_path / "held", "teacher/num_promoted")]
    free = [value for _, value in read_scalar(tmp_path / "free", "teacher/num_promoted")]
    reached = next(i for i, value in enumerate(held) if value >= 3)
    assert held[: reached + 1] == free[: reached + 1]  # the same runs until the hold
    assert set(held[reached:]) == {held[reached]} and free[-1] > held[-1]
    threshold = [value for _, value in read_scalar(tmp_path / "held", "teacher/threshold")]
    assert set(threshold[reached:]) == {threshold[reached]}
