"""End-to-end training throughput: the SAIL example vs the same loop without D vs SB3 TD3.

    python benchmarks/throughput.py [--env Hopper-v4] [--warmup 2000] [--frames 5000] [--rounds 2] \
        [--threads 1 2] [--trainers sail td3 sb3] [--sail-overrides "a=b c=d"] \
        [--example-root ../old --label before] [--device cuda] [--other-load "what else ran"]

Trainers, each in its own process, timed from the end of the warm-up (uniform random actions,
no updates) for ``--frames`` frames:

- ``sail``: ``examples/sail_td3.py`` with the config defaults (reads ``<run dir>/summary.json``).
- ``td3``: the same command with ``algo=td3_delayed`` (the same loop without the discriminator).
- ``sb3``: Stable-Baselines3 TD3 with the example's defaults (1000 steps every 1000 frames,
  policy_delay 2, batch 256, [400, 300] nets, Gaussian exploration noise from ``conf/env``).
  Needs ``pip install -e ".[bench]"``.

``--example-root`` runs ``sail`` and ``td3`` from another checkout (cwd, script and
``PYTHONPATH`` there, so its own package is imported), e.g. a worktree of an earlier commit;
``--label`` tags every record (``before``/``after``) so runs can be told apart in one table.
``--device cuda`` runs every trainer's networks and updates on the GPU (``device=cuda`` for the
example, ``device="cuda"`` for SB3); add ``--sail-overrides optim.cudagraphs=true`` for the
example's CUDA-graph step.

Two measurements of each trainer, both reported:

- in-process timers (the default): the timed part of one run of ``--frames`` frames, from
  the example's ``summary.json`` and timers around SB3's loop;
- ``--whole-process``: each run also with ``2 * --frames`` frames, both timed from process start
  to exit; ``frames / (T(2 frames) - T(frames))`` counts everything a longer run adds (logging,
  the Python around the phases, memory growth) and nothing it does once (imports, building,
  warm-up). Before the first round, each trainer runs once untimed (``--warmup`` frames and
  1000 more, the shortest run): a cold start costs the first process of a fresh install or cache several seconds
  (bytecode compilation, the page cache) that later ones do not pay, and without this run it
  would land on the first trainer's ``--frames`` run only.

Runs alternate round by round (round, threads, trainer), so peers share the same period.
Reports the median over rounds of frames/s, ms per gradient step, ms per collected frame and
peak RSS, and frames/s ratios against SB3 of the same label; each record also holds
``phases_ms_per_frame`` (ms per timed frame of each timed phase); writes the raw records and
the table to ``--out``.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import resource
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TRAINERS = ("sail", "td3", "sb3")
METRICS = ("fps", "ms_update", "ms_frame", "peak_mb", "gradient_steps")
PROCESS_METRIC = "fps_whole_process"
WARMUP_PROCESS_FRAMES = 1000  # the untimed run before --whole-process rounds: the shortest allowed
SB3_MISSING = 'stable-baselines3 is not installed: pip install -e ".[bench]"'


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="Hopper-v4")
    parser.add_argument("--warmup", type=int, default=2000, help="random frames before timing")
    parser.add_argument("--frames", type=int, default=5000, help="timed frames after the warm-up")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--trainers", nargs="+", choices=TRAINERS, default=list(TRAINERS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sail-overrides", default="", help="extra Hydra overrides for sail and td3")
    parser.add_argument("--example-root", type=Path, default=REPO, help="checkout to run sail and td3 from")
    parser.add_argument("--label", default="", help="stored in every record, e.g. before | after")
    parser.add_argument("--device", default="cpu", help="every trainer's torch device: cpu | cuda")
    parser.add_argument(
        "--whole-process", action="store_true", help="also run 2 x --frames: frames/s from the process times"
    )
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results" / "throughput" / "throughput.json")
    parser.add_argument("--other-load", default=None, help="what else ran on the machine, kept with the arguments")
    parser.add_argument("--worker", choices=["sb3"], help=argparse.SUPPRESS)
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.frames <= 0 or args.frames % 1000:
        parser.error(f"--frames must be a positive multiple of 1000 (the train cadence), got {args.frames}")
    if args.warmup <= 0 or args.warmup % 1000:
        parser.error(f"--warmup must be a positive multiple of 1000 (the train cadence), got {args.warmup}")
    if args.rounds < 1 or min(args.threads) < 1:
        parser.error("--rounds and --threads must be >= 1")
    args.example_root = args.example_root.resolve()
    if not (args.example_root / "examples" / "sail_td3.py").is_file():
        parser.error(f"--example-root {args.example_root} has no examples/sail_td3.py")
    return args


# ----------------------------------------------------------------------------- commands
def example_command(args, trainer: str, threads: int, run_dir: Path, frames: int | None = None) -> list[str]:
    frames = args.frames if frames is None else frames
    cmd = [
        sys.executable,
        str(args.example_root / "examples" / "sail_td3.py"),
        f"env={args.env}",
        f"seed={args.seed}",
        f"threads={threads}",
        f"collector.init_random_frames={args.warmup}",
        f"collector.total_frames={args.warmup + frames}",
        "logger.backends=[csv]",
        "checkpoint.every_frames=0",
        "eval.every_frames=0",
        f"hydra.run.dir={run_dir}",
        f"device={args.device}",
    ]
    if trainer == "td3":
        cmd.append("algo=td3_delayed")
    return cmd + shlex.split(args.sail_overrides)


def sb3_command(args, threads: int, frames: int | None = None) -> list[str]:
    return [
        sys.executable,
        "benchmarks/throughput.py",
        "--worker",
        "sb3",
        "--threads",
        str(threads),
        "--env",
        args.env,
        "--warmup",
        str(args.warmup),
        "--frames",
        str(args.frames if frames is None else frames),
        "--seed",
        str(args.seed),
        "--device",
        args.device,
    ]


def per_unit_ms(seconds: dict, phase: str, count) -> float | None:
    return seconds[phase] / count * 1e3 if phase in seconds and count else None


def record_from_summary(summary: dict) -> dict:
    """The benchmark's metrics from the example's ``summary.json`` (None where a key is missing)."""
    seconds, counts = summary.get("time_seconds") or {}, summary.get("counts") or {}
    fps = summary.get("train_frames_per_second")
    if fps is None and summary.get("train_seconds"):
        fps = summary.get("train_frames", 0) / summary["train_seconds"]
    steps = counts.get("gradient_steps", counts.get("update"))  # or the timed phase's call count
    return {
        "fps": fps,
        "ms_update": per_unit_ms(seconds, "update", steps),
        "ms_frame": per_unit_ms(seconds, "collect", counts.get("frames")),
        "peak_mb": summary.get("peak_memory_mb"),
        "gradient_steps": steps,
    }


def phases_ms_per_frame(summary: dict) -> dict:
    """ms per timed frame spent in each ``timeit`` phase of the example's ``summary.json``."""
    frames = (summary.get("counts") or {}).get("frames")
    return {phase: s / frames * 1e3 for phase, s in (summary.get("time_seconds") or {}).items()} if frames else {}


