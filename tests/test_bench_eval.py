"""``benchmarks/bench_eval.py``: the three ways play the same episodes and the record holds them (no timing claims)."""

from __future__ import annotations

import json

import pytest
from benchmark_scripts import load_benchmark
from tensordict import TensorDictBase

bench_eval = load_benchmark("bench_eval")


def test_ways_play_the_same_episodes_and_the_record(tmp_path):
    before = TensorDictBase.__dict__["from_any"]
    out = tmp_path / "eval.json"
    args = ["--episodes", "2", "--rounds", "2", "--max-steps", "15", "--label", "smoke", "--out", str(out)]
    bench_eval.main(args)
    assert TensorDictBase.__dict__["from_any"] is before  # the benchmark leaves from_any as it found it
    record = json.loads(out.read_text())["smoke"]
    assert [row["way"] for row in record["ways"]] == list(bench_eval.WAYS)
    assert all(len(row["rounds"]) == 2 and row["ms_per_step"] > 0 for row in record["ways"])
    assert record["ways"][0]["vs_sequence"] == 1.0
    assert len(record["returns"]) == 2 and record["setup"]["env"] == "HalfCheetah-v4"


def test_a_way_that_plays_other_episodes_fails(monkeypatch):
    play = bench_eval.play

    def other_episodes(way, *args):
        seconds, steps, returns = play(way, *args)
        return seconds, steps, [r + 1.0 for r in returns] if way == "one module, shortcut" else returns

    monkeypatch.setattr(bench_eval, "play", other_episodes)
    with pytest.raises(RuntimeError, match="'one module, shortcut' played other episodes"):
        bench_eval.main(["--episodes", "1", "--rounds", "1", "--max-steps", "5"])
