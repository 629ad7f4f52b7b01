"""examples/evaluate.py and videos: a run's checkpoint evaluated, a video written and decoded."""

from __future__ import annotations

import ctypes.util
import json
import math
import os
import sys

import pytest
from example_runner import REPO, evaluate, run

imageio = pytest.importorskip("imageio.v3", reason="videos need imageio (pip install -e '.[video]')")
pytest.importorskip("imageio_ffmpeg", reason="MP4 videos need imageio-ffmpeg (pip install -e '.[video]')")

EGL = {"MUJOCO_GL": "egl"}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """2000 frames of SAIL on Hopper with the shipped teacher: one evaluation of the actor (evaluated and
    kept, not SAIL's default target actor), one of its target actor and one of its averaged actor
    (500-frame memory), and one video, at the end."""
    run_dir = tmp_path_factory.mktemp("evaluate") / "run"
    run(
        run_dir,
        "env=Hopper-v4",
        "collector.total_frames=2000",
        "collector.init_random_frames=1000",
        "optim.updates_per_train=50",
        "optim.discriminator.steps=2",
        "eval.every_frames=2000",
        "eval.episodes=2",
        "eval.actor=online",
        "eval.other_actor=true",
        "eval.average_frames=500",
        "eval.best_policy.episodes=2",
        "checkpoint.every_frames=1000",
        "eval.video_every_frames=2000",
        "logger.backends=[csv]",
        env=EGL,
    )
    return run_dir


def test_training_records_a_video(trained):
    frames = imageio.imread(trained / "videos" / "eval_2000.mp4", plugin="FFMPEG")
    assert frames.shape[1:] == (240, 320, 3) and len(frames) >= 2  # the reset frame and >= 1 step
    assert frames.std() > 5  # a rendered scene, not a blank image


def test_evaluate_reproduces_the_runs_own_evaluation(trained):
    """On the training eval env's seed (run seed + 10000) the checkpoint's actor gives the logged eval return."""
    summary = json.loads((trained / "summary.json").read_text())
    proc = evaluate(f"run_dir={trained}", "episodes=2", "seed=10000", "out=" + str(trained / "same_seed.json"))
    result = json.loads((trained / "same_seed.json").read_text())
    assert result["dense_return"]["mean"] == pytest.approx(summary["final_eval_return"], rel=1e-6)
    assert result["checkpoint_frames"] == 2000 and result["episodes"] == 2 and result["seed"] == 10000
    assert "dense return" in proc.stdout and "delayed reward r_e" in proc.stdout


def test_evaluate_plays_at_once_or_one_after_another(trained, tmp_path):
    """The run's evaluations were batched (eval.vectorized, the default): evaluate.py plays its episodes
    at once too, unless vectorized=false says one after another on one env; either way episode 0
    starts where one env seeded `seed` starts (the video's episode), so it is the same episode."""
    evaluate(f"run_dir={trained}", "episodes=2", "seed=10000", f"out={tmp_path / 'at_once.json'}")
    evaluate(f"run_dir={trained}", "episodes=2", "seed=10000", "vectorized=false", f"out={tmp_path / 'one.json'}")
    at_once, one = (json.loads((tmp_path / f"{name}.json").read_text()) for name in ("at_once", "one"))
    assert at_once["vectorized"] is True and one["vectorized"] is False
    assert one["dense_return"]["values"][0] == pytest.approx(at_once["dense_return"]["values"][0], rel=1e-5)
    assert one["length"]["values"][0] == at_once["length"]["values"][0]
    # episode 1: the second episode of env 10000 against the first of env 10001
    assert one["dense_return"]["values"][1] != pytest.approx(at_once["dense_return"]["values"][1], rel=1e-3)


def test_target_actor_has_the_checkpoints_target_weights(trained):
    import torch
    from example_runner import saved
    from tensordict import TensorDict

    sys.path.insert(0, str(REPO / "examples"))
    from evaluate import load_actor, load_run
    from utils import make_env

    from torchrl_sail.harness import checkpoint_dir

    cfg, _ = load_run(trained)
    state = saved(trained, "loss")["loss"]
    for which, prefix in (("online", "actor_network_params."), ("target", "target_actor_network_params.")):
        actor = load_actor(cfg, make_env(cfg, 0), checkpoint_dir(trained), which)
        weights = TensorDict.from_module(actor).flatten_keys(".")
        assert len(weights.keys()) == 8  # three linear layers' weights and biases, the action bounds
        for key, value in weights.items():
            torch.testing.assert_close(value.data, state[prefix + key], rtol=0, atol=0)
    # 2000 frames of training (tau = 0.005) leave the target actor behind the actor
    first_layer = "actor_network_params.module.0.module.0.weight"
    assert not torch.equal(state[first_layer], state["target_" + first_layer])


