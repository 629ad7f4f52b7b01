"""Runs a method x env x seed x teacher matrix of the training scripts through Hydra multirun.

    python benchmarks/run_matrix.py --out benchmarks/runs/hopper50k --methods sail td3_delayed \
        --envs Hopper-v4 --seeds 0 1 --jobs 2 \
        --teacher paper=<teachers>/expert_data_no_img_Hopper_scores_1500_episodes_1.npz \
        -- collector.total_frames=50000

Each method runs with the script of its family, by its ``algo.learner`` (``examples/config_schema.py``'s
``SCRIPTS``): ``sail_td3.py`` (the off-policy methods), ``gail.py`` (gail, pofd) or ``bc.py``. One
multirun per teacher (``--teacher LABEL=PATH``, or ``--teacher LABEL`` for the teacher shipped for
each env) and script, each run in ``<out>/<LABEL>/<env>/<method>/seed<seed>``. Runs go two at a
time (``--jobs``) with one torch thread each (joblib, the default launcher), or as submitit jobs
(``--launcher submitit_local | submitit_slurm``). Every run gets ``resume=auto``: a half-finished
run continues from its checkpoint and a finished one is skipped, so rerunning the same command
after an interruption completes the matrix. ``<out>/matrix.json`` records each sweep asked for
(teacher, envs, methods, seeds), so ``benchmarks/aggregate.py`` can label the runs and list the
missing ones. Overrides after ``--`` go to every run.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "examples"
SCRIPT = EXAMPLES / "sail_td3.py"  # the off-policy methods' script (script_for: any method's)
CONF = REPO / "conf"
LAUNCHERS = ("joblib", "submitit_local", "submitit_slurm")
# Hydra resolves these per job: the run folder layout aggregate.py reads.
SUBDIR = "${env.name}/${algo.name}/seed${seed}"
_LABEL = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")
_PLAIN_VALUE = re.compile(r"^[A-Za-z0-9_./+:@-]+$")


@dataclass(frozen=True)
class Teacher:
    """A teacher of the matrix: its folder name under ``--out`` and its file (None: the shipped one)."""

    label: str
    path: Path | None


def parse_teacher(spec: str) -> Teacher:
    """``LABEL=PATH`` or ``LABEL`` (the env's shipped teacher) -> :class:`Teacher`.

    Raises:
        ValueError: a label that cannot be a folder name, or a path that does not exist.
    """
    label, _, path = spec.partition("=")
    if not _LABEL.match(label):
        raise ValueError(
            f"--teacher {spec!r}: the label {label!r} must be a plain folder name "
            "(letters, digits, _ . + -), e.g. paper=path/to/teacher.npz"
        )
    if not path:
        return Teacher(label, None)
    file = Path(path).expanduser().resolve()  # the runs start in the repository root, not here
    if not file.exists():
        raise ValueError(f"--teacher {spec!r}: {file} does not exist")
    return Teacher(label, file)


def hydra_value(text: str) -> str:
    """``text`` as a Hydra override value: quoted when a comma, space or quote would be parsed."""
    if _PLAIN_VALUE.match(text):
        return text
    return "'" + text.replace("\\", "\\\\").replace("'", "\\'") + "'"


@functools.cache
def learners() -> dict[str, str]:
    """``algo.learner`` of every ``conf/algo`` method, read from the composed config (a method may
    inherit its learner, e.g. pofd from gail)."""
    if str(EXAMPLES) not in sys.path:
        sys.path.insert(0, str(EXAMPLES))
    from config_schema import register_config_schema
    from hydra import compose, initialize_config_dir

    register_config_schema()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return {
            path.stem: str(compose("config", overrides=[f"algo={path.stem}"]).algo.learner)
            for path in sorted((CONF / "algo").glob("*.yaml"))
        }


def script_for(method: str) -> Path:
    """The training script of a ``conf/algo`` method: the one of its ``algo.learner``
    (``config_schema.SCRIPTS``), e.g. ``examples/gail.py`` for ``pofd``."""
    learner = learners()[method]  # (puts examples/ on sys.path)
    from config_schema import SCRIPTS

    return EXAMPLES / SCRIPTS[learner]


def by_script(methods: list[str]) -> dict[Path, list[str]]:
    """``methods`` grouped by their script (:func:`script_for`), in the order they are given."""
    groups = {}
    for method in methods:
        groups.setdefault(script_for(method), []).append(method)
    return groups


def check_choices(group: str, names: list[str]) -> None:
    """Raises ValueError naming the first of ``names`` without a ``conf/<group>/<name>.yaml``."""
    known = sorted(path.stem for path in (CONF / group).glob("*.yaml"))
    for name in names:
        if name not in known:
            raise ValueError(f"unknown {group} {name!r}: no {CONF / group / name}.yaml (known: {', '.join(known)})")


def multirun_command(
    teacher: Teacher,
    *,
    out: Path,
    methods: list[str],
    envs: list[str],
    seeds: list[int],
    launcher: str = "joblib",
    jobs: int = 2,
    resume: str = "auto",
    overrides: tuple[str, ...] = (),
    python: str = sys.executable,
    script: Path | None = None,
) -> list[str]:
    """The ``<script> -m`` command line (an argument list, no shell) of one teacher's multirun of
    ``methods``, which must share one script (``script``; default: theirs, :func:`script_for`)."""
    scripts = set(by_script(methods)) if script is None else {script}
    if len(scripts) != 1:
        raise ValueError(
            f"methods {methods} run with different scripts ({sorted(map(str, scripts))}): "
            f"one multirun per script (by_script)"
        )
    command = [
        python,
        str(scripts.pop()),
        "-m",
        f"algo={','.join(methods)}",
        f"env={','.join(envs)}",
        f"seed={','.join(map(str, seeds))}",
        f"hydra/launcher={launcher}",
        *launcher_options(launcher, jobs),
        "threads=1",
        f"resume={resume}",
        "logger.backends=[csv]",
        f"hydra.sweep.dir={hydra_value(str(out / teacher.label))}",
        f"hydra.sweep.subdir={SUBDIR}",
    ]
    if teacher.path is not None:
        command.append(f"teacher.path={hydra_value(str(teacher.path))}")
    return command + list(overrides)  # last: the user's overrides win


def launcher_options(launcher: str, jobs: int) -> list[str]:
    """How many runs go at once, and one CPU per run."""
    if launcher == "joblib":
        return [f"hydra.launcher.n_jobs={jobs}"]
    options = ["hydra.launcher.cpus_per_task=1"]
    if launcher == "submitit_slurm":  # submitit_local starts every job at once: it has no such limit
        options.append(f"hydra.launcher.array_parallelism={jobs}")
    return options


def record_matrix(out: Path, teachers: list[Teacher], methods: list[str], envs: list[str], seeds: list[int]) -> None:
    """Adds this call's sweeps (one per teacher) to ``<out>/matrix.json``: several calls may fill one folder.

    Raises:
        ValueError: a label already recorded for another teacher file.
    """
    path = out / "matrix.json"
    matrix = json.loads(path.read_text()) if path.exists() else {"teachers": {}, "sweeps": []}
    for teacher in teachers:
        path_text = None if teacher.path is None else str(teacher.path)
        if matrix["teachers"].get(teacher.label, path_text) != path_text:
            raise ValueError(
                f"{path} already uses the teacher label {teacher.label!r} for "
                f"{matrix['teachers'][teacher.label]}, not {path_text}: choose another label"
            )
        matrix["teachers"][teacher.label] = path_text
        sweep = {"teacher": teacher.label, "envs": envs, "methods": methods, "seeds": seeds}
        if sweep not in matrix["sweeps"]:
            matrix["sweeps"].append(sweep)
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(matrix, indent=2) + "\n")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    argv = list(sys.argv[1:] if argv is None else argv)
    overrides = argv[argv.index("--") + 1 :] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        usage="%(prog)s --out DIR --methods M [M ...] --envs E [E ...] "
        "--seeds S [S ...] --teacher LABEL[=PATH] ... [-- OVERRIDES]",
    )
    parser.add_argument("--out", type=Path, required=True, help="matrix folder: <out>/<teacher>/<env>/<method>/seed<n>")
    parser.add_argument("--methods", nargs="+", required=True, help="conf/algo names")
    parser.add_argument("--envs", nargs="+", required=True, help="conf/env names")
    parser.add_argument("--seeds", nargs="+", type=int, required=True)
    parser.add_argument(
        "--teacher",
        dest="teachers",
        action="append",
        required=True,
        metavar="LABEL[=PATH]",
        help="repeatable; LABEL alone = the teacher shipped for each env",
    )
    parser.add_argument("--launcher", choices=LAUNCHERS, default="joblib")
    parser.add_argument("--jobs", type=int, default=2, help="runs at once (joblib n_jobs, Slurm array_parallelism)")
    parser.add_argument(
        "--resume",
        choices=("auto", "true", "false"),
        default="auto",
        help="the example's resume= (auto: continue a checkpoint, skip a finished run)",
    )
    parser.add_argument("--dry-run", action="store_true", help="print the commands, run nothing")
    args = parser.parse_args(argv)
    args.overrides = tuple(overrides)
    try:
        args.teachers = [parse_teacher(spec) for spec in args.teachers]
        check_choices("algo", args.methods)
        check_choices("env", args.envs)
    except ValueError as err:
        parser.error(str(err))
    labels = [teacher.label for teacher in args.teachers]
    if len(set(labels)) != len(labels):
        parser.error(f"--teacher labels must differ, got {labels}")
    if len(args.envs) > 1 and any(teacher.path is not None for teacher in args.teachers):
        parser.error(
            "a teacher file belongs to one env: with several --envs, give only shipped teachers "
            "(--teacher LABEL), or call run_matrix.py once per env with the same --out"
        )
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    for name in ("methods", "envs", "seeds"):
        values = getattr(args, name)
        if len(set(values)) != len(values):
            parser.error(f"--{name} has duplicates: {values}")
    args.out = args.out.expanduser().resolve()
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    # one multirun per teacher and script (the methods of one family share a script)
    commands = [
        (
            teacher,
            multirun_command(
                teacher,
                out=args.out,
                methods=methods,
                envs=args.envs,
                seeds=args.seeds,
                launcher=args.launcher,
                jobs=args.jobs,
                resume=args.resume,
                overrides=args.overrides,
                script=script,
            ),
        )
        for teacher in args.teachers
        for script, methods in by_script(args.methods).items()
    ]
    if args.dry_run:
        for _, command in commands:
            print(shlex.join(command))
        return 0
    record_matrix(args.out, args.teachers, args.methods, args.envs, args.seeds)
    # Submitit jobs unpickle the task in a fresh interpreter: examples/ must be importable there.
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO / "examples"), os.environ.get("PYTHONPATH")])),
        "WANDB_SILENT": "true",
    }
    failed = []
    for teacher, command in commands:
        print(f"[run_matrix] teacher {teacher.label}: {shlex.join(command)}", flush=True)
        # One multirun's failure does not stop the others; rerunning resumes what is left.
        if subprocess.run(command, cwd=REPO, env=env).returncode != 0:
            failed.append(f"{teacher.label} ({Path(command[1]).name})")
    if failed:
        print(
            f"[run_matrix] the multiruns of {', '.join(failed)} failed; rerun the same command to resume "
            f"them, then: python benchmarks/aggregate.py {args.out}",
            file=sys.stderr,
        )
        return 1
    print(f"[run_matrix] done; aggregate with: python benchmarks/aggregate.py {args.out} --out {args.out / 'report'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
