"""What one evaluation step costs: the example's deterministic episodes, played four ways.

    python benchmarks/bench_eval.py [--env HalfCheetah-v4] [--episodes 3] [--rounds 3] [--threads 1] \
        [--out benchmarks/results/collect/eval.json]

Each way plays the same ``--episodes`` episodes (the same seed, the example's untrained actor)
and is timed per env step; the ways alternate within each round. Reported: the median over
``--rounds`` of the milliseconds per step, and of each round's ratio to ``sequence``:

- ``sequence``: TorchRL's ``env.rollout`` with the actor's ``TensorDictSequential``
  (``TensorDictModule(MLP)``, ``TanhModule``), every module output through tensordict 0.14's
  ``TensorDict.from_any``;
- ``sequence, shortcut``: the same with ``torchrl_sail._compat.fast_tensor_outputs`` applied;
- ``one module, shortcut``: ``examples/run_utils.py``'s ``evaluate_episodes`` (the actor as one
  ``TD3ExplorationPolicy`` without noise) with the shortcut, on one env: the training scripts'
  evaluations with ``eval.vectorized=false``;
- ``at once``: the same on a batched env of ``--episodes`` envs (``make_sail_env(num_envs=...)``),
  one episode each: the training scripts' evaluations (``eval.vectorized=true``, the default). Its
  time per step counts the episodes' own steps, not those of an env that ended early and waits.

The record also holds the returns: a sequential way that played other episodes than ``sequence``
fails the run, and so does ``at once`` if a round plays other episodes than its first round. Its
env ``i`` is seeded ``i * SEED_STRIDE`` (``torchrl_sail.envs``), so its episodes are not the
sequential ways' (env ``0``'s, one after another). HalfCheetah's episodes all last 1000 steps; where
episodes end early (a fall), the envs that ended step on until the longest ends, which this per-step
figure does not count.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import sys
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir
from tensordict import TensorDictBase
from torchrl.envs import ExplorationType, set_exploration_type

from torchrl_sail._compat import fast_tensor_outputs, is_from_any_shortcut
from torchrl_sail.harness import code_label, cpu_model, provenance

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

from config_schema import register_config_schema  # noqa: E402
from run_utils import evaluate_episodes  # noqa: E402
from utils import make_agent, make_env  # noqa: E402

WAYS = ("sequence", "sequence, shortcut", "one module, shortcut", "at once")


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="HalfCheetah-v4")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--max-steps", type=int, default=None, help="steps per episode (default: the env's)")
    parser.add_argument("--label", default="current", help="names this measurement in --out")
    parser.add_argument("--out", type=Path, default=None, help="JSON file: one record per --label, replaced")
    parser.add_argument("--other-load", default=None, help="what else ran on the machine, kept in the record")
    return parser.parse_args(argv)


def set_shortcut(on: bool) -> None:
    """``TensorDictBase.from_any`` with tensordict 0.15's shortcut for plain tensors, or tensordict's own."""
    if on:
        fast_tensor_outputs()
        return
    current = TensorDictBase.__dict__["from_any"].__func__
    if is_from_any_shortcut(current):
        TensorDictBase.from_any = classmethod(current.__wrapped__)


@torch.no_grad()
def play(way: str, env, actor, episodes: int, max_steps: int) -> tuple[float, int, list[float]]:
    """Seconds, env steps and dense returns of ``episodes`` deterministic episodes played ``way``."""
    set_shortcut(way != "sequence")
    env.set_seed(0)
    start = time.perf_counter()
    if way in ("one module, shortcut", "at once"):
        results = evaluate_episodes(env, actor, episodes, max_steps)
        returns, steps = [r["dense_return"] for r in results], sum(r["length"] for r in results)
    else:
        returns, steps = [], 0
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            for _ in range(episodes):
                rollout = env.rollout(max_steps, actor, break_when_any_done=True)
                returns.append(float(rollout["next", "episode_return"][-1]))
                steps += rollout.numel()
    return time.perf_counter() - start, steps, returns


def measure(args) -> tuple[dict[str, list[float]], dict[str, list[float]]]:
    register_config_schema()
    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("config", [f"env={args.env}"])
    env = make_env(cfg, 10_000)
    envs = {way: env for way in WAYS} | {"at once": make_env(cfg, 10_000, num_envs=args.episodes)}
    actor = make_agent(cfg, env)[0]
    max_steps = args.max_steps or cfg.env.max_episode_steps
    ms, returns = {way: [] for way in WAYS}, {}
    original = TensorDictBase.__dict__["from_any"]
    try:
        for _ in range(args.rounds):
            for way in WAYS:
                seconds, steps, played = play(way, envs[way], actor, args.episodes, max_steps)
                ms[way].append(1e3 * seconds / steps)
                first = returns.setdefault(way, played)
                # every round of every way plays the same episodes (the sequential ways the same as
                # each other): the ways differ in time only
                if played != first or (way != "at once" and played != returns["sequence"]):
                    raise RuntimeError(
                        f"bench_eval: {way!r} played other episodes: {played} against {returns['sequence']}"
                    )
    finally:
        TensorDictBase.from_any = original  # as it was before the benchmark
    return ms, returns


#: How the docs name each way
WAY_NAMES = {
    "sequence": "TorchRL's rollout with the actor's sequence",
    "sequence, shortcut": "+ the plain-tensor shortcut",
    "one module, shortcut": "the example's `evaluate_episodes`: one module + the shortcut",
    "at once": "the same on a batched env, one episode per env (`eval.vectorized`)",
}


def docs_table(path: Path, label: str) -> str:
    """The docs' Markdown for a record of ``--out``.

    Args:
        path: the file ``--out`` wrote.
        label: the record's ``--label``.

    Returns:
        The code it measured, its settings and machine, the command that makes it, and per way the median
        ms per step and the median of the rounds' time ratios to ``sequence``.
    """
    record = json.loads(Path(path).read_text())[label]
    setup = record["setup"]
    words = ["python", "benchmarks/bench_eval.py", "--env", setup["env"], "--episodes", str(setup["episodes"])]
    words += ["--rounds", str(setup["rounds"]), "--threads", str(setup["threads"])]
    words += ["--max-steps", str(setup["max_steps"])] if setup.get("max_steps") else []
    words += ["--label", label, *(["--other-load", setup["other_load"]] if setup.get("other_load") else [])]
    threads = f"{setup['threads']} torch thread" + ("" if setup["threads"] == 1 else "s")
    lines = [
        f"`{path}`, record `{label}` (code: {code_label(setup)}): {setup['env']}, {setup['rounds']} rounds of "
        f"{setup['episodes']} episodes, {threads}, torch {setup['torch']} on {setup['cpu_model']}; "
        f"other load: {setup.get('other_load') or 'not recorded'}.",
        "",
        "```text",
        shlex.join([*words, "--out", str(path)]),
        "```",
        "",
        "| way | ms per step (median) | time vs the sequence (median of the rounds' ratios) |",
        "|---|---|---|",
    ]
    for row in record["ways"]:
        lines.append(f"| {WAY_NAMES[row['way']]} | {row['ms_per_step']:.2f} | {row['vs_sequence']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    load_before = os.getloadavg()[0]  # the 1-minute load average: what else was running
    code = provenance(REPO)
    ms, returns = measure(args)
    rows = []
    print(f"{'way':<22} {'ms/step':>8} {'vs sequence':>12}")
    for way, rounds in ms.items():
        median = statistics.median(rounds)
        # the ratio within each round, where the ways shared the machine's state, then its median
        ratio = statistics.median(t / base for t, base in zip(rounds, ms["sequence"], strict=True))
        rows.append({"way": way, "ms_per_step": median, "vs_sequence": ratio, "rounds": rounds})
        print(f"{way:<22} {median:8.3f} {ratio:12.2f}")
    if args.out is not None:
        setup = {
            "command": shlex.join(["python", "benchmarks/bench_eval.py", *(argv or sys.argv[1:])]),
            "cpu_model": cpu_model(),
            "threads": args.threads,
            "torch": torch.__version__,
            "env": args.env,
            "episodes": args.episodes,
            "max_steps": args.max_steps,
            "rounds": args.rounds,
            "other_load": args.other_load,
            "load_average_before": load_before,
            **{key: code[key] for key in ("commit", "dirty")},
        }
        records = json.loads(args.out.read_text()) if args.out.exists() else {}
        records[args.label] = {
            "setup": setup,
            "ways": rows,
            "returns": returns["sequence"],
            "returns_at_once": returns["at once"],
        }
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(records, indent=1) + "\n")


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
