"""``benchmarks/bench_eval.py``: the sequential ways play the same episodes, the batched way the same in every
round, and the record holds them (no timing claims)."""

from __future__ import annotations

import json
import shlex

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
    # at once, env 1 is seeded 1: its episode is not the sequence's second (env 0's next episode)
    assert len(record["returns_at_once"]) == 2 and record["returns_at_once"][1] != record["returns"][1]
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


def test_the_batched_way_playing_other_episodes_in_a_later_round_fails(monkeypatch):
    play, rounds = bench_eval.play, []

    def other_episodes_in_round_two(way, *args):
        seconds, steps, returns = play(way, *args)
        rounds.append(way)
        return seconds, steps, [r + 1.0 for r in returns] if rounds.count("at once") == 2 else returns

    monkeypatch.setattr(bench_eval, "play", other_episodes_in_round_two)
    with pytest.raises(RuntimeError, match="'at once' played other episodes"):
        bench_eval.main(["--episodes", "2", "--rounds", "2", "--max-steps", "5"])


def test_docs_table_from_a_made_record(tmp_path):
    path = tmp_path / "eval.json"
    setup = {"env": "HalfCheetah-v4", "episodes": 2, "rounds": 3, "threads": 1, "torch": "2.13.0+cpu"}
    setup |= {
        "cpu_model": "Some CPU",
        "other_load": "none (paused)",
        "commit": "a" * 40,
        "dirty": True,
        "max_steps": 50,
    }
    ways = [
        {"way": "sequence", "ms_per_step": 3.004, "vs_sequence": 1.0},
        {"way": "sequence, shortcut", "ms_per_step": 2.456, "vs_sequence": 0.8861},
        {"way": "one module, shortcut", "ms_per_step": 2.244, "vs_sequence": 0.749},
        {"way": "at once", "ms_per_step": 0.5549, "vs_sequence": 0.1851},
    ]
    path.write_text(json.dumps({"HalfCheetah, 1 thread": {"setup": setup, "ways": ways, "returns": []}}))
    text = bench_eval.docs_table(path, "HalfCheetah, 1 thread")
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| way")]
    assert rows == [
        "| TorchRL's rollout with the actor's sequence | 3.00 | 1.00 |",
        "| + the plain-tensor shortcut | 2.46 | 0.89 |",
        "| the example's `evaluate_episodes`: one module + the shortcut | 2.24 | 0.75 |",
        "| the same on a batched env, one episode per env (`eval.vectorized`) | 0.55 | 0.19 |",
    ]
    command = next(line for line in text.splitlines() if line.startswith("python benchmarks/bench_eval.py"))
    args = bench_eval.parse_args(shlex.split(command)[2:])  # the rebuilt command parses to the record's setup
    assert (args.env, args.episodes, args.rounds, args.threads) == ("HalfCheetah-v4", 2, 3, 1)
    assert (args.label, args.other_load, args.out, args.max_steps) == (
        "HalfCheetah, 1 thread",
        "none (paused)",
        path,
        50,
    )
    assert "commit aaaaaaa (uncommitted changes)" in text and "on Some CPU" in text