def test_training_evaluates_the_target_actor_on_the_evaluations_start_states(trained, tmp_path):
    """eval.other_actor: the logged eval/return_target is evaluate.py's actor=target on the training
    eval env's seed (run seed + 10000), and eval/return stays the actor's (the test above)."""
    from example_runner import read_scalar

    [(frames, logged)] = read_scalar(trained, "eval/return_target")
    [(_, online)] = read_scalar(trained, "eval/return")
    evaluate(f"run_dir={trained}", "episodes=2", "seed=10000", "actor=target", f"out={tmp_path / 'target.json'}")
    result = json.loads((tmp_path / "target.json").read_text())
    assert frames == 2000 and result["checkpoint_frames"] == 2000
    assert result["dense_return"]["mean"] == pytest.approx(logged, rel=1e-6) and logged != online
    [(_, lowest)] = read_scalar(trained, "eval/min_return_target")
    assert lowest == pytest.approx(result["dense_return"]["min"], rel=1e-6)
    [(_, below)] = read_scalar(trained, "eval/below_teacher_target")
    assert below == 1.0  # 2000 frames of training: both episodes below the Hopper teacher's 1480.7


def test_training_evaluates_the_averaged_actor_and_evaluate_loads_it(trained, tmp_path):
    """eval.average_frames with eval.other_actor: the logged eval/return_average is evaluate.py's
    actor=average on the training eval env's seed, whose weights are the checkpoint's average, which
    is neither the actor nor its target actor."""
    import torch
    from example_runner import read_scalar, saved
    from tensordict import TensorDict

    sys.path.insert(0, str(REPO / "examples"))
    from evaluate import load_actor, load_run
    from utils import make_env

    from torchrl_sail.harness import checkpoint_dir

    [(frames, logged)] = read_scalar(trained, "eval/return_average")
    evaluate(f"run_dir={trained}", "episodes=2", "seed=10000", "actor=average", f"out={tmp_path / 'average.json'}")
    result = json.loads((tmp_path / "average.json").read_text())
    assert frames == 2000 and result["actor"] == "average"
    assert result["dense_return"]["mean"] == pytest.approx(logged, rel=1e-6)
    cfg, _ = load_run(trained)
    average = saved(trained, "actor_average")["actor_average"]["weights"]
    weights = TensorDict.from_module(load_actor(cfg, make_env(cfg, 0), checkpoint_dir(trained), "average"))
    for key, value in weights.flatten_keys(".").items():
        torch.testing.assert_close(value.data, average[key], rtol=0, atol=0)
    loss = saved(trained, "loss")["loss"]
    first_layer = "module.0.module.0.weight"
    for prefix in ("actor_network_params.", "target_actor_network_params."):
        assert not torch.equal(average[first_layer], loss[prefix + first_layer])


def test_evaluate_reproduces_the_best_policys_evaluation(trained, tmp_path):
    """The summary's best-policy figure is evaluate.py's policy=best on the same episodes (seed + 20000),
    and the kept weights are the actor's at that frame, not the last checkpoint's."""
    summary = json.loads((trained / "summary.json").read_text())
    best = summary["best_policy"]
    assert best["actor"] == "online" and best["episodes"] == 2 and best["window"] == 100
    assert best["frames"] % 500 == 0 and 0 < best["frames"] <= 2000
    evaluate(f"run_dir={trained}", "policy=best", "episodes=2", f"out={tmp_path / 'best.json'}")
    result = json.loads((tmp_path / "best.json").read_text())
    assert result["policy"] == "best" and result["policy_frames"] == best["frames"] and result["seed"] == 20000
    assert result["dense_return"]["mean"] == pytest.approx(best["eval_return"], rel=1e-6)


