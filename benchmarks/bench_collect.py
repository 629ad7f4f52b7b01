"""What one collected frame costs, layer by layer, on the example's training env and policy.

    python benchmarks/bench_collect.py [--env Hopper-v4] [--frames 5000] [--rounds 3] [--threads 1] \
        [--out benchmarks/results/collect/collect.json]

Each layer adds one piece on top of the previous one and is timed over ``--frames`` steps
(episodes reset as they end), median over ``--rounds``:

- ``gymnasium``: ``gymnasium.make(env)`` stepped with NumPy actions: the simulator and its wrappers;
- ``EnvBase floor``: an ``EnvBase`` whose ``_step`` only converts gymnasium's arrays into a
  tensordict (no spec encoding, no info reader), stepped one frame at a time: its difference to
  ``gymnasium`` is that conversion plus ``EnvBase.step_and_maybe_reset``'s own per-step work;
- ``GymEnv``: TorchRL's ``GymEnv`` through ``step_and_maybe_reset`` (what the collector calls);
- ``env stack``: the example's env (``make_sail_env``: the time feature, the delayed reward, ...);
- ``+ policy``: the example's exploration policy (actor, tanh, Gaussian noise) before each step;
- ``Collector``: the example's TorchRL ``Collector`` over the same env and policy, at its batch size.

The differences between consecutive layers are what each one costs per frame. ``--per-transform``
splits ``env stack`` into one layer per transform of the example's env (``+ DoubleToFloat``,
``+ StepCounter``, ...): ``GymEnv`` under a ``TransformedEnv`` holding the first k of them.
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

import gymnasium as gym
import numpy as np
import torch
from hydra import compose, initialize_config_dir
from tensordict import TensorDict
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import Compose, EnvBase, ExplorationType, GymEnv, TransformedEnv, set_exploration_type

from torchrl_sail.harness import code_label, cpu_flags, cpu_model, provenance

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "examples"))

from config_schema import register_config_schema  # noqa: E402
from utils import env_kwargs, make_agent, make_collector, make_env  # noqa: E402


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="Hopper-v4")
    parser.add_argument("--frames", type=int, default=5000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--overrides", default="", help="Hydra overrides of the example's config")
    parser.add_argument("--per-transform", action="store_true", help="one layer per transform of the env stack")
    parser.add_argument("--label", default="current", help="names this measurement in --out")
    parser.add_argument("--out", type=Path, default=None, help="JSON file: one record per --label, replaced")
    parser.add_argument("--other-load", default=None, help="what else ran on the machine, kept in the record")
    return parser.parse_args(argv)


def example_config(env: str, overrides: str):
    register_config_schema()
    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        return compose("config", [f"env={env}", *overrides.split()])


def time_gymnasium(name: str, frames: int) -> float:
    env = gym.make(name)
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, (frames, *env.action_space.shape)).astype(np.float32)
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


class FloorEnv(EnvBase):
    """A gymnasium task behind the least TorchRL: arrays to tensors, nothing else (the ``EnvBase floor``)."""

    def __init__(self, name: str):
        super().__init__()
        self.gym_env = gym.make(name)
        space = self.gym_env.action_space
        self.observation_spec = Composite(observation=Unbounded(self.gym_env.observation_space.shape))
        self.action_spec = Bounded(torch.as_tensor(space.low), torch.as_tensor(space.high), space.shape)
        self.reward_spec = Unbounded((1,))
        flag = Categorical(2, (1,), dtype=torch.bool)
        self.done_spec = Composite(done=flag, terminated=flag.clone(), truncated=flag.clone())

    def _output(self, observation, reward=None, terminated=False, truncated=False) -> TensorDict:
        flags = {
            "done": torch.tensor([terminated or truncated]),
            "terminated": torch.tensor([terminated]),
            "truncated": torch.tensor([truncated]),
        }
        out = {"observation": torch.from_numpy(observation.astype(np.float32)), **flags}
        if reward is not None:
            out["reward"] = torch.tensor([reward], dtype=torch.float32)
        return TensorDict._new_unsafe(out, batch_size=())

    def _reset(self, tensordict=None):
        return self._output(self.gym_env.reset()[0])

    def _step(self, tensordict):
        observation, reward, terminated, truncated, _ = self.gym_env.step(tensordict["action"].numpy())
        return self._output(observation, reward, terminated, truncated)

    def _set_seed(self, seed):
        self.gym_env.reset(seed=seed)


def time_env(env, frames: int, policy=None) -> float:
    """``frames`` steps of ``env`` through ``step_and_maybe_reset``, as the collector runs them."""
    td = env.reset()
    actions = env.action_spec.rand((frames,))
    start = time.perf_counter()
    for i in range(frames):
        if policy is None:
            td["action"] = actions[i]
        else:
            td = policy(td)
        _, td = env.step_and_maybe_reset(td)
    return time.perf_counter() - start


def time_collector(cfg, env, policy, frames: int) -> float:
    """The example's collector (``make_collector``): ``frames`` after its first batch."""
    collector = make_collector(cfg, env, policy, frames=0)
    batches = iter(collector)
    next(batches)  # the first batch builds the collector's buffers
    collected, start = 0, time.perf_counter()
    while collected < frames:
        collected += next(batches).numel()
    elapsed = time.perf_counter() - start
    collector.shutdown()
    return elapsed * frames / collected


