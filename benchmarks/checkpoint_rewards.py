"""The discriminator's reward at a run's checkpoint, on every stored row: teacher and agent, live and absorbing.

    python benchmarks/checkpoint_rewards.py RUN_DIR [--recent 20000]

For the off-policy methods with a discriminator reward (``examples/sail_td3.py``: sail, dac,
dac_published, ...). Rebuilds the run's discriminator, replay buffer and teacher buffer from its
``config.yaml`` (over the schema's defaults, as ``examples/evaluate.py`` does) and its last
checkpoint, on the CPU whatever device it trained on, evaluates D on each stored row and prints
one Markdown row per group: the teacher buffer's rows (the demonstrations and any promoted
trajectories: the header gives the counts), all the agent's rows and its ``--recent`` latest ones,
each split into live rows and DAC's absorbing-state rows (runs with ``algo.absorbing_state``).
The columns are D's mean probability, its mean logit, and the D reward ``coef * r(D)`` of the
run's ``algo.reward`` (kind, clip, coef) with its spread: the critic's reward for
``reward.source=discriminator``, to which ``source=shaped`` adds the env's delayed reward and
SAIL-RND its bonus (neither is included). It is computed in float32, also for
``optim.precision=bf16`` runs. What the logged diagnostics cannot say, this can: e.g. whether
falling (the absorbing state) costs the agent more per step than staying up. The run's teacher
file must still be where its config says.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch
from tensordict import TensorDictBase
from torchrl.checkpoint import Checkpoint

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

from evaluate import load_run  # noqa: E402
from utils import FilledRows, make_absorbing, make_discriminator, make_env, make_replay, make_reward, make_teacher  # noqa: E402

from torchrl_sail.harness import checkpoint_dir  # noqa: E402

HEADER = "| rows | count | D | logit | D reward | D reward std |\n|---|---|---|---|---|---|"


def parse_args(argv=None, doc: str = __doc__) -> argparse.Namespace:
    """``RUN_DIR [--recent N]``, the arguments of this tool and of ``checkpoint_actor.py`` (``doc``: its docstring)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--recent", type=int, default=20_000, help="the agent's latest rows, as their own group")
    args = parser.parse_args(argv)
    if args.recent < 1:
        parser.error(f"--recent must be >= 1, got {args.recent}")
    return args


def load(run_dir: Path):
    """The run's config, frames, D, reward transform and the stored rows (teacher, agent in write order)."""
    cfg, run = load_run(run_dir)
    if cfg.algo.learner not in ("td3", "sac"):
        raise ValueError(
            f"{run_dir}: algo={cfg.algo.name} is on-policy (algo.learner={cfg.algo.learner}): it keeps no replay "
            f"buffer to evaluate D on"
        )
    if cfg.algo.reward.source == "env":
        raise ValueError(
            f"{run_dir}: algo={cfg.algo.name} learns from the env's reward; it has no discriminator reward"
        )
    cfg.device = "cpu"
    env = make_env(cfg, cfg.seed)
    teacher, _, _ = make_teacher(cfg, env, make_absorbing(cfg))
    replay = make_replay(cfg.env.replay_size, "cpu")
    discriminator = make_discriminator(cfg, env)
    Checkpoint(discriminator=discriminator, replay=FilledRows(replay), teacher=teacher).load(
        checkpoint_dir(run_dir), components=["discriminator", "replay", "teacher"], map_location="cpu"
    )
    reward = make_reward(cfg, discriminator.eval(), keep_logit=True)
    return cfg, run, reward, teacher, write_order(replay)


def write_order(replay) -> TensorDictBase:
    """A replay buffer's stored rows, oldest first (also once its ring has wrapped)."""
    agent = replay.storage.get(torch.arange(len(replay)))
    if len(replay) == replay.storage.max_size:  # wrapped: the oldest row is at the writer's cursor
        agent = agent.roll(-int(replay.writer._cursor), 0)
    return agent


def groups(cfg, teacher: TensorDictBase, agent: TensorDictBase, recent: int) -> dict[str, TensorDictBase]:
    """Named row groups; with absorbing states each is split into live and absorbing rows."""
    named = {
        "teacher buffer": teacher,
        "agent, all": agent,
        f"agent, latest {min(recent, agent.shape[0])}": agent[-recent:],
    }
    if not cfg.algo.absorbing_state:
        return named
    split = {}
    for name, rows in named.items():
        absorbing = rows["observation"][..., -1] > 0.5  # the indicator column AbsorbingStateTransform appends
        split[f"{name}, live"], split[f"{name}, absorbing"] = rows[~absorbing], rows[absorbing]
    return split


@torch.no_grad()
def summarize(reward, rows: TensorDictBase) -> dict[str, float]:
    if not rows.shape[0]:  # (a TensorDict's numel() is at least 1)
        return {"count": 0}
    rows = rows.select("observation", "action").clone()
    rows["next", "reward"] = torch.zeros(rows.shape[0], 1)  # D's part alone (source=shaped adds it to this)
    out = reward(rows)
    logit, value = out[reward.discriminator.out_keys[0]].squeeze(-1), out["next", "reward"].squeeze(-1)
    return {
        "count": rows.shape[0],
        "D": torch.sigmoid(logit).mean().item(),
        "logit": logit.mean().item(),
        "reward": value.mean().item(),
        "reward_std": value.std().item() if value.numel() > 1 else float("nan"),
    }


def table(stats: dict[str, dict[str, float]]) -> str:
    lines = [HEADER]
    for name, s in stats.items():
        if not s["count"]:
            lines.append(f"| {name} | 0 | - | - | - | - |")
            continue
        lines.append(
            f"| {name} | {s['count']} | {s['D']:.3f} | {s['logit']:.2f} | {s['reward']:.3f} | {s['reward_std']:.3f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> dict[str, dict[str, float]]:
    args = parse_args(argv)
    torch.set_num_threads(1)
    cfg, run, reward, teacher, agent = load(args.run_dir)
    teacher_rows = teacher.storage.get(teacher.writer.stored_rows())
    stats = {name: summarize(reward, rows) for name, rows in groups(cfg, teacher_rows, agent, args.recent).items()}
    r, w = cfg.algo.reward, teacher.writer
    print(
        f"{args.run_dir}: checkpoint at {run['frames']} frames; D reward: source {r.source}, kind {r.kind}, "
        f"clip {r.clip}, coef {r.coef}; teacher buffer: {w.num_trajectories} trajectories held, of "
        f"{w.num_demonstrations} demonstrations and {w.num_promoted} promoted\n"
    )
    print(table(stats))
    return stats


if __name__ == "__main__":
    main()