def test_evaluate_reproduces_the_best_evaluated_policys_evaluation(trained, tmp_path):
    """The run's one evaluation (at 2000 frames) keeps the best evaluated policy; the summary's figure
    for it is evaluate.py's policy=best_evaluated on seed + 20000, and a run without the file is refused."""
    summary = json.loads((trained / "summary.json").read_text())
    best = summary["best_evaluated_policy"]
    assert (best["frames"], best["periodic_eval_return"]) == (2000, summary["final_eval_return"])
    assert best["actor"] == "online" and best["episodes"] == 2 and best["seed"] == 20000
    proc = evaluate(f"run_dir={trained}", "policy=best_evaluated", "episodes=2", f"out={tmp_path / 'b.json'}")
    result = json.loads((tmp_path / "b.json").read_text())
    assert result["policy"] == "best_evaluated" and result["policy_frames"] == 2000
    assert result["dense_return"]["mean"] == pytest.approx(best["eval_return"], rel=1e-6)
    assert "best evaluated policy at 2000 frames" in proc.stdout
    (trained / "best_evaluated_policy.pt").rename(tmp_path / "moved.pt")
    try:
        proc = evaluate(f"run_dir={trained}", "policy=best_evaluated", "episodes=1", check=False)
    finally:
        (tmp_path / "moved.pt").rename(trained / "best_evaluated_policy.pt")
    assert proc.returncode != 0 and f"run_dir={trained} has no best_evaluated_policy.pt" in proc.stderr


def test_evaluate_target_actor_and_a_learner_without_one(trained, tmp_path):
    results = {}
    for actor in ("online", "target"):
        proc = evaluate(f"run_dir={trained}", "episodes=1", f"actor={actor}", f"out={tmp_path / actor}.json")
        results[actor] = json.loads((tmp_path / f"{actor}.json").read_text())
        assert results[actor]["actor"] == actor and f"of its {actor} actor" in proc.stdout
    # the same episode (same seed) with other weights: another return
    assert results["online"]["seed"] == results["target"]["seed"]
    assert results["online"]["dense_return"]["values"] != results["target"]["dense_return"]["values"]
    # a run whose learner keeps no target actor is refused, naming the setting and the run
    sac = tmp_path / "sac"
    sac.mkdir()
    (sac / "config.yaml").write_text((trained / "config.yaml").read_text().replace("learner: td3", "learner: sac"))
    from torchrl.checkpoint import Checkpoint

    from torchrl_sail.harness import checkpoint_dir

    Checkpoint(run={"frames": 1000}).save(checkpoint_dir(sac))
    proc = evaluate(f"run_dir={sac}", "episodes=1", "actor=target", check=False)
    assert proc.returncode != 0 and f"actor=target: run_dir={sac} is algo=sail, a sac learner" in proc.stderr
    assert not (sac / "evaluation.json").exists()


def test_evaluate_writes_stats_and_a_video_that_decodes(trained):
    proc = evaluate(f"run_dir={trained}", "episodes=3", "video=true")
    result = json.loads((trained / "evaluation.json").read_text())
    assert result["seed"] == 20_000 and result["env"] == "Hopper-v4" and result["algo"] == "sail"
    assert result["actor"] == "online"
    for key in ("dense_return", "delayed_reward", "length"):
        s = result[key]
        assert len(s["values"]) == 3 and s["min"] <= s["mean"] <= s["max"]
    # r_e = floor(0.1 * dense return), the delayed reward the learner sees
    assert result["delayed_reward"]["values"] == [math.floor(0.1 * r) for r in result["dense_return"]["values"]]
    video = result["video"]
    frames = imageio.imread(trained / "evaluation.mp4", plugin="FFMPEG")
    # the first episode replayed on the rendering env: its reset frame and one frame per step
    assert len(frames) == video["frames"] == result["length"]["values"][0] + 1
    assert video["dense_return"] == pytest.approx(result["dense_return"]["values"][0], rel=1e-6)
    assert video["fps"] == 125 and "evaluation.mp4" in proc.stdout


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is not None, reason="OSMesa is installed here")
def test_missing_gl_library_names_the_variable_and_the_package(trained, tmp_path):
    # MuJoCo loads the MUJOCO_GL backend on import (TorchRL imports MuJoCo): checked before that
    proc = evaluate(
        f"run_dir={trained}", "episodes=1", f"out={tmp_path / 'e.json'}", env={"MUJOCO_GL": "osmesa"}, check=False
    )
    assert proc.returncode != 0 and "MuJoCo cannot load MUJOCO_GL='osmesa'" in proc.stderr
    assert "apt-get install libosmesa6" in proc.stderr and "MUJOCO_GL=egl" in proc.stderr
    assert not (tmp_path / "e.json").exists()


