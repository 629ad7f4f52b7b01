"""``benchmarks/bench_eval.py``: the three ways play the same episodes and the record holds them (no timing claims)."""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

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
    assert len(record["returns"]) == 2 and record["setup"]["env"] == "HalfCheetah-v4"
    assert shlex.split(record["setup"]["command"])[2:] == args  # the command as it can be pasted


def test_a_way_that_plays_other_episodes_fails(monkeypatch):
    play = bench_eval.play

    def other_episodes(way, *args):
        seconds, steps, returns = play(way, *args)
        return seconds, steps, [r + 1.0 for r in returns] if way == "one module, shortcut" else returns

    monkeypatch.setattr(bench_eval, "play", other_episodes)
    with pytest.raises(RuntimeError, match="'one module, shortcut' played other episodes"):
        bench_eval.main(["--episodes", "1", "--rounds", "1", "--max-steps", "5"])


def test_a_way_that_plays_other_episodes_in_a_later_round_fails(monkeypatch):
    play, rounds = bench_eval.play, []

    def other_episodes_in_round_two(way, *args):
        seconds, steps, returns = play(way, *args)
        rounds.append(way)
        later = rounds.count(way) == 2 and way == "sequence, shortcut"
        return seconds, steps, [r + 1.0 for r in returns] if later else returns

    monkeypatch.setattr(bench_eval, "play", other_episodes_in_round_two)
    with pytest.raises(RuntimeError, match="'sequence, shortcut' played other episodes"):
        bench_eval.main(["--episodes", "1", "--rounds", "2", "--max-steps", "5"])


def test_the_docs_table_is_the_committed_record():
    # docs/performance.md's "Evaluation steps" table, row by row in the order of the ways
    repo = Path(__file__).resolve().parents[1]
    record = json.loads((repo / "benchmarks/results/collect/eval.json").read_text())["HalfCheetah, 1 thread"]
    section = (repo / "docs/performance.md").read_text().split("### Evaluation steps", 1)[1].split("###", 1)[0]
    rows = [line.split("|")[2:4] for line in section.splitlines() if re.match(r"\| [^-|].* \| [0-9.]+ \|", line)]
    assert [(float(ms), float(ratio)) for ms, ratio in rows] == [
        (round(way["ms_per_step"], 2), round(way["vs_sequence"], 2)) for way in record["ways"]
    ]