def partial_stacks(cfg, env) -> dict[str, TransformedEnv]:
    """``GymEnv`` under the first k transforms of ``env``'s stack (copies), for k = 1 .. all but the last."""
    transforms = list(env.transform)
    return {
        f"+ {type(transforms[k - 1]).__name__}": TransformedEnv(
            GymEnv(cfg.env.name, device=env.base_env.device, **env_kwargs(cfg)),
            Compose(*[t.clone() for t in transforms[:k]]),
        )
        for k in range(1, len(transforms))
    }


def measure(args) -> dict[str, list[float]]:
    overrides = f"collector.init_random_frames=0 {args.overrides}"
    cfg = example_config(args.env, f"collector.total_frames={2 * args.frames + 10_000} {overrides}")
    env = make_env(cfg, 0)
    _, _, policy = make_agent(cfg, env)
    partial = partial_stacks(cfg, env) if args.per_transform else {}
    # the full stack is the "env stack" layer: named after its last transform with --per-transform
    stack = f"+ {type(env.transform[-1]).__name__} (env stack)" if args.per_transform else "env stack"
    layers = ["gymnasium", "EnvBase floor", "GymEnv", *partial, stack, "+ policy", "Collector"]
    times = {layer: [] for layer in layers}
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        for _ in range(args.rounds):
            times["gymnasium"].append(time_gymnasium(args.env, args.frames))
            floor = FloorEnv(args.env)
            floor.set_seed(0)
            times["EnvBase floor"].append(time_env(floor, args.frames))
            gym_env = GymEnv(args.env)
            gym_env.set_seed(0)
            times["GymEnv"].append(time_env(gym_env, args.frames))
            for layer, partial_env in partial.items():
                partial_env.set_seed(0)
                times[layer].append(time_env(partial_env, args.frames))
            times[stack].append(time_env(env, args.frames))
            times["+ policy"].append(time_env(env, args.frames, policy))
            times["Collector"].append(time_collector(cfg, env, policy, args.frames))
    return {layer: [1e3 * t / args.frames for t in ts] for layer, ts in times.items()}


# ----------------------------------------------------------------------------- the docs' tables

#: How the docs name each layer; ``--per-transform``'s layers are named by their transform
LAYER_NAMES = {
    "gymnasium": "gymnasium's env stepped with NumPy actions",
    "EnvBase floor": "`EnvBase floor` (gymnasium's arrays into a tensordict, through `EnvBase`)",
    "GymEnv": "TorchRL's `GymEnv` (`step_and_maybe_reset`)",
    "env stack": "the example's env stack (`make_sail_env`: time feature, delayed reward, step counter, ...)",
    "+ policy": "+ the example's exploration policy before each step",
    "Collector": "the example's `Collector` over that env and policy",
}


def layer_name(layer: str) -> str:
    """The docs' name of a layer of :func:`measure`."""
    if layer in LAYER_NAMES:
        return LAYER_NAMES[layer]
    transform, stack, _ = layer.removeprefix("+ ").partition(" (env stack)")
    return f"+ `{transform}`" + (" (the example's env stack)" if stack else "")


def record_line(path: Path, label: str, setup: dict) -> str:
    """A record of ``--out`` for the docs: where it lies, the code it measured, its settings and machine,
    and the command that makes it (from the settings the record holds)."""
    words = ["python", "benchmarks/bench_collect.py"]
    words += ["--env", setup["env"]] if setup["env"] != "Hopper-v4" else []
    words += ["--frames", str(setup["frames"]), "--rounds", str(setup["rounds"]), "--threads", str(setup["threads"])]
    words += ["--overrides", setup["overrides"]] if setup["overrides"] else []
    words += ["--per-transform"] if setup["per_transform"] else []
    words += ["--label", label, *(["--other-load", setup["other_load"]] if setup.get("other_load") else [])]
    threads = f"{setup['threads']} torch thread" + ("" if setup["threads"] == 1 else "s")
    return (
        f"- `{path}`, record `{label}` (code: {code_label(setup)}): {setup['env']}, {setup['rounds']} rounds of "
        f"{setup['frames']} frames, {threads}, torch {setup['torch']} on {setup['cpu_model']}; "
        f"other load: {setup.get('other_load') or 'not recorded'}.\n\n"
        f"  ```text\n  {shlex.join([*words, '--out', str(path)])}\n  ```"
    )


