"""Teachers of several qualities for one env (the teacher-quality sweep, the paper's Table 2).

    python benchmarks/make_teachers.py --env Hopper-v4 --budgets 10000 30000 80000 \
        [--max-return 1000] [--out benchmarks/teachers] [-- OVERRIDES]

Runs ``examples/make_teacher.py env=<env> frames=<budget> out=<out>/<env>_<budget>`` for each
budget, one after the other (a teacher already made is kept, so an interrupted sweep resumes),
then prints the ``--teacher td3_<budget/1000>k=<path>`` arguments (``td3_30k``) for ``benchmarks/run_matrix.py``.
Add other teachers (the paper's ``.npz``, a ``.pt`` file) as more ``--teacher LABEL=PATH``.
Overrides after ``--`` go to every ``make_teacher.py`` run.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "examples" / "make_teacher.py"
CONF = REPO / "conf"


def budget_label(budget: int) -> str:
    """``td3_30k`` for 30000 frames (``td3_2500`` when not a whole thousand)."""
    return f"td3_{budget // 1000}k" if budget % 1000 == 0 else f"td3_{budget}"


def teacher_command(
    env: str,
    budget: int,
    out: Path,
    seed: int = 0,
    max_return: float | None = None,
    overrides: tuple[str, ...] = (),
    python: str = sys.executable,
) -> list[str]:
    """The ``make_teacher.py`` command of one budget; its Hydra logs go beside the teachers."""
    command = [
        python,
        str(SCRIPT),
        f"env={env}",
        f"frames={budget}",
        f"seed={seed}",
        "threads=1",
        f"out={out / f'{env}_{budget}'}",
        f"hydra.run.dir={out / 'logs' / f'{env}_{budget}'}",
    ]
    if max_return is not None:
        command.append(f"max_return={max_return}")
    return command + list(overrides)


def teacher_return(path: Path) -> float:
    """The recorded trajectory's dense return, from the teacher's ``metadata.json``."""
    return max(json.loads((path / "metadata.json").read_text())["episode_returns"])


def eval_every_frames(overrides: tuple[str, ...]) -> int:
    """make_teacher.py records a teacher at its evaluations: a budget needs at least one."""
    for override in reversed(overrides):
        if override.startswith("eval_every_frames="):
            return int(override.partition("=")[2])
    sys.path.insert(0, str(REPO / "examples"))
    from config_schema import MakeTeacherConfig  # the source of make_teacher.py's defaults

    return MakeTeacherConfig().eval_every_frames


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    argv = list(sys.argv[1:] if argv is None else argv)
    overrides = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", required=True, help="a conf/env name")
    parser.add_argument("--budgets", nargs="+", type=int, required=True, help="TD3 frames per teacher")
    parser.add_argument("--max-return", type=float, help="record only trajectories at most this good")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks" / "teachers")
    parser.add_argument("--force", action="store_true", help="remake teachers that already exist")
    parser.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    args = parser.parse_args(argv)
    args.overrides = tuple(overrides)
    if not (CONF / "env" / f"{args.env}.yaml").exists():
        parser.error(f"unknown env {args.env!r}: no {CONF / 'env' / args.env}.yaml")
    minimum = eval_every_frames(args.overrides)
    too_small = [budget for budget in args.budgets if budget < minimum]
    if too_small:
        parser.error(f"--budgets {too_small} are below eval_every_frames={minimum}: no teacher would be recorded")
    if len(set(args.budgets)) != len(args.budgets):
        parser.error(f"--budgets has duplicates: {args.budgets}")
    args.out = args.out.expanduser().resolve()
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO / "examples"), os.environ.get("PYTHONPATH")])),
    }
    teachers = []
    for budget in sorted(args.budgets):
        path = args.out / f"{args.env}_{budget}"
        command = teacher_command(args.env, budget, args.out, args.seed, args.max_return, args.overrides)
        if args.dry_run:
            print(shlex.join(command))
        elif (path / "metadata.json").exists() and not args.force:
            print(f"[make_teachers] {path} exists (return {teacher_return(path):.1f}): kept")
        else:
            print(f"[make_teachers] {shlex.join(command)}", flush=True)
            if subprocess.run(command, cwd=REPO, env=env).returncode != 0:
                print(f"[make_teachers] the {budget}-frame teacher failed", file=sys.stderr)
                return 1
        teachers.append((budget_label(budget), path))
    if not args.dry_run:
        for label, path in teachers:
            print(f"[make_teachers] {label}: return {teacher_return(path):.1f}, {path}")
    print(
        "run_matrix.py arguments:", " ".join(f"--teacher {label}={shlex.quote(str(path))}" for label, path in teachers)
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