@pytest.mark.skipif(bool(os.environ.get("DISPLAY")), reason="a display is available: glfw can render")
def test_unusable_gl_backend_fails_before_anything_is_written(trained, tmp_path):
    proc = evaluate(
        f"run_dir={trained}",
        "episodes=1",
        "video=true",
        f"out={tmp_path / 'e.json'}",
        env={"MUJOCO_GL": "glfw"},
        check=False,
    )
    assert proc.returncode != 0 and "Cannot render Hopper-v4 with MUJOCO_GL='glfw'" in proc.stderr
    assert "apt-get install libegl1" in proc.stderr
    assert not (tmp_path / "e.json").exists()  # nothing half-written


def test_evaluate_bad_run_dir(tmp_path):
    sys.path.insert(0, str(REPO / "examples"))
    from evaluate import load_run

    with pytest.raises(FileNotFoundError, match=f"run_dir={tmp_path}: no config.yaml"):
        load_run(tmp_path)
    (tmp_path / "config.yaml").write_text("seed: 0\n")
    with pytest.raises(FileNotFoundError, match="no checkpoint/ to evaluate"):
        load_run(tmp_path)


def test_evaluate_reads_a_config_saved_before_newer_settings(tmp_path):
    from torchrl.checkpoint import Checkpoint

    sys.path.insert(0, str(REPO / "examples"))
    from evaluate import load_run
    from utils import make_discriminator, make_discriminator_loss

    from torchrl_sail import make_sail_env
    from torchrl_sail.harness import checkpoint_dir

    # a run saved before the discriminator remedies existed: its config has none of their keys
    saved = REPO / "benchmarks" / "results" / "campaign" / "main" / "paper" / "Hopper-v4" / "sail" / "seed0"
    old = (saved / "config.yaml").read_text()
    assert "label_smoothing" not in old and "discriminator_spectral_norm" not in old
    (tmp_path / "config.yaml").write_text(old)
    Checkpoint(run={"frames": 1000}).save(checkpoint_dir(tmp_path))
    cfg, run = load_run(tmp_path)
    assert run["frames"] == 1000 and cfg.env.name == "Hopper-v4" and cfg.seed == 0
    assert cfg.network.discriminator_spectral_norm is False and cfg.optim.discriminator.max_accuracy is None
    assert cfg.eval.vectorized is False  # as it ran: one env, one episode after another (SAVED_BEFORE)
    discriminator = make_discriminator(cfg, make_sail_env("Hopper-v4"))  # what load_actor builds
    assert make_discriminator_loss(cfg, discriminator).label_smoothing.item() == 0.0


def test_evaluate_exports_the_agents_episodes_to_minari(trained, tmp_path):
    pytest.importorskip("minari", reason="Minari export needs pip install -e '.[minari]'")
    from torchrl_sail import load_demonstrations

    datasets = {"MINARI_DATASETS_PATH": str(tmp_path / "datasets")}
    evaluate(
        f"run_dir={trained}",
        "episodes=2",
        "export=sail/Hopper-v4/agent-v0",
        f"out={tmp_path / 'e.json'}",
        "video=true",
        "video_format=gif",
        "video_size=[160,120]",
        env=datasets,
    )
    result = json.loads((tmp_path / "e.json").read_text())
    # the GIF: the first episode, its reset frame and one per step, at the requested size
    assert imageio.imread(tmp_path / "e.gif", index=None).shape == (result["length"]["values"][0] + 1, 120, 160, 3)
    data, meta = load_demonstrations(tmp_path / "datasets" / "sail" / "Hopper-v4" / "agent-v0")
    # dense rewards recovered from the running return: the episodes' returns, exactly as evaluated
    assert meta["episode_returns"] == pytest.approx(result["dense_return"]["values"], rel=1e-9)
    assert data.numel() == sum(result["length"]["values"]) and data["observation"].shape[-1] == 12
    proc = evaluate(
        f"run_dir={trained}",
        "episodes=1",
        "export=sail/Hopper-v4/agent-v0",
        f"out={tmp_path / 'f.json'}",
        env=datasets,
        check=False,
    )
    assert proc.returncode != 0 and "overwrite" in proc.stderr  # an existing dataset is kept
