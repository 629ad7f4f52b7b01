"""``benchmarks/bench_collect.py``: the layers it times and the record it writes (a few frames, no timing claims)."""

from __future__ import annotations

import json

import torch
from benchmark_scripts import load_benchmark
from torchrl.envs import GymEnv

bench_collect = load_benchmark("bench_collect")


def test_per_transform_layers_and_record(tmp_path, capsys):
    out = tmp_path / "collect.json"
    args = [
        "--frames",
        "20",
        "--rounds",
        "1",
        "--per-transform",
        "--label",
        "smoke",
        "--out",
        str(out),
        "--other-load",
        "tests",
    ]
    bench_collect.main(args)
    record = json.loads(out.read_text())["smoke"]
    layers = [row["layer"] for row in record["layers"]]
    # the example's stack, one transform at a time, the full stack last under its own name
    assert layers == [
        "gymnasium",
        "EnvBase floor",
        "GymEnv",
        "+ DoubleToFloat",
        "+ StepCounter",
        "+ InitTracker",
        "+ TimeFeature",
        "+ DelayedRewardTransform (env stack)",
        "+ policy",
        "Collector",
    ]
    previous = 0.0
    for row in record["layers"]:
        assert len(row["rounds"]) == 1 and row["ms_per_frame"] > 0
        assert abs(row["added"] - (row["ms_per_frame"] - previous)) < 1e-9  # the difference to the layer above
        previous = row["ms_per_frame"]
    assert record["setup"]["frames"] == 20 and record["setup"]["env"] == "Hopper-v4"
    assert record["setup"]["other_load"] == "tests" and record["setup"]["load_average_before"] >= 0
    assert len(record["setup"]["commit"]) == 40
    assert "+ DelayedRewardTransform (env stack)" in capsys.readouterr().out
    # a second label is added beside the first, not over it
    bench_collect.main(["--frames", "20", "--rounds", "1", "--label", "plain", "--out", str(out)])
    records = json.loads(out.read_text())
    assert set(records) == {"smoke", "plain"}
    assert [row["layer"] for row in records["plain"]["layers"]] == [
        "gymnasium",
        "EnvBase floor",
        "GymEnv",
        "env stack",
        "+ policy",
        "Collector",
    ]


def test_floor_env_steps_like_gym_env():
    """The floor does GymEnv's work (same observations, rewards and flags), only with less TorchRL around it."""
    floor, reference = bench_collect.FloorEnv("Hopper-v4"), GymEnv("Hopper-v4")
    assert floor.done_keys == reference.done_keys  # the same flags for EnvBase to complete and reset on
    floor.set_seed(3)
    reference.set_seed(3)
    actions = torch.ones(150, 3)  # full torque: the hopper falls, so a reset is compared too
    td_floor, td_reference = floor.reset(), reference.reset()
    torch.testing.assert_close(td_floor["observation"], td_reference["observation"].float())
    ends = 0
    for action in actions:
        td_floor["action"], td_reference["action"] = action, action
        (step_floor, td_floor), (step_reference, td_reference) = (
            floor.step_and_maybe_reset(td_floor),
            reference.step_and_maybe_reset(td_reference),
        )
        for key in ("observation", "reward", "done", "terminated", "truncated"):
            expected = step_reference["next", key]
            torch.testing.assert_close(step_floor["next", key], expected.to(step_floor["next", key].dtype))
        ends += int(step_reference["next", "done"])
        torch.testing.assert_close(td_floor["observation"], td_reference["observation"].float())  # after a reset too
    assert ends >= 1
