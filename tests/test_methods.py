"""End-to-end tiny runs of every baseline (``algo=<method>``): the off-policy ones with ``sail_td3.py``, GAIL and
POfD with ``gail.py``, BC with ``bc.py``; ``resume=auto``; bad input, and a method given to another family's script."""

from __future__ import annotations

import json
import math
import shutil

import pytest
from example_runner import evaluate, fail_in_process, read_scalar, run, saved
from test_example import HOPPER, TINY

COMMON = [
    "env=Hopper-v4",
    "collector.total_frames=2000",
    "logger.backends=[csv]",
    "checkpoint.every_frames=1000",
    *TINY,
]


def outputs_written(run_dir, algo, frames):
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["algo"] == algo and summary["frames"] == frames
    assert (run_dir / "config.yaml").exists() and (run_dir / "checkpoint" / "manifest.json").exists()
    assert (run_dir / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert read_scalar(run_dir, "eval/return")
    return summary


# dac_published at test scale: its actor starts at gradient step 60 (of 50 per 1000 frames) and its lr
# halves every 1000 frames; on the frame cadence, whose counts are known in advance (its own cadence,
# after each episode, is tests/test_loop.py's EpisodeCadence)
EXTRA = {
    "dac_published": [
        "optim.actor_updates_after=60",
        "optim.actor_lr_decay.every_frames=1000",
        "optim.cadence=frames",
        "optim.block_order=td3_first",
        "optim.start_frames=null",
    ]
}


def test_dac_published_runs_the_releases_loop(tmp_path, teacher_dir):
    """Kostrikov et al.'s loop end to end (its own cadence, D first, learning from 1000 frames, random
    episodes until the actor starts), small networks: after each episode as many D steps as TD3 steps,
    each count one per frame of the episodes that ended from 1000 frames on; the actor at every 2nd
    step from the first even step past optim.actor_updates_after."""
    run_dir = tmp_path / "dac_published"
    small = [f"network.{net}_cells=[64,64]" for net in ("actor", "critic", "discriminator")]
    overrides = [f"teacher.path={teacher_dir / HOPPER}", "optim.actor_updates_after=101", *small]
    # TINY's block sizes would change the method's one D step and one TD3 step per frame, and its
    # batches its 50-frame collection: not used here
    mine = ("optim.updates_per_train", "optim.discriminator.steps", "collector.frames_per_batch")
    loop_settings = [o for o in TINY if not o.startswith(mine)]
    common = ["env=Hopper-v4", "collector.total_frames=1600", "logger.backends=[csv]", "checkpoint.every_frames=1000"]
    run(run_dir, "algo=dac_published", *common, *loop_settings, *overrides)
    summary = outputs_written(run_dir, "dac_published", 1600)
    steps = summary["gradient_steps"]
    # the frames of the episodes that ended from 1000 frames on (the first of them began before 1000:
    # random Hopper episodes last tens of frames), the last episode unfinished
    assert 0 < steps <= 1600 - 1000 + 200
    optimizer_steps = {
        name: int(saved(run_dir, f"optim_{name}")[f"optim_{name}"]["state"][0]["step"])
        for name in ("critic", "discriminator", "actor")
    }
    assert optimizer_steps == {"critic": steps, "discriminator": steps, "actor": steps // 2 - 50}  # 102, 104, ...


@pytest.mark.parametrize("algo", ["dac", "dac_published", "ddpgfd", "pofd_td3", "td3_delayed", "sail_rnd", "sail_sac"])
def test_td3_baselines_run(tmp_path, teacher_dir, algo):
    run_dir = tmp_path / algo
    run(run_dir, f"algo={algo}", f"teacher.path={teacher_dir / HOPPER}", *COMMON, *EXTRA.get(algo, []))
    summary = outputs_written(run_dir, algo, 2000)
    assert summary["gradient_steps"] == 100 and summary["num_promoted"] == 0  # nothing beats C this early
    alphas = {value for _, value in read_scalar(run_dir, "alpha")}
    trains_d = (run_dir / "logs" / "scalars" / "d").exists()
    if algo == "ddpgfd":  # prioritized demonstrations, env reward, no D, + the n-step loss
        assert not trains_d and read_scalar(run_dir, "sail/env_reward_mean")
        assert read_scalar(run_dir, "sail/loss_qvalue_nstep")
        shares = [share for _, share in read_scalar(run_dir, "sail/teacher_share")]
        assert shares and all(0 < share < 1 for share in shares)  # the priorities' share, not a fixed half
        weights = [weight for _, weight in read_scalar(run_dir, "sail/priority_weight_mean")]
        assert len(weights) == len(shares) and all(0 < weight <= 1 for weight in weights)  # (v_i / min v)^-beta
        # one priority per demonstration row (425) and stored agent row, set by the steps
        leaves = saved(run_dir, "replay_priorities")["replay_priorities"]["leaves"]
        assert leaves.shape == (425 + 2000 - 10,) and leaves.unique().numel() > 100
        assert saved(run_dir, "optim_critic")["optim_critic"]["param_groups"][0]["weight_decay"] == 1e-5
    elif algo == "td3_delayed":
        assert alphas == {0.0} and not trains_d and read_scalar(run_dir, "sail/env_reward_mean")
    elif algo == "sail_rnd":  # SAIL's alpha, D, and a predictor trained beside D
        assert alphas == {0.5} and trains_d and read_scalar(run_dir, "sail/d_reward_mean")
        assert len(read_scalar(run_dir, "rnd/loss_predictor")) >= 2 and read_scalar(run_dir, "train/intrinsic_reward")
        rnd = saved(run_dir, "rnd")["rnd"]
        assert rnd["_obs_rms.count"] >= 2000  # the training env's statistics, one update per step
    elif algo == "sail_sac":  # SAIL's alpha and D; SAC's temperature fixed at the authors' 0.01
        assert alphas == {0.5} and trains_d and read_scalar(run_dir, "sail/d_reward_mean")
        temperatures = [value for _, value in read_scalar(run_dir, "sail/temperature")]
        assert temperatures and all(t == pytest.approx(0.01) for t in temperatures)
        assert read_scalar(run_dir, "sail/entropy")
        assert "log_alpha" in saved(run_dir, "loss")["loss"]
    else:  # dac, dac_published, pofd_td3: a discriminator, no teacher rows
        assert alphas == {0.0} and trains_d and read_scalar(run_dir, "sail/d_reward_mean")
    replay = saved(run_dir, "replay")["replay"]
    if algo == "dac":
        # the SAIL authors' DAC: one absorbing transition after every termination, each with the
        # indicator set and a random action; the terminal and absorbing rows stay terminated
        data = replay["data"]
        obs, next_obs = data["observation"], data["next"]["observation"]
        absorbing = obs[:, -1] == 1
        assert obs.shape[-1] == 13 and replay["size"] > 2000 and int(absorbing.sum()) == replay["size"] - 2000
        assert (next_obs[absorbing, -1] == 1).all() and data["next"]["terminated"][absorbing].all()
        into = (next_obs[:, -1] == 1) & ~absorbing
        assert int(into.sum()) == int(absorbing.sum()) and data["next"]["terminated"][into].all()
        actions = data["action"][absorbing]
        assert (actions != 0).all() and (actions.abs() <= 1).all() and len(actions.unique(dim=0)) == len(actions)
        # the 425-step demonstration fell: + 1 absorbing transition
        assert read_scalar(run_dir, "teacher/size")[-1][1] == 426
        rewards = [value for _, value in read_scalar(run_dir, "sail/d_reward_mean")]
        assert all(-math.log(0.99) - 1e-6 <= r <= -math.log(0.01) + 1e-6 for r in rewards)  # clipped D
    elif algo == "dac_published":
        # Kostrikov et al.'s absorbing state: bootstrapped through (nothing stays terminated)
        data = replay["data"]
        absorbing = data["observation"][:, -1] == 1
        assert int(absorbing.sum()) == replay["size"] - 2000 > 0 and not data["next"]["terminated"].any()
        assert (data["action"][absorbing] == 0).all()
        # the actor's first update is gradient step 60, in the second block; its lr halves per 1000 frames
        assert [frame for frame, _ in read_scalar(run_dir, "sail/loss_actor")] == [2000]
        lrs = dict(read_scalar(run_dir, "sail/actor_lr"))  # set at each TD3 block, logged until the next
        assert (lrs[1000], lrs[1500], lrs[2000]) == (1e-3, 1e-3, 5e-4)
        d = saved(run_dir, "discriminator")["discriminator"]
        assert not any("obs_norm" in key or "running" in key for key in d)  # D reads raw (s, a)
    elif algo == "ddpgfd":
        # the last 10 frames wait for their lookahead; every stored row (agent and demonstration)
        # has the n-step view of the stream it came from
        assert replay["size"] == 2000 - 10
        assert_nstep_view(replay["data"], complete=False)
        assert_nstep_view(saved(run_dir, "teacher")["teacher"][:425], complete=True)  # the 425-step demonstration
    else:
        assert replay["size"] == 2000

    # resume works for every method: a larger budget continues from the 2000-frame checkpoint
    run(
        run_dir,
        f"algo={algo}",
        f"teacher.path={teacher_dir / HOPPER}",
        *COMMON,
        *EXTRA.get(algo, []),
        "collector.total_frames=3000",
        "resume=auto",
    )
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [1000, 2000, 3000]
    if algo == "dac_published":  # the schedule continues from the frame count
        assert dict(read_scalar(run_dir, "sail/actor_lr"))[3000] == 2.5e-4
    assert json.loads((run_dir / "summary.json").read_text())["gradient_steps"] == 150


def assert_nstep_view(data, *, complete, n=10, gamma=0.99):
    """Stored rows of one env stream, in order: their ("next_n", ...) entries follow from the 1-step ones."""
    reward, done = data["next"]["reward"].squeeze(-1).double(), data["next"]["done"].squeeze(-1)
    view, length = data["next_n"], len(reward)
    for t in range(length if complete else length - n):  # a stored row's last n successors may not be stored yet
        k = 1
        while k < n and not done[t + k - 1]:
            k += 1
        assert view["steps_to_next_obs"][t].item() == k
        expected = sum(gamma**i * reward[t + i] for i in range(k))
        assert abs(view["reward"][t].item() - expected) <= 1e-4 * max(1.0, abs(expected))
        assert (view["observation"][t] == data["next"]["observation"][t + k - 1]).all()
        assert view["terminated"][t].item() == data["next"]["terminated"][t + k - 1].item()
    assert done.any()  # episodes ended inside the checked stream


def test_pofd_td3_reward_is_the_env_reward_plus_the_shaping(tmp_path, teacher_dir):
    # With coef=0 the shaped reward is the env reward: the first TD3 block (1000 frames, before
    # any D step draws from the random stream) samples the same rows as td3_delayed's, and its
    # mean reward is the same (the shaping's arithmetic is tested in test_discriminator_reward).
    first = {}
    for algo, extra in (
        ("pofd_td3", ["algo.reward.coef=0.0", "algo.discriminator_agent_data=replay"]),
        ("td3_delayed", []),
    ):
        run(tmp_path / algo, f"algo={algo}", f"teacher.path={teacher_dir / HOPPER}", *COMMON, *extra)
        first[algo] = read_scalar(
            tmp_path / algo, "sail/env_reward_mean" if algo == "td3_delayed" else "sail/d_reward_mean"
        )[0]
    assert first["pofd_td3"][0] == first["td3_delayed"][0] == 1000
    assert first["pofd_td3"][1] == pytest.approx(first["td3_delayed"][1], rel=1e-6)


def test_bc_is_offline_and_skipped_when_finished(tmp_path, teacher_dir):
    run_dir = tmp_path / "bc"
    args = ["algo=bc", f"teacher.path={teacher_dir / HOPPER}", "algo.bc.epochs=10", "algo.bc.batch_size=64", *COMMON]
    run(run_dir, *args, script="bc.py")
    summary = outputs_written(run_dir, "bc", 0)
    assert summary["offline"] is True and summary["gradient_steps"] == 60  # 10 epochs of 425 // 64 = 6 batches
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [0]
    losses = [value for _, value in read_scalar(run_dir, "bc/loss")]
    assert losses[-1] < losses[0]  # the actor fits the teacher's actions
    assert saved(run_dir, "run")["run"]["gradient_steps"] == 60
    stamp = (run_dir / "summary.json").stat().st_mtime_ns
    proc = run(run_dir, *args, "resume=auto", script="bc.py")
    assert "finished run: skipped" in proc.stdout and (run_dir / "summary.json").stat().st_mtime_ns == stamp
    # evaluate.py loads BC's actor: on the run's eval seed it reproduces the run's evaluation
    evaluate(f"run_dir={run_dir}", "seed=10000", "episodes=1", f"out={tmp_path / 'eval.json'}")
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["dense_return"]["mean"] == pytest.approx(summary["final_eval_return"], rel=1e-6)
    [(_, lowest)] = read_scalar(run_dir, "eval/min_return")  # one episode: its return is the minimum
    assert lowest == pytest.approx(result["dense_return"]["min"], rel=1e-6)
    assert read_scalar(run_dir, "eval/below_teacher") == [(0, 1.0)]  # 10 epochs: below the teacher's 1480.7


def norm_count(run_dir) -> int:
    """How many observations (resets and steps) the training env's normaliser has seen, per the checkpoint."""
    return int(saved(run_dir, "observation_norm")["observation_norm"]["_extra_state"]["count.-|-.observation"])


def test_gail_runs_on_policy_and_resumes(tmp_path, teacher_dir):
    run_dir = tmp_path / "gail"
    args = [
        "algo=gail",
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "algo.ppo.frames_per_batch=512",
        # D's own normaliser (TorchRL's GAIL D has none) shows which observations D saw, below
        "network.normalize_observations=true",
        "eval.every_frames=1024",
        "eval.episodes=1",
        "checkpoint.every_frames=1024",
        "logger.backends=[csv]",
        "resume=auto",
    ]
    run(run_dir, *args, "collector.total_frames=2048", script="gail.py")
    summary = outputs_written(run_dir, "gail", 2048)
    assert summary["gradient_steps"] == 4 * 10 * 8  # batches x PPO epochs x minibatches of 64
    assert read_scalar(run_dir, "d/loss_discriminator") and read_scalar(run_dir, "ppo/loss_objective")
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [1024, 2048]
    # TorchRL's lr annealing: the k-th of 320 updates (4 batches x 10 epochs x 8 minibatches) runs at
    # 3e-4 * (1 - (k - 1) / 320); logged at each batch's last update, saved with the optimizer
    assert read_scalar(run_dir, "ppo/lr") == [
        (512 * b, pytest.approx(3e-4 * (1 - (80 * b - 1) / 320), rel=1e-9)) for b in (1, 2, 3, 4)
    ]
    assert [group["lr"] for group in saved(run_dir, "optim_ppo")["optim_ppo"]["param_groups"]] == [
        pytest.approx(3e-4 / 320, rel=1e-9)
    ] * 2  # the actor's and the critic's
    # The training env's normaliser is checkpointed: 2048 steps and one update per reset
    count = norm_count(run_dir)
    assert 2048 < count < 2048 + 2048
    # D compares raw observations with the teacher's: every row it saw (teacher and agent) has a
    # Hopper height z > 0.7 (the healthy range: a root observation never terminated), so its running
    # mean of z is > 0.7 with a small spread; normalised agent rows (z near 0 +- 1) give 0.60 and 0.62
    d = saved(run_dir, "discriminator")["discriminator"]
    n = d["module.obs_norm.count"]
    mean = d["module.obs_norm.sum"][0] / n
    std = (d["module.obs_norm.sumsq"][0] / n - mean**2).sqrt()
    assert 2048 <= n < 2049 and mean > 0.7 and std < 0.5  # 4 batches x 1 D step x (256 teacher + 256 agent rows)

    run(run_dir, *args, "collector.total_frames=3072", script="gail.py")  # continued from the 2048-frame checkpoint
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [1024, 2048, 3072]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["gradient_steps"] == 6 * 10 * 8
    # the budget grew to 480 updates: the 480th runs at 3e-4 / 480
    assert read_scalar(run_dir, "ppo/lr")[-1] == (3072, pytest.approx(3e-4 / 480, rel=1e-9))
    # the resumed run went on from the saved statistics: + 1024 steps + its first reset (and any
    # others); restarted from scratch it would hold at most 1 + 1024 + 1024 < count + 1024
    assert count + 1024 < norm_count(run_dir) <= count + 2048
    # evaluate.py loads the PPO actor and the frozen statistics of the last checkpoint: on the run's
    # eval seed it reproduces the run's final evaluation (the resumed run's first, on a fresh eval env)
    evaluate(f"run_dir={run_dir}", "seed=10000", "episodes=1", f"out={tmp_path / 'eval.json'}")
    result = json.loads((tmp_path / "eval.json").read_text())
    assert result["algo"] == "gail" and result["checkpoint_frames"] == 3072 and result["length"]["values"][0] >= 1
    assert result["dense_return"]["mean"] == pytest.approx(summary["final_eval_return"], rel=1e-6)


def test_pofd_is_ppo_on_the_shaped_delayed_reward(tmp_path, teacher_dir):
    run_dir = tmp_path / "pofd"
    run(
        run_dir,
        "algo=pofd",
        "env=Hopper-v4",
        f"teacher.path={teacher_dir / HOPPER}",
        "algo.ppo.frames_per_batch=256",
        "algo.ppo.epochs=1",
        "algo.reward.coef_decay=0.5",
        "collector.total_frames=1024",
        "eval.every_frames=1024",
        "eval.episodes=1",
        "checkpoint.every_frames=1024",
        "logger.backends=[csv]",
        script="gail.py",
    )
    summary = outputs_written(run_dir, "pofd", 1024)
    assert summary["gradient_steps"] == 4 * 1 * 4  # batches x PPO epochs x minibatches of 64
    # lambda_1 = 0.1 * 0.5^i at the i-th batch
    assert read_scalar(run_dir, "pofd/lambda_1") == [(256, 0.1), (512, 0.05), (768, 0.025), (1024, 0.0125)]
    # PPO learns from the delayed env reward plus lambda_1 * -log(1 - D) > 0 (the shaping's
    # arithmetic is tested in test_discriminator_reward): above the env reward in every batch
    env, shaped = read_scalar(run_dir, "sail/env_reward_mean"), read_scalar(run_dir, "sail/d_reward_mean")
    assert [frame for frame, _ in env] == [frame for frame, _ in shaped] == [256, 512, 768, 1024]
    assert any(value > 0 for _, value in env)  # episodes ended: the delayed reward came
    assert all(s > e for (_, e), (_, s) in zip(env, shaped, strict=True))
    assert saved(run_dir, "observation_norm")


def test_ddpgfd_with_collector_batches_shorter_than_n(tmp_path, teacher_dir):
    """A batch of 5 frames with n = 10: the first one's transitions all wait for their n-step view."""
    run_dir = tmp_path / "short_batches"
    run(
        run_dir,
        "algo=ddpgfd",
        f"teacher.path={teacher_dir / HOPPER}",
        *COMMON,
        "collector.total_frames=300",
        "collector.init_random_frames=100",
        "collector.frames_per_batch=5",
        "optim.train_every_frames=100",
        "eval.every_frames=300",
        "checkpoint.every_frames=0",
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["frames"] == 300 and summary["gradient_steps"] == 150  # at 100, 200 and 300 frames
    # every collected transition reached the replay once its n steps were in (or its episode ended)
    assert saved(run_dir, "replay")["replay"]["size"] >= 300 - 10


def test_resume_auto_continues_skips_and_restarts(tmp_path, teacher_dir):
    run_dir = tmp_path / "run"
    args = ["algo=ddpgfd", f"teacher.path={teacher_dir / HOPPER}", *COMMON, "resume=auto"]
    run(run_dir, *args)  # no folder yet: a fresh run
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [1000, 2000]
    proc = run(run_dir, *args)  # finished: skipped
    assert "finished run: skipped" in proc.stdout
    run(run_dir, *args, "collector.total_frames=3000")  # a larger budget: continued from the checkpoint
    assert [frame for frame, _ in read_scalar(run_dir, "eval/return")] == [1000, 2000, 3000]
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
    assert [frame for frame, _ in read_scalar(fresh, "eval/return")] == [1000, 2000]


@pytest.mark.parametrize(
    "overrides, message, script",
    [
        (["algo=gaail"], "Could not find 'algo/gaail'", "sail_td3.py"),
        (
            ["algo=dac", "algo.adaptive=true"],
            "algo.absorbing_state=True: absorbing states need a fixed teacher",
            "sail_td3.py",
        ),
        (
            ["algo.reward.source=dense"],
            "Invalid value 'dense', expected one of [discriminator, env, shaped]",
            "sail_td3.py",
        ),
        (["algo.reward.kind=wgan"], "full_key: algo.reward.kind", "sail_td3.py"),
        (["algo=sail_rnd", "collector.num_workers=2"], "use collector.num_workers=1", "sail_td3.py"),
        (["algo=sail_sac", "optim.precision=bf16"], "bf16 is TD3's fused step only", "sail_td3.py"),
        (["algo=bc", "algo.bc.batch_size=0"], "algo.bc.batch_size=0", "bc.py"),
        (["algo=gail", "algo.ppo.epochs=0"], "algo.ppo.epochs=0", "gail.py"),
        (["resume=maybe"], "resume='maybe'", "sail_td3.py"),
    ],
)
def test_bad_method_config_fails_before_training(tmp_path, teacher_dir, overrides, message, script):
    error = fail_in_process(
        tmp_path / "run",
        *overrides,
        f"teacher.path={teacher_dir / HOPPER}",
        "collector.total_frames=1000",
        script=script,
    )
    assert message in error, error
    assert not (tmp_path / "run" / "checkpoint").exists()


@pytest.mark.parametrize(
    "script, algo, runs_it",
    [
        ("sail_td3.py", "gail", "gail.py"),
        ("sail_td3.py", "pofd", "gail.py"),
        ("sail_td3.py", "bc", "bc.py"),
        ("gail.py", "sail", "sail_td3.py"),
        ("gail.py", "bc", "bc.py"),
        ("bc.py", "dac", "sail_td3.py"),
        ("bc.py", "pofd", "gail.py"),
        ("gail.py", None, "sail_td3.py"),
        ("bc.py", None, "sail_td3.py"),  # no algo=: config.yaml's default, sail
    ],
)
def test_a_method_of_another_family_names_its_script(tmp_path, script, algo, runs_it):
    # One entry point per family: a script given another family's method says which script runs it,
    # before the run folder gets anything.
    error = fail_in_process(tmp_path / "run", *([f"algo={algo}"] if algo else []), script=script)
    assert f"ValueError: examples/{script} runs " in error, error
    assert f"run python examples/{runs_it} algo={algo or 'sail'} with the same overrides" in error, error
    assert not any((tmp_path / "run").iterdir())


@pytest.mark.parametrize("algo, script", [("bc", "bc.py"), ("dac", "sail_td3.py"), ("gail", "gail.py")])
def test_method_without_a_teacher_is_refused(tmp_path, algo, script):
    # InvertedPendulum has no shipped teacher: every method that needs one says how to get one.
    error = fail_in_process(
        tmp_path / "run", f"algo={algo}", "env=InvertedPendulum-v4", "collector.total_frames=1000", script=script
    )
    assert "No teacher.path given" in error, error
    assert not (tmp_path / "run" / "checkpoint").exists()
