"""Evaluate a trained run: deterministic episodes of its last checkpoint or its best policy, and optionally a video.

    python examples/evaluate.py run_dir=outputs/Hopper-v4/sail/seed0
    python examples/evaluate.py run_dir=outputs/Hopper-v4/sail/seed0 policy=best episodes=50
    python examples/evaluate.py run_dir=outputs/Hopper-v4/sail/seed0 policy=best_evaluated episodes=50
    MUJOCO_GL=egl python examples/evaluate.py run_dir=outputs/Hopper-v4/sail/seed0 video=true episodes=20

The run's ``config.yaml`` rebuilds its env and actor (any method: ``sail_td3.py``, ``gail.py``,
``bc.py``), the checkpoint's weights are loaded, and ``episodes`` deterministic episodes run on a
fresh seed (the run's seed + 20000 unless ``seed`` is given), at once on a batched env whose env
``i`` is seeded ``seed + i * SEED_STRIDE`` (``torchrl_sail.envs``) when the run's evaluations were
(``eval.vectorized``; ``vectorized=`` says otherwise), else one after another on one env seeded
``seed``: as the run's own final evaluation of its kept policies, whose figures in ``summary.json``
come back. The dense return (what the paper
reports), the delayed reward r_e (what the learner saw) and the episode length are printed and
written with their mean, std, min and max to ``<run_dir>/evaluation.json``. ``policy=best``
evaluates the policy the run kept as its best by its own training returns (``best_policy.pt``,
the SAIL authors' rule) instead of its last checkpoint, ``policy=best_evaluated`` the policy at its
best periodic evaluation (``best_evaluated_policy.pt``). The actor is the one the run's own
evaluations use (its ``eval.actor``) unless ``actor=online``, ``actor=target`` (a TD3 learner's
target actor, the Polyak average of its recent weights) or ``actor=average`` (the longer average a
run with ``eval.average_frames`` keeps) says otherwise. ``video=true`` replays the
first episode on a rendering env (same seed: the same start) into ``evaluation.mp4`` (or
``.gif``) beside it.
``export=<dataset id>`` writes the evaluated episodes, with their dense rewards, as a local Minari
dataset (``pip install -e '.[minari]'``): the trained agent's own trajectories, shareable and
usable as a teacher (``teacher.path=minari:<dataset id>``).
"""

from __future__ import annotations

from mujoco_gl import check_mujoco_gl

check_mujoco_gl()  # before TorchRL imports MuJoCo, which loads the MUJOCO_GL backend on import

import importlib.util
import json
import statistics
from pathlib import Path

import hydra
import torch
from config_schema import register_config_schema, saved_run_config
from omegaconf import OmegaConf
from run_utils import evaluate_episodes, load_kept_policy, make_actor_average, seed_everything
from torchrl.checkpoint import Checkpoint
from utils import (
    copy_observation_norm,
    make_agent,
    make_discriminator,
    make_env,
    make_eval_env,
    make_losses,
    make_ppo_models,
)
from video import make_render_env, record_episode, video_fps, write_video

from torchrl_sail import observation_normalizer
from torchrl_sail._compat import fast_tensor_outputs
from torchrl_sail.harness import BEST_EVALUATED_POLICY, BEST_POLICY, CONFIG, checkpoint_dir, write_atomic

register_config_schema()

# policy=: the file of each policy a run keeps beside its checkpoint, and how the report names it
KEPT_POLICIES = {"best": BEST_POLICY, "best_evaluated": BEST_EVALUATED_POLICY}
POLICY_LABELS = {"last": "checkpoint", "best": "best policy", "best_evaluated": "best evaluated policy"}


def load_run(run_dir: Path):
    """The run's resolved config and the frames its checkpoint holds; clear errors for a wrong folder."""
    config, checkpoint = run_dir / CONFIG, checkpoint_dir(run_dir)
    if not config.exists():
        raise FileNotFoundError(
            f"run_dir={run_dir}: no config.yaml; point run_dir at a folder written by "
            f"examples/sail_td3.py, gail.py or bc.py (e.g. outputs/Hopper-v4/sail/seed0)"
        )
    if not (checkpoint / "manifest.json").exists():
        raise FileNotFoundError(
            f"run_dir={run_dir}: no checkpoint/ to evaluate (the run stopped before its first "
            f"checkpoint; see checkpoint.every_frames)"
        )
    run = {}
    Checkpoint(run=run).load(checkpoint, components=["run"])
    return saved_run_config(OmegaConf.load(config)), run