def run_one(args, trainer: str, threads: int, frames: int | None = None) -> dict:
    """One process of ``trainer`` for ``frames`` (default ``--frames``) timed frames: its metrics and wall time."""
    frames = args.frames if frames is None else frames
    run_dir = Path(tempfile.mkdtemp(prefix=f"throughput-{trainer}-"))
    cmd = (
        sb3_command(args, threads, frames)
        if trainer == "sb3"
        else example_command(args, trainer, threads, run_dir, frames)
    )
    print("$", shlex.join(cmd), flush=True)
    env = {**os.environ, "WANDB_SILENT": "true", "HYDRA_FULL_ERROR": "1"}
    if trainer != "sb3":  # import the package of the checkout the example runs from
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(args.example_root), os.environ.get("PYTHONPATH")]))
    try:
        if trainer == "td3" and not (args.example_root / "conf" / "algo" / "td3_delayed.yaml").is_file():
            raise RuntimeError(
                f"{args.example_root} has no conf/algo/td3_delayed.yaml: td3 needs a checkout "
                "with algo=td3_delayed (skipped)"
            )
        start = time.perf_counter()
        proc = subprocess.run(
            cmd, cwd=REPO if trainer == "sb3" else args.example_root, env=env, capture_output=True, text=True
        )
        process_seconds = time.perf_counter() - start
        if proc.returncode:
            raise RuntimeError(f"exit {proc.returncode}: {proc.stderr.strip()[-2000:]}")
        if trainer == "sb3":
            record = json.loads(proc.stdout.strip().splitlines()[-1])
        else:
            summary = json.loads((run_dir / "summary.json").read_text())
            record = {**record_from_summary(summary), "phases_ms_per_frame": phases_ms_per_frame(summary)}
        record["process_seconds"] = process_seconds
    except (RuntimeError, OSError, ValueError, IndexError) as err:
        print(f"  {trainer} failed: {err}", file=sys.stderr)
        record = {"error": str(err)}
    finally:
        shutil.rmtree(run_dir, ignore_errors=True)
    return {
        "label": args.label,
        "trainer": trainer,
        "threads": threads,
        "frames": frames,
        "command": shlex.join(cmd),
        **record,
    }


