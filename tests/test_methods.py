"""End-to-end tiny runs of every baseline of ``sail_td3.py`` (``algo=<method>``), ``resume=auto``, bad input."""
from __future__ import annotations

import json
import shutil

import pytest
from example_runner import evaluate, fail_in_process, run, saved, scalar
from test_example import HOPPER, TINY

COMMON = ["env=Hopper-v4", "collector.total_frames=2000", "logger.backends=[csv]", "checkpoint.every_frames=1000",
          *TINY]


def outputs_written(run_dir, algo, frames):
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["algo"] == algo and summary["frames"] == frames
    assert (run_dir / "config.yaml").exists() and (run_dir / "checkpoint" / "manifest.json").exists()
    assert (run_dir / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert scalar(run_dir, "eval/return")
    return summary


@pytest.mark.parametrize("algo", ["dac", "ddpgfd", "pofd", "td3_delayed", "sail_rnd", "sail_sac"])
def test_td3_baselines_run(tmp_path, teacher_dir, algo):
    run_dir = tmp_path / algo
    run(run_dir, f"algo={algo}", f"teacher.path={teacher_dir / HOPPER}", *COMMON)
    summary = outputs_written(run_dir, algo, 2000)
    assert summary["gradient_steps"] == 100 and summary["num_promoted"] == 0  # nothing beats C this early
    alphas = {value for _, value in scalar(run_dir, "alpha")}
    trains_d = (run_dir / "logs" / "scalars" / "d").exists()
    if algo == "ddpgfd":  # demonstrations in half of every batch, env reward, no D
        assert alphas == {0.5} and not trains_d and scalar(run_dir, "sail/env_reward_mean")
    elif algo == "td3_delayed":
        assert alphas == {0.0} and not trains_d and scalar(run_dir, "sail/env_reward_mean")
    elif algo == "sail_rnd":  # SAIL's alpha, D, and a predictor trained beside D
        assert alphas == {0.5} and trains_d and scalar(run_dir, "sail/d_reward_mean")
        assert len(scalar(run_dir, "rnd/loss_predictor")) >= 2 and scalar(run_dir, "train/intrinsic_reward")
        rnd = saved(run_dir, "rnd")["rnd"]
        assert rnd["_obs_rms.count"] >= 2000  # the training env's statistics, one update per step
    elif algo == "sail_sac":  # SAIL's alpha and D; SAC's temperature learned beside them
        assert alphas == {0.5} and trains_d and scalar(run_dir, "sail/d_reward_mean")
        temperatures = [value for _, value in scalar(run_dir, "sail/temperature")]
        assert temperatures and temperatures[-1] != 1.0 and scalar(run_dir, "sail/entropy")
        assert "log_alpha" in saved(run_dir, "loss")["loss"]
    else:  # dac, pofd: a discriminator, no teacher rows
        assert alphas == {0.0} and trains_d and scalar(run_dir, "sail/d_reward_mean")
    replay = saved(run_dir, "replay")["replay"]
    if algo == "dac":
        # one absorbing transition after every termination, each with the indicator set
        obs, next_obs = replay["data"]["observation"], replay["data"]["next"]["observation"]
        absorbing = obs[:, -1] == 1
        assert obs.shape[-1] == 13 and replay["size"] > 2000 and int(absorbing.sum()) == replay["size"] - 2000
        assert (next_obs[absorbing, -1] == 1).all() and not replay["data"]["next"]["terminated"].any()
        # the 425-step demonstration fell: + 1 absorbing transition
        assert scalar(run_dir, "teacher/size")[-1][1] == 426
    else:
        assert replay["size"] == 2000

    # resume works for every method: a larger budget continues from the 2000-frame checkpoint
    run(run_dir, f"algo={algo}", f"teacher.path={teacher_dir / HOPPER}", *COMMON, "collector.total_frames=3000",
        "resume=auto")
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [1000, 2000, 3000]
    assert json.loads((run_dir / "summary.json").read_text())["gradient_steps"] == 150


def test_pofd_reward_is_the_env_reward_plus_the_shaping(tmp_path, teacher_dir):
    # With coef=0 the shaped reward is the env reward: the first TD3 block (1000 frames, before
    # any D step draws from the random stream) samples the same rows as td3_delayed's, and its
    # mean reward is the same (the shaping's arithmetic is tested in test_discriminator_reward).
    first = {}
    for algo, extra in (("pofd", ["algo.reward.coef=0.0", "algo.discriminator_agent_data=replay"]),
                        ("td3_delayed", [])):
        run(tmp_path / algo, f"algo={algo}", f"teacher.path={teacher_dir / HOPPER}", *COMMON, *extra)
        first[algo] = scalar(tmp_path / algo, "sail/env_reward_mean" if algo == "td3_delayed" else "sail/d_reward_mean")[0]
    assert first["pofd"][0] == first["td3_delayed"][0] == 1000
    assert first["pofd"][1] == pytest.approx(first["td3_delayed"][1], rel=1e-6)


def test_bc_is_offline_and_skipped_when_finished(tmp_path, teacher_dir):
    run_dir = tmp_path / "bc"
    args = ["algo=bc", f"teacher.path={teacher_dir / HOPPER}", "algo.bc.epochs=10", *COMMON]
    run(run_dir, *args)
    summary = outputs_written(run_dir, "bc", 0)
    assert summary["offline"] is True and summary["gradient_steps"] == 67  # ceil(10 * 425 / 64)
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [0]
    losses = [value for _, value in scalar(run_dir, "bc/loss")]
    assert losses[-1] < losses[0]  # the actor fits the teacher's actions
    assert saved(run_dir, "run")["run"]["gradient_steps"] == 67
    stamp = (run_dir / "summary.json").stat().st_mtime_ns
    proc = run(run_dir, *args, "resume=auto")
    assert "finished run: skipped" in proc.stdout and (run_dir / "summary.json").stat().st_mtime_ns == stamp
    # evaluate.py loads BC's actor: on the run's eval seed it reproduces the run's evaluation
    evaluate(f"run_dir={run_dir}", "seed=10000", "episodes=1", f"out={tmp_path / 'eval.json'}")
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["dense_return"]["mean"] == pytest.approx(summary["final_eval_return"], rel=1e-6)


def test_gail_runs_on_policy_and_resumes(tmp_path, teacher_dir):
    run_dir = tmp_path / "gail"
    args = ["algo=gail", "env=Hopper-v4", f"teacher.path={teacher_dir / HOPPER}", "algo.ppo.frames_per_batch=512",
            "eval.every_frames=1024", "eval.episodes=1", "checkpoint.every_frames=1024", "logger.backends=[csv]",
            "resume=auto"]
    run(run_dir, *args, "collector.total_frames=2048")
    summary = outputs_written(run_dir, "gail", 2048)
    assert summary["gradient_steps"] == 4 * 10 * 8  # batches x PPO epochs x minibatches of 64
    assert scalar(run_dir, "d/loss_discriminator") and scalar(run_dir, "ppo/loss_objective")
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [1024, 2048]
    run(run_dir, *args, "collector.total_frames=3072")  # continued from the 2048-frame checkpoint
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [1024, 2048, 3072]
    assert json.loads((run_dir / "summary.json").read_text())["gradient_steps"] == 6 * 10 * 8
    # evaluate.py loads the PPO actor of the last checkpoint
    evaluate(f"run_dir={run_dir}", "episodes=1", f"out={tmp_path / 'eval.json'}")
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["algo"] == "gail" and result["checkpoint_frames"] == 3072 and result["length"]["values"][0] >= 1


def test_resume_auto_continues_skips_and_restarts(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    args = ["algo=ddpgfd", f"teacher.path={teacher_dir / HOPPER}", *COMMON, "resume=auto"]
    run(run_dir, *args)  # no folder yet: a fresh run
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [1000, 2000]
    proc = run(run_dir, *args)  # finished: skipped
    assert "finished run: skipped" in proc.stdout
    run(run_dir, *args, "collector.total_frames=3000")  # a larger budget: continued from the checkpoint
    assert [frame for frame, _ in scalar(run_dir, "eval/return")] == [1000, 2000, 3000]
    assert json.loads((run_dir / "summary.json").read_text())["frames"] == 3000

    # A finished run committed without its checkpoint (as in benchmarks/results/) is skipped, and
    # asking it for more frames than it has is refused (nothing to continue from).
    shutil.rmtree(run_dir / "checkpoint")
    assert "finished run: skipped" in run(run_dir, *args, "collector.total_frames=3000").stdout
    proc = run(run_dir, *args, "collector.total_frames=4000", check=False)
    assert proc.returncode != 0 and "no checkpoint to extend it" in proc.stderr

    # A run that stopped before its first checkpoint: its logs are dropped and it starts over.
    fresh = tmp_path / "fresh"
    (fresh / "logs" / "scalars" / "eval").mkdir(parents=True)
    (fresh / "logs" / "scalars" / "eval" / "return.csv").write_text("500,1.0\n")
    run(fresh, *args)
    assert [frame for frame, _ in scalar(fresh, "eval/return")] == [1000, 2000]


@pytest.mark.parametrize(
    "overrides, message",
    [
        (["algo=gaail"], "Could not find 'algo/gaail'"),
        (["algo=dac", "algo.adaptive=true"], "algo.absorbing_state=True: absorbing states need a fixed teacher"),
        (["algo.reward.source=dense"], "Invalid value 'dense', expected one of [discriminator, env, shaped]"),
        (["algo.reward.kind=wgan"], "full_key: algo.reward.kind"),
        (["algo=sail_rnd", "collector.num_workers=2"], "use collector.num_workers=1"),
        (["algo=sail_sac", "optim.precision=bf16"], "bf16 is TD3's fused step only"),
        (["algo=bc", "algo.bc.batch_size=0"], "algo.bc.batch_size=0"),
        (["resume=maybe"], "resume='maybe'"),
    ],
)
def test_bad_method_config_fails_before_training(tmp_path, teacher_dir, overrides, message):
    error = fail_in_process(tmp_path / "run", *overrides, f"teacher.path={teacher_dir / HOPPER}",
                            "collector.total_frames=1000")
    assert message in error, error
    assert not (tmp_path / "run" / "checkpoint").exists()


@pytest.mark.parametrize("algo", ["bc", "dac", "gail"])
def test_method_without_a_teacher_is_refused(tmp_path, algo):
    # InvertedPendulum has no shipped teacher: every method that needs one says how to get one.
    error = fail_in_process(tmp_path / "run", f"algo={algo}", "env=InvertedPendulum-v4", "collector.total_frames=1000")
    assert "No teacher.path given" in error, error
    assert not (tmp_path / "run" / "checkpoint").exists()