def load_actor(cfg, env, checkpoint: Path, which: str = "online", kept_policy: Path | None = None):
    """The run's deterministic actor with the checkpoint's weights (TD3/SAC keep them in the loss).

    A PPO actor reads normalised observations: ``env``'s normaliser gets the training statistics the
    checkpoint holds, frozen. ``which``: the actor by ``eval.actor``'s name, ``online`` (the actor
    itself), ``target`` (a TD3 learner's target actor, the Polyak average of its recent weights) or
    ``average`` (the run's ``eval.average_frames`` average). ``kept_policy``: a TD3/SAC run's
    ``best_policy.pt`` or ``best_evaluated_policy.pt``, whose weights replace the checkpoint's.
    """
    if cfg.algo.learner == "ppo":
        actor, _ = make_ppo_models(cfg, env)
        norm = observation_normalizer(env)  # None for runs without it (algo.ppo.normalize_observations)
        components = {"actor": actor} if norm is None else {"actor": actor, "observation_norm": norm}
        Checkpoint(**components).load(checkpoint, components=list(components))
        if norm is not None:
            norm.freeze()
    elif cfg.algo.learner == "bc":
        actor, _, _ = make_agent(cfg, env)
        Checkpoint(actor=actor).load(checkpoint, components=["actor"])
    else:
        actor, critic, _ = make_agent(cfg, env)
        loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
        Checkpoint(loss=loss).load(checkpoint, components=["loss"])  # the actor's parameters live in the loss
        if kept_policy is not None:
            load_kept_policy(kept_policy, loss, which)
        elif which == "target":
            loss.actor_network_params.data.copy_(loss.target_actor_network_params.data)
        elif which == "average":
            average = make_actor_average(cfg, loss)
            Checkpoint(actor_average=average).load(checkpoint, components=["actor_average"])
            loss.actor_network_params.data.copy_(average.weights)
    return actor.eval()


def episode_transitions(rollout, absorbing_state: bool):
    """A rollout as demonstration transitions: the dense per-step reward back from the running
    dense return (the env's own reward is the delayed one), DAC's absorbing indicator dropped."""
    episode_return = rollout["next", "episode_return"].squeeze(-1)
    dense = torch.diff(episode_return, prepend=episode_return.new_zeros(1)).float().unsqueeze(-1)
    data = rollout.select(
        "observation",
        "action",
        ("next", "observation"),
        ("next", "done"),
        ("next", "terminated"),
        ("next", "truncated"),
    ).clone()
    data["next", "reward"] = dense
    if absorbing_state:
        data["observation"], data["next", "observation"] = (
            data["observation"][..., :-1],
            data["next", "observation"][..., :-1],
        )
    return data


def check_args(args, cfg) -> None:
    """Everything that can fail is checked before the first episode (``cfg``: the run's config)."""
    if args.policy != "last" and cfg.algo.learner not in ("td3", "sac"):
        raise ValueError(
            f"policy={args.policy}: run_dir={args.run_dir} is algo={cfg.algo.name}, a {cfg.algo.learner} learner; "
            f"only the off-policy runs of examples/sail_td3.py keep the policies policy=best and best_evaluated load"
        )
    kept = KEPT_POLICIES.get(str(args.policy))
    if kept is not None and not (Path(args.run_dir) / kept).exists():
        raise FileNotFoundError(
            f"policy={args.policy}: run_dir={args.run_dir} has no {kept} (written at the run's checkpoints once "
            f"it keeps one; runs of versions before it have none): use policy=last"
        )
    if args.actor == "target" and cfg.algo.learner != "td3":
        raise ValueError(
            f"actor=target: run_dir={args.run_dir} is algo={cfg.algo.name}, a {cfg.algo.learner} learner without "
            f"a target actor; only TD3 learners (sail, dac, td3_delayed, ...) keep one"
        )
    if args.actor == "average" and not cfg.eval.average_frames:
        raise ValueError(
            f"actor=average: run_dir={args.run_dir} kept no averaged actor (its eval.average_frames is 0; "
            f"a run keeps one with eval.average_frames=N)"
        )
    if args.episodes < 1:
        raise ValueError(f"episodes={args.episodes}: must be >= 1")
    if args.video:
        if len(args.video_size) != 2 or min(args.video_size) < 16:
            raise ValueError(f"video_size={list(args.video_size)}: must be [width, height], each >= 16")
        if args.video_format == "mp4" and importlib.util.find_spec("imageio_ffmpeg") is None:
            raise ImportError("video_format=mp4 needs imageio-ffmpeg: pip install -e '.[video]' (or video_format=gif)")
    if args.export:
        from torchrl_sail.data.minari import minari_datasets_root

        if (minari_datasets_root() / args.export).exists() and not args.overwrite:
            raise FileExistsError(
                f"export={args.export}: a Minari dataset of that id exists under "
                f"{minari_datasets_root()}; pass overwrite=true or another id"
            )


