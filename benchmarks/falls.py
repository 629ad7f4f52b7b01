"""Falls after a run passed its teacher: the online actor against its target actor, and what the logs
show in the frames before each evaluation that fell.

    python benchmarks/falls.py <run folder> [<run folder> ...] [--out falls.md]

A run folder is a live run (``logs/scalars/``) or a results copy (``scalars.csv``) with its
``config.yaml`` and, once finished, its ``summary.json`` (its teacher's return; for an unfinished
run, ``--teacher-return``). Its evaluations (``eval/return``) logged the actor of ``eval.actor``
and, with ``eval.other_actor=true``, the run's other actors too (``eval/return_online``,
``eval/return_target``, ``eval/return_average``); a run that evaluated the online actor alone reads
"not evaluated" for the target actor, and one that did not evaluate its online actor is refused. Per
run: the fall share of each actor on its own curve (:func:`torchrl_sail.harness.fall_share`; "never
passed" where it never did), and how often one fell where the other held. Then, pooled over the
runs, each diagnostic averaged over the ``--window`` frames before an evaluation after either
actor's first pass, at each actor's falls (from its own first pass) against its other evaluations:
``actor/change`` and ``actor/target_gap`` (how far a TD3 block moves the actor, how far it is from
the target actor), ``sail/q_mean``, ``sail/d_reward_mean``, ``train/dense_return``, D's accuracy
and reward on each side, the teacher buffer's threshold C and the trajectories promoted, each as a
z-score within its run, so that envs pool; and, where the run logged it, the share of the
evaluation's episodes below the teacher (a fall of one episode in ten, or a collapse). These levels
drift with a run's frames, and falls may come earlier or later in a run than its other evaluations
(the report says where), so a second table gives each diagnostic's change since the window before the previous
evaluation, apart from that drift, and a third how often each actor fell after its run's largest
rises of the threshold C against after its other changes, in each half of the run after a pass
(:func:`rise_report`). How many falls were over by the next evaluation tells a dip of one evaluation from a
collapse that lasts; how many of the target actor's falls came at a fall of the online actor tells
whether the target actor, an average of the actor's recent weights, falls with it. A run that also
evaluated an averaged actor (``eval.average_frames``, ``eval/return_average``) gets its fall share
beside the other two, and how many of its falls came with a fall of the online actor.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from pathlib import Path

import yaml

from torchrl_sail.harness import fall_share, read_scalar, write_atomic

DIAGNOSTICS = (
    "actor/change",
    "actor/target_gap",
    "sail/q_mean",
    "sail/d_reward_mean",
    "train/dense_return",
    "d/accuracy_agent",
    "d/accuracy_teacher",
    "d/reward_agent",
    "d/reward_teacher",
    "teacher/threshold",
)
PROMOTED = "teacher/num_promoted"


ACTORS = ("online", "target", "average")


def actors(folder: Path, tag: str = "eval/return") -> dict[str, dict[int, float]]:
    """The run's evaluations by actor, ``{"online": {frames: value}, "target": {...}, "average": {...}}``,
    of ``tag`` (``eval/below_teacher``: the share of the evaluation's episodes below the teacher);
    empty for an actor the run did not evaluate."""
    evaluated = (run_config(folder).get("eval") or {}).get("actor", "online")  # an earlier version's: online
    return {name: dict(read_scalar(folder, tag if name == evaluated else f"{tag}_{name}")) for name in ACTORS}


def run_config(folder: Path) -> dict:
    return yaml.safe_load((folder / "config.yaml").read_text()) or {}


def window_mean(series: list[tuple[int, float]], start: int, end: int) -> float | None:
    values = [value for frames, value in series if start < frames <= end]
    return statistics.fmean(values) if values else None


def last_at(series: list[tuple[int, float]], frames: int) -> float:
    values = [value for at, value in series if at <= frames]
    return values[-1] if values else 0.0


def teacher_return(folder: Path, given: float | None) -> float:
    """The run's teacher return: its ``summary.json``'s, else ``given`` (an unfinished run)."""
    if (folder / "summary.json").exists():
        return json.loads((folder / "summary.json").read_text())["teacher_return"]
    if given is None:
        raise ValueError(f"{folder}: no summary.json (an unfinished run): give its teacher's return, --teacher-return")
    return given


def first_pass(curve: dict[int, float] | None, teacher: float) -> int | None:
    """The frame of the first evaluation strictly above ``teacher``; None if none is (or no curve)."""
    return next((f for f in sorted(curve or {}) if curve[f] > teacher), None)


def run_rows(folder: Path, window: int, given_teacher: float | None = None) -> tuple[dict, list[dict]]:
    """The run's summary line and one row per evaluation after either actor's first pass, where each
    actor is judged (fell or not) from its own first pass on (``None`` before it, or where it was not
    evaluated)."""
    teacher = teacher_return(folder, given_teacher)
    curves = actors(folder)
    if not curves["online"]:
        evaluated = (run_config(folder).get("eval") or {}).get("actor", "online")
        raise ValueError(
            f"{folder}: no eval/return_online: "
            + ("it logged no evaluation" if evaluated == "online" else f"the run evaluated its {evaluated} actor alone")
        )
    below = actors(folder, "eval/below_teacher")  # empty for runs of versions that did not log it
    for name in ("target", "average"):
        curves[name] = curves[name] or None  # None: not evaluated
    first = {name: first_pass(curve, teacher) for name, curve in curves.items()}
    passes = [f for f in (first["online"], first["target"]) if f is not None]
    frames = sorted(set(curves["online"]) | set(curves["target"] or {}))
    after = [f for f in frames if passes and f > min(passes)]

    def judged(name: str, f: int) -> bool | None:
        curve = curves[name]
        if curve is None or f not in curve or first[name] is None or f <= first[name]:
            return None
        return curve[f] < teacher

    def holds(name: str, f: int) -> bool:  # evaluated at f, at or above the teacher's return
        return curves[name] is not None and f in curves[name] and curves[name][f] >= teacher

    series = {tag: read_scalar(folder, tag) for tag in (*DIAGNOSTICS, PROMOTED)}
    rows = []
    for f in after:
        row = {
            "fell": judged("online", f),
            "target_fell": judged("target", f),
            "online_below": below["online"].get(f),
            "target_below": below["target"].get(f),
        }
        # one actor fell where the other held (at or above the teacher there)
        row["online_alone"] = row["fell"] is True and holds("target", f)
        row["target_alone"] = row["target_fell"] is True and holds("online", f)
        for tag in DIAGNOSTICS:
            row[tag] = window_mean(series[tag], f - window, f)
        row["promoted"] = last_at(series[PROMOTED], f) - last_at(series[PROMOTED], f - window)
        rows.append(row)
    # where in the run each evaluation came: its frame as a z-score over these rows (0: the run's middle)
    spread = statistics.pstdev(after) if len(after) > 1 else 0.0
    for row, f in zip(rows, after, strict=True):
        row["position"] = (f - statistics.fmean(after)) / spread if spread > 0 else None
    # a fall whose next evaluation is above the teacher again: a dip of one evaluation, not a collapse
    for row, following in zip(rows, [*after[1:], None], strict=True):
        for name, flag in (("online", "fell"), ("target", "target_fell")):
            above = following is not None and following in (curves[name] or {}) and curves[name][following] > teacher
            row["back" if name == "online" else "target_back"] = row[flag] is True and above
    line = {
        "run": str(folder),
        "teacher": teacher,
        "passed_at": first["online"],
        "target_passed_at": first["target"],
        # None: not evaluated; else fall_share's (None: never passed)
        "online": fall_share(sorted(curves["online"].items()), teacher),
        "target": None if curves["target"] is None else fall_share(sorted(curves["target"].items()), teacher),
        "target_evaluated": curves["target"] is not None,
        "online_only": sum(row["online_alone"] for row in rows) if curves["target"] is not None else None,
        "target_only": sum(row["target_alone"] for row in rows) if curves["target"] is not None else None,
        # the averaged actor (eval.average_frames), judged from its own first pass on its own curve
        "average_frames": (run_config(folder).get("eval") or {}).get("average_frames"),
        "average": None if curves["average"] is None else fall_share(sorted(curves["average"].items()), teacher),
        "average_with_online": None,
    }
    if curves["average"] is not None:  # its falls at an evaluation where the online actor fell too
        fell = [f for f in curves["average"] if judged("average", f)]
        line["average_with_online"] = sum(judged("online", f) is True for f in fell)
    return line, rows


def shown(share: dict | None, evaluated: bool = True) -> str:
    if not evaluated:
        return "not evaluated"
    if share is None or share["share"] is None:
        return "never passed"
    return f"{100 * share['share']:.1f}% ({share['falls']}/{share['evaluations']})"


def mean_of(rows: list[dict], key: str) -> str:
    values = [row[key] for row in rows if row[key] is not None]
    if not values:
        return "-"
    text = f"{statistics.fmean(values):.2f}".replace("-0.00", "0.00")  # a z-score mean of 0 up to rounding
    return f"{text} (n={len(values)})"


def changes(rows: list[dict]) -> list[dict]:
    """``rows`` with each diagnostic (and ``promoted``) as its change since the row before (the window
    before the previous evaluation; ``None`` for the first row or a missing value): what moved just
    before an evaluation, apart from the slow drift of a run that the levels share with time."""
    keys = (*DIAGNOSTICS, "promoted")
    out = []
    for before, row in zip([None, *rows[:-1]], rows, strict=True):
        delta = {
            key: None if before is None or row[key] is None or before[key] is None else row[key] - before[key]
            for key in keys
        }
        out.append({**row, **delta})
    return out


def standardized(rows: list[dict]) -> list[dict]:
    """``rows`` with each diagnostic (and ``promoted``) as a z-score within the run: its distance from
    the run's mean over these rows in the run's standard deviations, so that runs of different envs,
    scales and signs (a logit reward's negative Q) pool; 0 is the run's own average after its pass
    (``None`` where the value is missing or the run's values do not vary)."""
    keys = (*DIAGNOSTICS, "promoted")
    moments = {}
    for key in keys:
        values = [row[key] for row in rows if row[key] is not None]
        spread = statistics.pstdev(values) if len(values) > 1 else 0.0
        moments[key] = (statistics.fmean(values), spread) if spread > 0 else None

    def z(key: str, value: float | None) -> float | None:
        if value is None or moments[key] is None:
            return None
        mean, spread = moments[key]
        return (value - mean) / spread

    return [{**row, **{key: z(key, row[key]) for key in keys}} for row in rows]


def report(folders: list[Path], window: int, given_teacher: float | None = None) -> str:
    lines = [
        "| run | teacher | online actor passed at | fall share: online actor | target actor "
        "| online fell alone | target fell alone |",
        "|---|---|---|---|---|---|---|",
    ]
    pooled, pooled_changes, pooled_rises, lines_of_runs = [], [], [], []
    for folder in folders:
        line, rows = run_rows(folder, window, given_teacher)
        pooled += standardized(rows)
        pooled_changes += standardized(changes(rows))
        pooled_rises += largest_rises(changes(rows))
        lines_of_runs.append(line)
        lines.append(
            f"| `{line['run']}` | {line['teacher']:.1f} | {line['passed_at'] or '-'} | {shown(line['online'])} "
            f"| {shown(line['target'], line['target_evaluated'])} "
            f"| {'-' if line['online_only'] is None else line['online_only']} "
            f"| {'-' if line['target_only'] is None else line['target_only']} |"
        )
    groups = {}
    for actor, flag in (("online", "fell"), ("target", "target_fell")):
        judged = [row for row in pooled if row[flag] is not None]
        groups[actor] = ([row for row in judged if row[flag]], [row for row in judged if not row[flag]])
    (online_fell, online_held), (target_fell, target_held) = groups["online"], groups["target"]
    back = {actor: sum(row[key] for row in pooled) for actor, key in (("online", "back"), ("target", "target_back"))}
    lines += [
        "",
        f"Back above the teacher by the next evaluation (a dip of one evaluation, not a collapse): "
        f"{back['online']} of the online actor's {len(online_fell)} falls, {back['target']} of the target "
        f"actor's {len(target_fell)} (a run's last evaluation has no next).",
        "",
        *(
            [
                f"Both actors fell at the same evaluation: "
                f"{sum(row['fell'] is True for row in target_fell)} of the target actor's {len(target_fell)} "
                "falls came with a fall of the online actor.",
                "",
            ]
            if target_fell
            else []
        ),
        f"Over the {window}-frame window before each evaluation after an actor's first pass: at the online "
        f"actor's {len(online_fell)} falls against its {len(online_held)} other evaluations after its first pass, "
        f"and at the target actor's {len(target_fell)} falls against its {len(target_held)} others after its own "
        "first pass (a fall: below the teacher's return; an actor fell alone where the other was at or above it). "
        "Each value is a z-score within its run: its distance from the run's mean over its evaluations after "
        "the first pass of either actor, in the run's population standard deviations (0 = that run's average), "
        "so that runs of different envs pool.",
        "",
        "| diagnostic | before an online fall | before the online actor's others "
        "| before a target fall | before the target actor's others |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| `{key}` | {mean_of(online_fell, key)} | {mean_of(online_held, key)} "
        f"| {mean_of(target_fell, key)} | {mean_of(target_held, key)} |"
        for key in (*DIAGNOSTICS, "promoted")
    ]
    lines.append(
        f"| at the evaluation: share of its episodes below the teacher (`eval/below_teacher`, not a z-score) "
        f"| {mean_of(online_fell, 'online_below')} | {mean_of(online_held, 'online_below')} "
        f"| {mean_of(target_fell, 'target_below')} | {mean_of(target_held, 'target_below')} |"
    )
    return "\n".join(
        lines + change_report(pooled_changes, window) + rise_report(pooled_rises) + average_report(lines_of_runs)
    )


def change_report(pooled: list[dict], window: int) -> list[str]:
    """Where in the runs the falls came, and the table of :func:`report` on each diagnostic's change
    since the previous evaluation's window (:func:`changes`), each as a z-score within its run."""
    groups = {}
    for actor, flag in (("online", "fell"), ("target", "target_fell")):
        judged = [row for row in pooled if row[flag] is not None]
        groups[actor] = ([row for row in judged if row[flag]], [row for row in judged if not row[flag]])

    (online_fell, online_held), (target_fell, target_held) = groups["online"], groups["target"]
    lines = [
        "",
        "The levels above drift with a run's frames, and falls need not come evenly over a run: where each "
        "evaluation came in its run (its frame as a z-score over the run's evaluations after a pass, 0 its middle), "
        f"the online actor's falls {mean_of(online_fell, 'position')}, its other evaluations "
        f"{mean_of(online_held, 'position')}"
        + (
            f"; the target actor's falls {mean_of(target_fell, 'position')}, its others "
            f"{mean_of(target_held, 'position')}"
            if target_fell or target_held
            else ""
        )
        + f". The change of each diagnostic from the {window}-frame window before the "
        "previous evaluation to the one before this evaluation is apart from that drift (a z-score within its "
        "run as above; a run's first evaluation after a pass has no change):",
        "",
        "| diagnostic, change since the previous window | before an online fall | before the online actor's others "
        "| before a target fall | before the target actor's others |",
        "|---|---|---|---|---|",
    ]
    lines += [
        f"| `{key}` | {mean_of(online_fell, key)} | {mean_of(online_held, key)} "
        f"| {mean_of(target_fell, key)} | {mean_of(target_held, key)} |"
        for key in (*DIAGNOSTICS, "promoted")
    ]
    return lines


RISE = "teacher/threshold"  # the diagnostic whose rises rise_report counts falls after
RISE_SHARE = 4  # a run's largest rises: its largest quarter of the changes of RISE


def largest_rises(rows: list[dict]) -> list[dict]:
    """``rows`` (:func:`changes`, not standardized) with ``largest_rise``: whether the row's change of
    :data:`RISE` is among the run's ``ceil(n / RISE_SHARE)`` largest of its ``n`` changes, and above 0
    (``None`` where the row has no change), and ``late``: whether it came in the second half of the run
    after a pass (its ``position`` above 0; ``None`` for a run's only evaluation after a pass)."""
    rises = sorted((row[RISE] for row in rows if row[RISE] is not None), reverse=True)
    cut = rises[math.ceil(len(rises) / RISE_SHARE) - 1] if rises else None
    return [
        {
            **row,
            "largest_rise": None if row[RISE] is None else row[RISE] > 0 and row[RISE] >= cut,
            "late": None if row["position"] is None else row["position"] > 0,
        }
        for row in rows
    ]


def rise_report(pooled: list[dict]) -> list[str]:
    """How often each actor fell after the largest rises of the threshold C (:func:`largest_rises`),
    against after its other changes, in the first and the second half of the runs after a pass: the
    change table's C line as fall rates, with time held apart (falls come earlier in a run)."""

    def rate(rows: list[dict], flag: str) -> str:
        judged = [row[flag] for row in rows if row[flag] is not None]
        return f"{100 * sum(judged) / len(judged):.0f}% ({sum(judged)}/{len(judged)})" if judged else "-"

    lines = [
        "",
        f"Falls after the threshold C's largest rises: an evaluation whose window's C (`{RISE}`) rose, since the "
        f"window before the previous evaluation, by one of its run's largest 1/{RISE_SHARE} of changes (and above 0), "
        "against the run's other evaluations with a change; in the first and the second half of the run's "
        "evaluations after a pass:",
        "",
        "| half of the run | C's change | online actor fell | target actor fell |",
        "|---|---|---|---|",
    ]
    for late in (False, True):
        for largest in (True, False):
            part = [row for row in pooled if row["late"] is late and row["largest_rise"] is largest]
            lines.append(
                f"| {'second' if late else 'first'} | {'a largest rise' if largest else 'other'} "
                f"| {rate(part, 'fell')} | {rate(part, 'target_fell')} |"
            )
    return lines


def average_report(runs: list[dict]) -> list[str]:
    """The averaged actor's fall share beside the online and target actors' on the runs that
    evaluated it (``eval.average_frames`` with ``eval.other_actor=true``), and pooled; nothing where
    none did."""
    runs = [line for line in runs if line["average"] is not None]
    if not runs:
        return []
    lines = [
        "",
        "The averaged actor (`eval.average_frames`), on the runs that evaluated it:",
        "",
        "| run | memory (frames) | fall share: averaged actor | online actor | target actor "
        "| averaged actor's falls with an online fall |",
        "|---|---|---|---|---|---|",
    ]
    for line in runs:
        falls_of = line["average"]["falls"] if line["average"]["share"] is not None else 0
        lines.append(
            f"| `{line['run']}` | {line['average_frames']} | {shown(line['average'])} | {shown(line['online'])} "
            f"| {shown(line['target'], line['target_evaluated'])} | {line['average_with_online']} of {falls_of} |"
        )
    pooled = {}
    for name in ("average", "online", "target"):
        shares = [line[name] for line in runs if line[name] is not None and line[name]["share"] is not None]
        falls, evaluations = sum(x["falls"] for x in shares), sum(x["evaluations"] for x in shares)
        pooled[name] = (
            shown({"share": falls / evaluations, "falls": falls, "evaluations": evaluations}) if evaluations else "-"
        )
    lines += [
        "",
        f"Pooled over these runs: the averaged actor {pooled['average']}, the online actor {pooled['online']}, "
        f"the target actor {pooled['target']} (each from its own first pass).",
    ]
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--window", type=int, default=10_000, help="frames before an evaluation (default: 10000)")
    parser.add_argument("--teacher-return", type=float, help="the teacher's return of runs without a summary.json")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    text = report(args.runs, args.window, args.teacher_return)
    print(text)
    if args.out:
        write_atomic(args.out, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