# ----------------------------------------------------------------------------- SB3 worker
def require_sb3() -> None:
    try:
        import stable_baselines3  # noqa: F401
    except ImportError:
        raise SystemExit(SB3_MISSING) from None


def sb3_worker(args) -> dict:
    import torch

    torch.set_num_threads(args.threads[0])
    require_sb3()
    import gymnasium as gym
    import numpy as np
    from omegaconf import OmegaConf
    from stable_baselines3 import TD3
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.noise import NormalActionNoise

    sys.path.insert(0, str(REPO / "examples"))
    from config_schema import EnvConfig  # the env file holds what differs from the schema's defaults

    env_cfg = OmegaConf.merge(
        OmegaConf.structured(EnvConfig), OmegaConf.load(REPO / "conf" / "env" / f"{args.env}.yaml")
    )
    env = gym.make(args.env, max_episode_steps=env_cfg.max_episode_steps)
    act_dim = env.action_space.shape[-1]
    noise = NormalActionNoise(np.zeros(act_dim), env_cfg.exploration_noise * np.ones(act_dim))
    model = TD3(
        "MlpPolicy",
        env,
        learning_rate=1e-3,
        buffer_size=1_000_000,
        learning_starts=args.warmup,
        batch_size=256,
        tau=0.005,
        gamma=0.99,
        train_freq=(1000, "step"),
        gradient_steps=1000,
        action_noise=noise,
        policy_delay=2,
        target_policy_noise=0.2,
        target_noise_clip=0.5,
        policy_kwargs=dict(net_arch=[400, 300]),
        seed=args.seed,
        device=args.device,
    )
    clock = {"start": None, "train": 0.0, "collect": 0.0, "steps": 0}

    class StartClock(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps == args.warmup:
                clock["start"] = time.perf_counter()
            return True

    def timed(name: str, fn):
        def wrapper(*a, **kw):
            t0, timing = time.perf_counter(), model.num_timesteps >= args.warmup
            out = fn(*a, **kw)
            if timing:
                clock[name] += time.perf_counter() - t0
            return out

        return wrapper

    train = timed("train", model.train)

    def counted_train(gradient_steps: int, batch_size: int = 100) -> None:
        clock["steps"] += gradient_steps
        train(gradient_steps, batch_size)

    model.train, model.collect_rollouts = counted_train, timed("collect", model.collect_rollouts)
    model.learn(total_timesteps=args.warmup + args.frames, callback=StartClock())
    seconds = time.perf_counter() - clock["start"]
    steps = clock["steps"]
    return {
        "fps": args.frames / seconds,
        "ms_update": clock["train"] / steps * 1e3 if steps else None,
        "ms_frame": clock["collect"] / args.frames * 1e3,
        "gradient_steps": steps,
        "phases_ms_per_frame": {name: clock[name] / args.frames * 1e3 for name in ("collect", "train")},
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


# ----------------------------------------------------------------------------- report
def median(values: list) -> float | None:
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def aggregate(records: list[dict]) -> list[dict]:
    """Median over rounds per (label, trainer, threads), and frames/s over SB3's (same label and threads)."""

    def key(r: dict) -> tuple:
        return r.get("label", ""), r["trainer"], r["threads"]

    base_frames = min((r.get("frames", 0) for r in records), default=0)
    rows = []
    for label, trainer, threads in dict.fromkeys(map(key, records)):
        group = [r for r in records if key(r) == (label, trainer, threads)]
        runs = [r for r in group if r.get("frames", base_frames) == base_frames]  # the in-process figures
        phases = [r.get("phases_ms_per_frame") or {} for r in runs]
        rows.append(
            {
                "label": label,
                "trainer": trainer,
                "threads": threads,
                "runs": len(runs),
                "failed": sum("error" in r for r in runs),
                **{m: median([r.get(m) for r in runs]) for m in METRICS},
                "phases_ms_per_frame": {
                    p: median([ph.get(p) for ph in phases]) for p in dict.fromkeys(p for ph in phases for p in ph)
                },
                PROCESS_METRIC: whole_process_fps(group, base_frames),
            }
        )
    for metric, ratio in (("fps", "fps_vs_sb3"), (PROCESS_METRIC, "fps_whole_process_vs_sb3")):
        sb3 = {(row["label"], row["threads"]): row[metric] for row in rows if row["trainer"] == "sb3"}
        for row in rows:
            base = sb3.get((row["label"], row["threads"]))
            row[ratio] = row[metric] / base if row[metric] is not None and base else None
    return rows


def whole_process_rates(runs: list[dict], frames: int) -> dict[int, float]:
    """Per round, ``frames / (T(2 frames) - T(frames))`` from the process times of its two runs (rounds
    without both, or with a non-positive difference, left out)."""
    times = {}
    for r in runs:
        if r.get("process_seconds") is not None and "error" not in r:
            times.setdefault(r.get("round", 0), {})[r.get("frames")] = r["process_seconds"]
    rates = {rnd: frames / (t[2 * frames] - t[frames]) for rnd, t in times.items() if {frames, 2 * frames} <= t.keys()}
    return {rnd: rate for rnd, rate in rates.items() if rate > 0}


def whole_process_fps(runs: list[dict], frames: int) -> float | None:
    """The median over rounds of :func:`whole_process_rates`."""
    rates = list(whole_process_rates(runs, frames).values())
    return statistics.median(rates) if rates else None


def markdown(rows: list[dict]) -> str:
    lines = [
        "| label | trainer | threads | frames/s | ms/update | ms/frame | grad steps | peak MB | frames/s vs sb3 "
        "| whole-process frames/s | whole-process vs sb3 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [
            r["label"],
            r["trainer"],
            r["threads"],
            fmt(r["fps"], ".1f"),
            fmt(r["ms_update"], ".2f"),
            fmt(r["ms_frame"], ".3f"),
            fmt(r["gradient_steps"], ".0f"),
            fmt(r["peak_mb"], ".0f"),
            fmt(r["fps_vs_sb3"], ".2f"),
            fmt(r.get(PROCESS_METRIC), ".1f"),
            fmt(r.get("fps_whole_process_vs_sb3"), ".2f"),
        ]
        lines.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- the docs' tables


def fmt(value: float | None, spec: str) -> str:
    """``value`` in ``format``'s ``spec``, ``-`` where it is missing."""
    return "-" if value is None else format(value, spec)


def plural(count: int, noun: str) -> str:
    """``count`` and ``noun``, in the plural unless ``count`` is 1."""
    return f"{count} {noun}" + ("" if count == 1 else "s")


def trainer_name(trainer: str, args: dict) -> str:
    """How the docs name ``trainer`` of the invocation whose arguments were ``args``."""
    if trainer == "sb3":
        device = args.get("device", "cpu")
        return "SB3 TD3" if device == "cpu" else f'SB3 TD3, `device="{device}"`'
    name = "SAIL" if trainer == "sail" else "TD3, `algo=td3_delayed`"
    overrides = args.get("sail_overrides", "")
    return f"{name}, `{overrides}`" if overrides else f"{name} (defaults)" if trainer == "sail" else name


def command_line(args: dict, out: Path) -> str:
    """The command that made an invocation, from its recorded ``args``, writing to ``out``.

    Options at their defaults are left out, as is ``--example-root`` (a path of the machine it ran
    on: the file's ``code`` says which code ran).
    """
    defaults = vars(make_parser().parse_args([]))
    words = ["python benchmarks/throughput.py"]
    for name in ("trainers", "threads", "rounds", "warmup", "frames", "env", "seed", "device", "sail_overrides"):
        value = args.get(name, defaults[name])
        if value != defaults[name] or name in ("trainers", "threads", "rounds", "warmup", "frames"):
            values = value if isinstance(value, list) else [value]
            words.append(f"--{name.replace('_', '-')} " + " ".join(shlex.quote(str(v)) for v in values))
    if args.get("whole_process"):
        words.append("--whole-process")
    for name in ("label", "other_load"):
        if args.get(name):
            words.append(f"--{name.replace('_', '-')} {shlex.quote(args[name])}")
    return " ".join(words + [f"--out {out}"])


def machine_line(info: dict) -> str:
    """The machine of an invocation, as its file records it."""
    flags = ", ".join(info.get("cpu_flags") or []) or "none of AVX2, AVX-512, AMX"
    gpu_name = f"{info['gpu']}, " if info.get("gpu") else ""
    versions = ", ".join(f"{name} {info[name.lower()]}" for name in ("Python", "torch", "torchrl", "stable-baselines3"))
    load = f"1-minute load average {info['load_1min']:.2f} at the start"
    return f"{gpu_name}{info['cpu_model']} ({info['cpu_count']} CPUs; CPU flags: {flags}); {versions}; {load}"


def docs_block(paths: list[Path]) -> str:
    """The docs' Markdown for invocations of this script.

    Args:
        paths: files written by ``--out``, in the order to show them.

    Returns:
        Per file, the code it measured, its command, its settings and machine; then a table of the
        medians over rounds of every trainer and thread count and, where any file has several rounds,
        one of every round. Ratios are to SB3 of the same invocation, thread count (and round);
        ``-`` where a figure is missing.
    """
    from torchrl_sail.harness import code_label

    made, medians, rounds, several = [], [], [], False
    for path in paths:
        data = json.loads(Path(path).read_text())
        args, records = data["args"], data["records"]
        several |= args["rounds"] > 1
        whole = f"; whole-process from runs of {args['frames']} and {2 * args['frames']} frames"
        other = f"; other load: {args['other_load']}" if args.get("other_load") else ""
        made += [
            f"- `{path}`, invocation `{args.get('label') or '-'}` (code: {code_label(data)}): "
            f"{args.get('env', 'Hopper-v4')}, {plural(args['rounds'], 'round')} of {args['frames']} timed frames "
            f"after {args['warmup']} warm-up frames{whole if args.get('whole_process') else ''}; "
            f"on {machine_line(data['machine'])}{other}.",
            "",
            "  ```text",
            f"  {command_line(args, path)}",
            "  ```",
        ]
        for row in aggregate(records):
            label, name = row["label"] or "-", trainer_name(row["trainer"], args)
            medians.append(
                f"| {label} | {name} | {row['threads']} | {fmt(row['fps'], '.1f')} | {fmt(row['fps_vs_sb3'], '.2f')} "
                f"| {fmt(row.get(PROCESS_METRIC), '.1f')} | {fmt(row.get('fps_whole_process_vs_sb3'), '.2f')} "
                f"| {fmt(row['ms_update'], '.2f')} | {fmt(row['ms_frame'], '.2f')} | {fmt(row['peak_mb'], '.0f')} |"
            )
            rounds.append(round_row(records, row, label, name, args["frames"]))
    lines = [
        *made,
        "",
        "| invocation | trainer | threads | frames/s, timers | vs SB3 | frames/s, whole-process | vs SB3 "
        "| ms per TD3 step | ms collection per frame | peak MB |",
        "|---|---|---|---|---|---|---|---|---|---|",
        *medians,
    ]
    if several:  # with one round, the medians are the rounds
        lines += [
            "",
            "Round by round (frames/s, and its ratio to SB3's in the same round):",
            "",
            "| invocation | trainer | threads | timers | vs SB3 | whole-process | vs SB3 |",
            "|---|---|---|---|---|---|---|",
            *rounds,
        ]
    return "\n".join(lines)


def round_row(records: list[dict], row: dict, label: str, name: str, frames: int) -> str:
    """The per-round figures of one row of :func:`aggregate` (a trainer at a thread count), as a table row:
    each round's frames/s and ratio to SB3's in the same round, ``-`` for a round without the figure."""

    def group(trainer: str) -> list[dict]:
        return [
            r
            for r in records
            if r["trainer"] == trainer and r["threads"] == row["threads"] and r.get("label", "") == row["label"]
        ]

    def timers(runs: list[dict]) -> dict[int, float]:
        return {r.get("round", 0): r["fps"] for r in runs if r.get("frames", frames) == frames and r.get("fps")}

    def cells(mine: dict[int, float], peer: dict[int, float]) -> tuple[str, str]:
        values = ", ".join(fmt(mine.get(rnd), ".1f") for rnd in played)
        ratios = ", ".join(fmt(mine[rnd] / peer[rnd] if rnd in mine and rnd in peer else None, ".2f") for rnd in played)
        return values, ratios

    own, sb3 = group(row["trainer"]), group("sb3")
    played = sorted({r.get("round", 0) for r in own})
    timer_cells = cells(timers(own), timers(sb3))
    process_cells = cells(whole_process_rates(own, frames), whole_process_rates(sb3, frames))
    return f"| {label} | {name} | {row['threads']} | " + " | ".join(timer_cells + process_cells) + " |"


def gpu(device: str) -> dict:
    if not device.startswith("cuda"):
        return {}
    import torch

    return {"gpu": torch.cuda.get_device_name(torch.device(device))}


def machine(device: str = "cpu") -> dict:
    def version(name: str) -> str:
        try:
            return importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            return "not installed"

    from torchrl_sail.harness import cpu_flags, cpu_model

    return {
        "cpu_model": cpu_model(),
        "cpu_flags": cpu_flags(),
        **gpu(device),
        "cpu_count": os.cpu_count(),
        "load_1min": os.getloadavg()[0],
        "python": sys.version.split()[0],
        **{name: version(name) for name in ("torch", "torchrl", "stable-baselines3")},
    }


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    if args.worker:
        print(json.dumps(sb3_worker(args)))
        return
    if "sb3" in args.trainers:
        require_sb3()
    from torchrl_sail.harness import provenance

    info = machine(args.device)
    code = {key: provenance(args.example_root)[key] for key in ("commit", "dirty")}  # the code sail and td3 ran
    print(", ".join(f"{k} {v}" for k, v in info.items()))
    if info["load_1min"] > 0.5:
        print(f"WARNING: 1-min load average {info['load_1min']:.2f} > 0.5: something else is running", file=sys.stderr)
    records = []
    if args.whole_process:  # a cold start is paid here, not by the first timed process (see above)
        for threads in args.threads:
            for trainer in args.trainers:
                print(f"untimed warm-up run: {trainer}, {threads} thread(s)", flush=True)
                run_one(args, trainer, threads, WARMUP_PROCESS_FRAMES)
    for rnd in range(args.rounds):
        for threads in args.threads:
            for trainer in args.trainers:
                for frames in (args.frames, 2 * args.frames) if args.whole_process else (args.frames,):
                    records.append({"round": rnd, **run_one(args, trainer, threads, frames)})
    rows = aggregate(records)
    print(markdown(rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    config = {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items() if k != "worker"}
    args.out.write_text(
        json.dumps({**code, "machine": info, "args": config, "records": records, "table": rows}, indent=2)
    )
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
