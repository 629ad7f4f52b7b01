"""``benchmarks/bench_collect.py``: the layers it times and the record it writes (a few frames, no timing claims)."""

from __future__ import annotations

import json
import shlex

import pytest
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


def made_record(rounds: dict[str, list[float]], **setup) -> dict:
    """A record as ``main`` writes it, from each layer's per-round ms per frame."""
    rows, previous = [], 0.0
    for layer, values in rounds.items():
        median = sorted(values)[len(values) // 2]
        rows.append({"layer": layer, "ms_per_frame": median, "added": median - previous, "rounds": values})
        previous = median
    base = {"env": "Hopper-v4", "frames": 3000, "rounds": 3, "threads": 1, "torch": "2.13.0+cpu", "cpu_model": "CPU"}
    base |= {"overrides": "", "per_transform": False, "other_load": None, "commit": "b" * 40, "dirty": False}
    return {"setup": base | setup, "layers": rows}


def test_docs_table_one_column_per_record_and_the_added_column(tmp_path):
    path = tmp_path / "collect.json"
    first = made_record({"gymnasium": [0.1, 0.2, 0.3], "GymEnv": [0.5, 0.4, 0.6], "Collector": [1.0, 1.2, 1.1]})
    second = made_record(
        {"gymnasium": [0.3, 0.3, 0.3], "EnvBase floor": [0.35, 0.45, 0.4], "GymEnv": [0.9, 0.7, 0.8]},
        overrides="device=cuda optim.cudagraphs=true",
        per_transform=True,
        other_load="two runs",
        code="commit 1234567 (a note)",
        threads=2,
    )
    path.write_text(json.dumps({"a": first, "b b": second}))
    text = bench_collect.docs_table(path, ["a", "b b"])
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| layer")]
    # layers in the order measured, a record without the layer shows "-"
    assert rows == [
        f"| {bench_collect.LAYER_NAMES['gymnasium']} | 0.20 | 0.30 |",
        f"| {bench_collect.LAYER_NAMES['GymEnv']} | 0.50 | 0.80 |",
        f"| {bench_collect.LAYER_NAMES['Collector']} | 1.10 | - |",
        f"| {bench_collect.LAYER_NAMES['EnvBase floor']} | - | 0.40 |",
    ]
    commands = [line.strip() for line in text.splitlines() if "python benchmarks/bench_collect.py" in line]
    for command, label in zip(commands, ("a", "b b"), strict=True):  # each parses back to its record's settings
        args = bench_collect.parse_args(shlex.split(command)[2:])
        setup = json.loads(path.read_text())[label]["setup"]
        assert (args.frames, args.rounds, args.threads, args.overrides) == tuple(
            setup[key] for key in ("frames", "rounds", "threads", "overrides")
        )
        assert (args.per_transform, args.other_load, args.label, args.out) == (
            setup["per_transform"],
            setup["other_load"],
            label,
            path,
        )
    lines = text.splitlines()
    assert "record `a` (code: commit bbbbbbb): Hopper-v4, 3 rounds of 3000 frames, 1 torch thread," in lines[0]
    assert "other load: not recorded." in lines[0]
    assert "(code: commit 1234567 (a note)): Hopper-v4" in text and "2 torch threads" in text  # the note first
    added = bench_collect.docs_table(path, ["a"], added=True).splitlines()[-2:]
    assert added == [
        f"| {bench_collect.LAYER_NAMES['GymEnv']} | 0.50 | 0.30 |",
        f"| {bench_collect.LAYER_NAMES['Collector']} | 1.10 | 0.60 |",
    ]


def test_docs_table_names_a_missing_record_and_refuses_added_over_several(tmp_path):
    path = tmp_path / "collect.json"
    path.write_text(json.dumps({"a": made_record({"gymnasium": [0.1]})}))
    with pytest.raises(KeyError, match=r"collect.json has no record 'c'; it has 'a'"):
        bench_collect.docs_table(path, ["a", "c"])
    with pytest.raises(ValueError, match="one record"):
        bench_collect.docs_table(path, ["a", "a"], added=True)


def test_docs_ratios_within_each_round_and_their_median(tmp_path):
    path = tmp_path / "collect.json"
    record = made_record({"gymnasium": [0.2, 0.1, 0.4], "EnvBase floor": [0.5, 0.3, 0.6], "GymEnv": [0.6, 0.3, 0.9]})
    path.write_text(json.dumps({"r": record}))
    text = bench_collect.docs_ratios(path, "r", [("EnvBase floor", "gymnasium"), ("GymEnv", "EnvBase floor")])
    rows = [
        line.split(" | ")[1:]
        for line in text.splitlines()
        if line.startswith("| `EnvBase") or line.startswith("| TorchRL")
    ]
    # 0.5/0.2, 0.3/0.1, 0.6/0.4; then 0.6/0.5, 0.3/0.3, 0.9/0.6
    assert rows == [["2.50, 3.00, 1.50", "2.50 |"], ["1.20, 1.00, 1.50", "1.20 |"]]


def test_layer_names_of_the_per_transform_layers():
    assert bench_collect.layer_name("+ StepCounter") == "+ `StepCounter`"
    assert bench_collect.layer_name("+ DelayedRewardTransform (env stack)") == (
        "+ `DelayedRewardTransform` (the example's env stack)"
    )