def stats(values: list[float]) -> dict:
    return {
        "mean": statistics.fmean(values),
        "std": statistics.pstdev(values),
        "min": min(values),
        "max": max(values),
        "values": values,
    }


@hydra.main(version_base="1.3", config_path="../conf", config_name="evaluate")
def main(args):  # noqa: F821
    torch.set_num_threads(args.threads)
    fast_tensor_outputs()  # tensordict 0.15's shortcut for plain-tensor outputs: same returns, less time
    run_dir = Path(args.run_dir)
    cfg, run = load_run(run_dir)
    if args.device is not None:
        cfg.device = args.device
    seed = cfg.seed + 20_000 if args.seed is None else args.seed
    if args.actor is None:
        args.actor = cfg.eval.actor  # the actor the run's own evaluations use
    out = Path(args.out) if args.out else run_dir / "evaluation.json"
    check_args(args, cfg)
    if args.vectorized is not None:
        cfg.eval.vectorized = args.vectorized
    seed_everything(seed)
    env = make_env(cfg, seed)  # the actor's specs (and a PPO actor's normaliser)
    kept = KEPT_POLICIES.get(str(args.policy))
    kept_policy = run_dir / kept if kept is not None else None
    actor = load_actor(cfg, env, checkpoint_dir(run_dir), str(args.actor), kept_policy=kept_policy)
    eval_env = make_eval_env(cfg, seed, args.episodes)
    copy_observation_norm(env, eval_env)  # a PPO actor's frozen statistics (others: nothing)
    episodes = evaluate_episodes(
        eval_env, actor, args.episodes, cfg.env.max_episode_steps, keep_rollouts=bool(args.export)
    )

    result = {
        "run_dir": str(run_dir),
        "env": cfg.env.name,
        "algo": cfg.algo.name,
        "run_seed": cfg.seed,
        "checkpoint_frames": run["frames"],
        "policy": str(args.policy),
        # the frame the evaluated weights are from: the kept policy's, else the checkpoint's
        "policy_frames": torch.load(kept_policy, weights_only=True)["frames"] if kept_policy else run["frames"],
        "actor": str(args.actor),
        "seed": seed,
        "episodes": args.episodes,
        "vectorized": bool(cfg.eval.vectorized),
        **{key: stats([e[key] for e in episodes]) for key in ("dense_return", "delayed_reward", "length")},
    }
    if args.video:
        render_env = make_render_env(cfg, seed, args.video_size)  # same seed: replays episode 0
        copy_observation_norm(env, render_env)  # a PPO actor's frozen statistics (others: nothing)
        frames, rollout = record_episode(render_env, actor, cfg.env.max_episode_steps)
        video = write_video(frames, out.with_suffix(f".{args.video_format}"), video_fps(render_env))
        result["video"] = {
            "path": str(video),
            "frames": len(frames),
            "fps": video_fps(render_env),
            "dense_return": float(rollout["next", "episode_return"][-1]),
        }
    if args.export:
        from torchrl_sail import export_minari_dataset

        data = torch.cat([episode_transitions(e["rollout"], cfg.algo.absorbing_state) for e in episodes])
        dataset = export_minari_dataset(
            data,
            args.export,
            env=cfg.env.name,
            overwrite=args.overwrite,
            max_episode_steps=cfg.env.max_episode_steps,
            algorithm_name=f"torchrl_sail {cfg.algo.name}, deterministic actor at {run['frames']} frames",
            description=f"{args.episodes} deterministic episodes (seed {seed}) of {run_dir}",
        )
        result["export"] = {"dataset_id": args.export, "path": str(dataset)}
    write_atomic(out, json.dumps(result, indent=2))

    print(
        f"{cfg.algo.name} on {cfg.env.name} (seed {cfg.seed}), {POLICY_LABELS[str(args.policy)]} "
        f"at {result['policy_frames']} frames, "
        f"{args.episodes} deterministic episodes (seed {seed}) of its {args.actor} actor:"
    )
    for key, label in (
        ("dense_return", "dense return"),
        ("delayed_reward", "delayed reward r_e"),
        ("length", "episode length"),
    ):
        s = result[key]
        print(f"  {label:<19} mean {s['mean']:9.1f}  std {s['std']:8.1f}  min {s['min']:9.1f}  max {s['max']:9.1f}")
    if args.video:
        print(
            f"  video: {result['video']['path']} ({result['video']['frames']} frames at {result['video']['fps']} fps, "
            f"dense return {result['video']['dense_return']:.1f})"
        )
    if args.export:
        print(
            f"  Minari dataset {args.export}: {result['export']['path']} "
            f"(train on it: teacher.path=minari:{args.export})"
        )
    print(f"  written to {out}")


if __name__ == "__main__":
    main()
