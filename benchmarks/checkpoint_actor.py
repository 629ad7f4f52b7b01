"""The TD3 actor at a run's checkpoint: how far its tanh is saturated, and what its critic says there.

    python benchmarks/checkpoint_actor.py RUN_DIR [--recent 20000]

For the TD3 methods of ``examples/sail_td3.py`` (sail, dac, td3_delayed, ...). Rebuilds the run's
actor, critic, replay buffer and teacher buffer from its ``config.yaml`` and last checkpoint (on
the CPU) and prints one Markdown row per group of stored rows: the teacher buffer's, all the
agent's and its ``--recent`` latest (split into live and absorbing rows for DAC's absorbing
states, as ``checkpoint_rewards.py`` does). Per group, on the rows' states:

- ``stored |a| >= 0.99``: the share of the stored actions' components within 1% of a bound
  (what the agent did, exploration noise included; the teacher's recorded actions);
- ``pi |a| >= 0.99`` and ``pi |x|``: the same share for the actor's own action ``pi(s)``, and the
  mean ``|x|`` of its pre-tanh output ``x`` (from ``|x| = 2.65`` on, ``|tanh(x)| >= 0.99``);
- ``|dQ/da|`` and ``|dQ/dx|``: the first critic's mean slope in the action at ``pi(s)``, and the
  slope the actor's update follows, ``dQ/da (1 - tanh(x)^2) (high - low) / 2``: near 0, the
  actor no longer moves;
- ``Q(s, pi(s))`` and ``Q(s, centre)``: the first critic's mean value of the actor's action and of
  the action box's centre (the zero action for symmetric bounds).

A run whose rows show ``pi |a| >= 0.99`` near 1 and ``|dQ/dx|`` near 0 while ``Q(s, centre)`` is
above ``Q(s, pi(s))`` has an actor stuck at the bounds that its critic would move, if it could.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.checkpoint import Checkpoint

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))
sys.path.insert(0, str(REPO / "benchmarks"))

import checkpoint_rewards  # noqa: E402
from evaluate import load_run  # noqa: E402
from utils import (  # noqa: E402
    FilledRows,
    make_absorbing,
    make_agent,
    make_discriminator,
    make_env,
    make_losses,
    make_replay,
    make_teacher,
)

from torchrl_sail.harness import checkpoint_dir  # noqa: E402

#: |a| within this share of a bound, in units of the half-width of the action box
SATURATED = 0.99
HEADER = (
    "| rows | count | stored \\|a\\| >= 0.99 | pi \\|a\\| >= 0.99 | pi \\|x\\| | \\|dQ/da\\| | \\|dQ/dx\\| "
    "| Q(s, pi(s)) | Q(s, centre) |\n|---|---|---|---|---|---|---|---|---|"
)


def parse_args(argv=None) -> argparse.Namespace:
    return checkpoint_rewards.parse_args(argv, __doc__)


def load(run_dir: Path):
    """The run's config, frames, loss (actor and critics), and the stored rows (teacher, agent in write order)."""
    cfg, run = load_run(run_dir)
    if cfg.algo.learner != "td3":
        raise ValueError(
            f"{run_dir}: algo={cfg.algo.name} has no deterministic tanh actor (algo.learner={cfg.algo.learner}); "
            "this tool reads TD3 runs"
        )
    cfg.device = "cpu"
    env = make_env(cfg, cfg.seed)
    teacher, _, _ = make_teacher(cfg, env, make_absorbing(cfg))
    replay = make_replay(cfg.env.replay_size, "cpu")
    actor, critic, _ = make_agent(cfg, env)
    loss = make_losses(cfg, actor, critic, make_discriminator(cfg, env), env.action_spec)[0]
    Checkpoint(loss=loss, replay=FilledRows(replay), teacher=teacher).load(
        checkpoint_dir(run_dir), components=["loss", "replay", "teacher"], map_location="cpu"
    )
    return cfg, run, loss, teacher.storage.get(teacher.writer.stored_rows()), checkpoint_rewards.write_order(replay)


def summarize(loss, rows: TensorDictBase) -> dict[str, float]:
    """The group's statistics (see the module docstring); ``{"count": 0}`` for no row."""
    if not rows.shape[0]:  # (a TensorDict's numel() is at least 1)
        return {"count": 0}
    body, tanh = loss.actor_network.module[0], loss.actor_network.module[1]  # make_agent's MLP and TanhModule
    critic, action_key = loss.qvalue_network, loss.tensor_keys.action
    box = tanh.spec[tanh.out_keys[0]].space  # the action spec TanhModule maps into
    low, high = box.low, box.high
    centre, half = (high + low) / 2, (high - low) / 2
    with loss.actor_network_params.to_module(loss.actor_network):
        with torch.no_grad():
            x = body(rows.select(*body.in_keys).copy())[body.out_keys[0]]
        x.requires_grad_(True)
        pi = tanh(TensorDict({tanh.in_keys[0]: x}, batch_size=x.shape[:1]))[tanh.out_keys[0]]
    pi_leaf = pi.detach().requires_grad_(True)

    def q(action: torch.Tensor) -> torch.Tensor:
        td = rows.select(*(key for key in critic.in_keys if key != action_key)).copy()
        td[action_key] = action
        with loss.qvalue_network_params[0].to_module(critic):
            return critic(td)[loss.tensor_keys.state_action_value].squeeze(-1)

    q_pi = q(pi)
    (dq_dx,) = torch.autograd.grad(q_pi.sum(), x)
    (dq_da,) = torch.autograd.grad(q(pi_leaf).sum(), pi_leaf)
    with torch.no_grad():
        q_centre = q(centre.expand_as(pi))

    def saturated(action: torch.Tensor) -> float:
        return ((action - centre).abs() >= SATURATED * half).float().mean().item()

    return {
        "count": rows.shape[0],
        "stored_saturated": saturated(rows[action_key]),
        "pi_saturated": saturated(pi.detach()),
        "preactivation": x.detach().abs().mean().item(),
        "dq_da": dq_da.abs().mean().item(),
        "dq_dx": dq_dx.abs().mean().item(),
        "q_pi": q_pi.mean().item(),
        "q_centre": q_centre.mean().item(),
    }


def table(stats: dict[str, dict[str, float]]) -> str:
    lines = [HEADER]
    for name, s in stats.items():
        if not s["count"]:
            lines.append(f"| {name} | 0 |" + " - |" * 7)
            continue
        lines.append(
            f"| {name} | {s['count']} | {s['stored_saturated']:.3f} | {s['pi_saturated']:.3f} | "
            f"{s['preactivation']:.2f} | {s['dq_da']:.3g} | {s['dq_dx']:.3g} | {s['q_pi']:.2f} | {s['q_centre']:.2f} |"
        )
    return "\n".join(lines)


def main(argv=None) -> dict[str, dict[str, float]]:
    args = parse_args(argv)
    torch.set_num_threads(1)
    cfg, run, loss, teacher_rows, agent = load(args.run_dir)
    named = checkpoint_rewards.groups(cfg, teacher_rows, agent, args.recent)
    stats = {name: summarize(loss, rows) for name, rows in named.items()}
    print(f"{args.run_dir}: checkpoint at {run['frames']} frames\n")
    print(table(stats))
    return stats


if __name__ == "__main__":
    main()