def docs_table(path: Path, labels: list[str], added: bool = False) -> str:
    """The docs' Markdown for records of ``--out``.

    Args:
        path: the file ``--out`` wrote.
        labels: the records to show, one column each.
        added: also each layer's difference to the one before it (with one record only).

    Returns:
        Each record's :func:`record_line`, then a table with one row per layer (in the order measured)
        and one column per record: ms per frame, the median over its rounds; ``-`` where a record has
        no such layer.

    Raises:
        KeyError: a label the file has no record of (named, with the labels it has).
        ValueError: ``added`` with more than one record.
    """
    records = json.loads(Path(path).read_text())
    missing = [label for label in labels if label not in records]
    if missing:
        raise KeyError(f"{path} has no record {', '.join(map(repr, missing))}; it has {', '.join(map(repr, records))}")
    if added and len(labels) != 1:
        raise ValueError("added is the difference between the layers of one record")
    medians = {label: {row["layer"]: row["ms_per_frame"] for row in records[label]["layers"]} for label in labels}
    layers = list(dict.fromkeys(layer for label in labels for layer in medians[label]))
    header = ["layer", *(f"`{label}`" for label in labels), *(["added"] if added else [])]
    lines = [*(record_line(path, label, records[label]["setup"]) for label in labels), ""]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for layer in layers:
        cells = [f"{medians[label][layer]:.2f}" if layer in medians[label] else "-" for label in labels]
        if added:
            row = next(row for row in records[labels[0]]["layers"] if row["layer"] == layer)
            cells.append(f"{row['added']:.2f}")
        lines.append(f"| {layer_name(layer)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def docs_ratios(path: Path, label: str, pairs: list[tuple[str, str]]) -> str:
    """The docs' Markdown for ratios between layers of a record of ``--out``: where the machine's speed
    drifts between rounds, the ratio within a round is the figure.

    Args:
        path: the file ``--out`` wrote.
        label: the record's ``--label``.
        pairs: ``(layer, base)`` pairs: each row is ``layer``'s time over ``base``'s.

    Returns:
        The record's :func:`record_line`, then a table of each pair's ratio in every round and their median.
    """
    record = json.loads(Path(path).read_text())[label]
    rounds = {row["layer"]: row["rounds"] for row in record["layers"]}
    lines = [
        record_line(path, label, record["setup"]),
        "",
        "| ratio, within a round | rounds | median |",
        "|---|---|---|",
    ]
    for layer, base in pairs:
        ratios = [mine / theirs for mine, theirs in zip(rounds[layer], rounds[base], strict=True)]
        values = ", ".join(f"{ratio:.2f}" for ratio in ratios)
        lines.append(f"| {layer_name(layer)} / {layer_name(base)} | {values} | {statistics.median(ratios):.2f} |")
    return "\n".join(lines)


def main(argv=None) -> None:
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    load_before = os.getloadavg()[0]  # the 1-minute load average: what else was running
    code = provenance(REPO)
    ms = measure(args)
    rows, previous = [], 0.0
    width = max(map(len, ms))
    print(f"{'layer':<{width}} {'ms/frame':>9} {'added':>7}")
    for layer in ms:
        median = statistics.median(ms[layer])
        rows.append({"layer": layer, "ms_per_frame": median, "added": median - previous, "rounds": ms[layer]})
        print(f"{layer:<{width}} {median:9.3f} {median - previous:+7.3f}")
        previous = median
    if args.out is not None:
        setup = {
            "command": shlex.join(["python", "benchmarks/bench_collect.py", *(argv or sys.argv[1:])]),
            "cpu_model": cpu_model(),
            "avx512_bf16_or_amx": bool({"avx512_bf16", "amx_bf16"} & set(cpu_flags())),
            "threads": args.threads,
            "torch": torch.__version__,
            "env": args.env,
            "frames": args.frames,
            "rounds": args.rounds,
            "overrides": args.overrides,
            "per_transform": args.per_transform,
            "other_load": args.other_load,
            "load_average_before": load_before,
            **{key: code[key] for key in ("commit", "dirty")},
        }
        records = json.loads(args.out.read_text()) if args.out.exists() else {}
        records[args.label] = {"setup": setup, "layers": rows}
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(records, indent=1) + "\n")


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
