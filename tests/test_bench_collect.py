"""``benchmarks/bench_collect.py``: the layers it times and the record it writes (a few frames, no timing claims)."""

from __future__ import annotations

import json

from benchmark_scripts import load_benchmark

bench_collect = load_benchmark("bench_collect")


def test_per_transform_layers_and_record(tmp_path, capsys):
    out = tmp_path / "collect.json"
    args = ["--frames", "20", "--rounds", "1", "--per-transform", "--label", "smoke", "--out", str(out)]
    bench_collect.main(args)
    record = json.loads(out.read_text())["smoke"]
    layers = [row["layer"] for row in record["layers"]]
    # the example's stack, one transform at a time, the full stack last under its own name
    assert layers == [
        "gymnasium",
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
    assert "+ DelayedRewardTransform (env stack)" in capsys.readouterr().out
    # a second label is added beside the first, not over it
    bench_collect.main(["--frames", "20", "--rounds", "1", "--label", "plain", "--out", str(out)])
    records = json.loads(out.read_text())
    assert set(records) == {"smoke", "plain"}
    assert [row["layer"] for row in records["plain"]["layers"]] == [
        "gymnasium",
        "GymEnv",
        "env stack",
        "+ policy",
        "Collector",
    ]
