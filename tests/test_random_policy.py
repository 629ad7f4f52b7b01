"""``benchmarks/random_policy.py``: a uniform random policy's return, against a hand-rolled loop."""

from __future__ import annotations

import json

import gymnasium as gym
import pytest
from benchmark_scripts import load_benchmark

random_policy = load_benchmark("random_policy")


def test_episodes_match_a_hand_rolled_seeded_loop():
    records = random_policy.random_episodes("Hopper-v4", 2)  # a random Hopper falls in tens of steps
    env = gym.make("Hopper-v4")
    for seed, (total, length) in enumerate(records):
        env.reset(seed=seed)
        env.action_space.seed(seed)
        rewards = []
        while True:
            _, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            rewards.append(reward)
            if terminated or truncated:
                break
        assert length == len(rewards) and total == pytest.approx(sum(rewards), abs=1e-9)
    env.close()
    assert records[0] != records[1]  # two seeds, two episodes


def test_row_and_json(tmp_path, capsys):
    assert random_policy.row("X-v0", [(1.0, 10), (-2.0, 20), (4.0, 30)]) == "| X-v0 | 3 | 1.0 | -2.0 | 4.0 | 20 |"
    out = tmp_path / "random.json"
    assert random_policy.main(["--envs", "Hopper-v4", "--episodes", "2", "--out", str(out)]) == 0
    written = json.loads(out.read_text())
    assert written["episodes"] == 2 and len(written["envs"]["Hopper-v4"]["returns"]) == 2
    assert set(written["versions"]) == {"gymnasium", "mujoco"}
    records = list(zip(written["envs"]["Hopper-v4"]["returns"], written["envs"]["Hopper-v4"]["lengths"], strict=True))
    assert capsys.readouterr().out.splitlines()[2] == random_policy.row("Hopper-v4", records)


def test_episodes_below_one_is_refused(capsys):
    with pytest.raises(SystemExit):
        random_policy.main(["--episodes", "0"])
    assert "--episodes must be at least 1, got 0" in capsys.readouterr().err
