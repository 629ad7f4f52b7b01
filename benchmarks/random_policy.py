"""The return of a uniform random policy: the floor a run's evaluations are read against.

    python benchmarks/random_policy.py --envs Hopper-v4 HalfCheetah-v4 Walker2d-v4 Swimmer-v4 \
        --episodes 5 --out benchmarks/results/random_policy/random_policy.json

Episode ``i`` resets the gymnasium env with seed ``i`` and draws every action from the env's
``action_space`` seeded with ``i``, until the episode ends (a fall, or the 1000-step limit).
Prints one Markdown row per env (mean, min and max return, mean length) and writes the
per-episode returns and lengths, with the gymnasium and MuJoCo versions, to ``--out`` as JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import gymnasium as gym
import mujoco

ENVS = ("Hopper-v4", "HalfCheetah-v4", "Walker2d-v4", "Swimmer-v4")
HEADER = "| env | episodes | mean return | min | max | mean length |\n|---|---|---|---|---|---|"


def random_episodes(env_name: str, episodes: int) -> list[tuple[float, int]]:
    """``(return, length)`` of ``episodes`` episodes of uniform random actions, episode ``i`` on seed ``i``."""
    env = gym.make(env_name)
    records = []
    try:
        for seed in range(episodes):
            env.reset(seed=seed)
            env.action_space.seed(seed)
            total, length, done = 0.0, 0, False
            while not done:
                _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
                total += float(reward)
                length += 1
                done = terminated or truncated
            records.append((total, length))
    finally:
        env.close()
    return records


def row(env_name: str, records: list[tuple[float, int]]) -> str:
    returns = [total for total, _ in records]
    lengths = [length for _, length in records]
    return (
        f"| {env_name} | {len(records)} | {statistics.fmean(returns):.1f} | {min(returns):.1f} "
        f"| {max(returns):.1f} | {statistics.fmean(lengths):.0f} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=list(ENVS))
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--out", type=Path, help="JSON file for the per-episode returns and lengths")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    results = {env_name: random_episodes(env_name, args.episodes) for env_name in args.envs}
    print(HEADER)
    for env_name, records in results.items():
        print(row(env_name, records))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            env_name: {"returns": [r for r, _ in records], "lengths": [n for _, n in records]}
            for env_name, records in results.items()
        }
        versions = {"gymnasium": gym.__version__, "mujoco": mujoco.__version__}
        record = {"episodes": args.episodes, "versions": versions, "envs": payload}
        args.out.write_text(json.dumps(record, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
