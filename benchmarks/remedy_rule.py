"""Which remedy of the falls goes on to a confirmation (``docs/results.md``, "What a fall on Hopper
is"), applied to the committed tuning runs: each remedy's figures against the candidate's on the
same seeds and teachers, and the choice, or what is still missing.

    python benchmarks/remedy_rule.py benchmarks/results/campaign [--out benchmarks/results/remedies/rule.md]

The runs are ``benchmarks/campaign.py``'s: ``--stages average`` trains the trusted-default candidate
alone (teacher labels ``<teacher>-average10k`` and ``-average30k``: the memory of an averaged actor
that is evaluated beside the others and does not change training), ``--stages remedies`` the
candidate with each remedy (``<teacher>-trusted-<remedy>``, :data:`campaign.REMEDIES`), 300k frames,
on the tuning seeds :data:`campaign.REMEDY_SEEDS` with the teachers of
:data:`campaign.AVERAGE_TEACHERS`. Every figure reads the target actor's evaluations (``eval/return``:
the candidate's ``eval.actor=target``). A remedy is chosen if its target actor's fall share, pooled
over its runs, is at most :data:`MAX_SHARE_OF_CANDIDATE` of the candidate's on the same (env, teacher,
seed) cells, every one of its runs passes its teacher, and its last-5 mean per teacher is not below
the candidate's by more than the candidate's sample standard deviation there. The remedy judged is
the one with the lowest fall share (the first in :data:`campaign.REMEDIES` on a tie): if it misses
a criterion, none goes on, as the rule was written before the runs. The choice is ``pending`` until
every run is finished.

The average stage's runs also evaluated an averaged actor (``eval/return_average``, memory
``eval.average_frames``: 10k frames on two seeds, 30k on the other two, :data:`campaign.AVERAGE_SEEDS`).
It goes on to a confirmation of its own by the same bounds with the same runs' target actor in the
candidate's place: its fall share pooled over the stage's runs at most
:data:`MAX_SHARE_OF_CANDIDATE` of the target actor's, every run's averaged actor passes its teacher,
and its last-5 mean per teacher not below the target actor's by more than the target actor's sample
standard deviation there; of the two memories, the one with the lower pooled fall share over its own
runs goes on (the shorter on a tie, as a tie between remedies goes to the first).

A run is refused, naming its folder, when its config was not run with its setting's values
(:data:`SETTINGS`), when two runs claim the same cell, or when its evaluations cannot be read
(:func:`trusted_rule.readable`'s checks).
"""

from __future__ import annotations

import math
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import find_run_folders, load_run  # noqa: E402
from campaign import AVERAGE_SEEDS, AVERAGE_TEACHERS, REMEDIES, REMEDY_SEEDS  # noqa: E402
from trusted_rule import (  # noqa: E402
    EVALUATIONS,
    FRAMES,
    Result,
    config_value,
    percent,
    readable,
    refuse_unless_ran_with,
    rule_main,
    spread,
)

from torchrl_sail.harness import read_scalar  # noqa: E402

MAX_SHARE_OF_CANDIDATE = 0.5
AVERAGED = "averaged"  # the average stage's averaged actor, judged against its target actor
AVERAGED_TAG = "eval/return_average"
CANDIDATE = {"optim.actor_preactivation_coef": 0.001, "eval.actor": "target", "eval.other_actor": True}
# what each setting's runs were run with (campaign.TRUSTED, and each remedy's override on top)
PLAIN = {"network.critic_layer_norm": False, "teacher.eviction": "topk", "optim.actor_lr": None}
SETTINGS = {
    "candidate": {**CANDIDATE, **PLAIN},
    "ln": {**CANDIDATE, **PLAIN, "network.critic_layer_norm": True},
    "fifo": {**CANDIDATE, **PLAIN, "teacher.eviction": "fifo"},
    "actor_lr": {**CANDIDATE, **PLAIN, "optim.actor_lr": 0.0003},
}


def setting_of(label: str) -> tuple[str, str] | None:
    """``(setting, teacher)`` of a teacher label, e.g. ``paper-trusted-ln`` -> ``("ln", "paper")``, or None."""
    for memory in AVERAGE_SEEDS:
        if label.endswith(f"-average{memory // 1000}k"):
            return "candidate", label.removesuffix(f"-average{memory // 1000}k")
    for name in REMEDIES:
        if label.endswith(f"-trusted-{name}"):
            return name, label.removesuffix(f"-trusted-{name}")
    return None


def memory_of(label: str) -> int | None:
    """The averaged actor's memory in frames of an average-stage label (``paper-average10k`` -> 10000)."""
    return next((memory for memory in AVERAGE_SEEDS if label.endswith(f"-average{memory // 1000}k")), None)


def checked(run, setting: str, curve: list[tuple[int, float]] | None = None) -> list[tuple[int, float]]:
    """The target actor's evaluations of ``run`` (or ``curve``, its averaged actor's), after checking its
    setting (an older run's missing key at what it ran with, ``trusted_rule.BEFORE_THE_KEY``) and that they
    can be read."""
    claim = f"counted as a {setting} run"
    refuse_unless_ran_with(run, {**SETTINGS[setting], **EVALUATIONS}, claim, f"the {setting} setting has")
    if curve is None:
        return readable(run, run.curve, "eval/return")
    return readable(run, curve, AVERAGED_TAG)


def averaged(run) -> Result:
    """The averaged actor's figures of an average-stage ``run``, after checking its memory."""
    memory, ran = memory_of(run.teacher), config_value(run.config, "eval.average_frames")
    if ran != memory:
        raise ValueError(
            f"{run.folder}: labelled {run.teacher}, but its config has eval.average_frames={ran!r} where the "
            f"label names {memory}"
        )
    if run.seed not in AVERAGE_SEEDS[memory]:
        raise ValueError(
            f"{run.folder}: labelled {run.teacher} on seed {run.seed}, not one of that memory's seeds "
            f"{AVERAGE_SEEDS[memory]}"
        )
    curve = sorted(dict(read_scalar(run.folder, AVERAGED_TAG)).items())
    teacher = run.teacher.removesuffix(f"-average{memory // 1000}k")
    return Result(run.env, teacher, run.seed, run.teacher_return, checked(run, "candidate", curve))


def tuning_runs(roots: list[Path]) -> dict[str, dict[tuple[str, str, int], Result]]:
    """Every finished 300k tuning run, by setting and (env, teacher, seed)."""
    found = {name: {} for name in (*SETTINGS, AVERAGED)}
    folders = {}
    cells = {(env, teacher) for env, teacher in AVERAGE_TEACHERS}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        claimed = setting_of(run.teacher)
        total = (run.config.get("collector") or {}).get("total_frames")
        if claimed is None or run.problem is not None or total != FRAMES or run.method != "sail":
            continue
        setting, teacher = claimed
        key = (run.env, teacher, run.seed)
        if key[:2] not in cells or run.seed not in REMEDY_SEEDS:
            continue
        if (setting, key) in folders:
            raise ValueError(f"two {setting} runs of {key}: {folders[setting, key]} and {folder}")
        folders[setting, key] = folder
        found[setting][key] = Result(*key, run.teacher_return, checked(run, setting))
        if setting == "candidate":
            found[AVERAGED][key] = averaged(run)
    return found


def needed(seeds=REMEDY_SEEDS) -> list[tuple[str, str, int]]:
    return [(env, teacher, seed) for env, teacher in AVERAGE_TEACHERS for seed in seeds]


def pooled(results: dict, seeds=REMEDY_SEEDS) -> tuple[int, int]:
    counts = [results[key].falls for key in needed(seeds)]
    return sum(f for f, _ in counts), sum(n for _, n in counts)


def table(found: dict) -> list[str]:
    lines = [
        "| env | teacher | setting | seeds | passed teacher | last-5 | fall share |",
        "|---|---|---|---|---|---|---|",
    ]
    for env, teacher in AVERAGE_TEACHERS:
        for name, results in found.items():
            runs = [results[env, teacher, seed] for seed in REMEDY_SEEDS if (env, teacher, seed) in results]
            falls = [run.falls for run in runs]
            shown = f"{teacher} ({runs[0].teacher_return:.1f})" if runs else teacher
            share = percent(sum(f for f, _ in falls), sum(n for _, n in falls)) if runs else "-"
            setting = "candidate, averaged actor" if name == AVERAGED else name
            lines.append(
                f"| {env} | {shown} | {setting} | {len(runs)} | {sum(run.passed for run in runs)} "
                f"| {spread([run.last5 for run in runs])} | {share} |"
            )
    return [*lines, ""]


def judge(found: dict, remedy: str) -> tuple[bool | None, list[str]]:
    """Whether ``remedy`` (or :data:`AVERAGED`) meets the three criteria against the candidate's target
    actor (None: runs missing), and the lines that say why."""
    if remedy == AVERAGED:  # the same runs' two actors
        of, missing = "the target actor's", [key for key in needed() if key not in found["candidate"]]
        pending = f"- {remedy}: pending, {len(missing)} of the average stage's runs missing."
    else:
        of = "the candidate's"
        missing = [key for name in ("candidate", remedy) for key in needed() if key not in found[name]]
        pending = f"- {remedy}: pending, {len(missing)} of its and the candidate's runs missing."
    if missing:
        return None, [pending]
    ours, theirs = pooled(found[remedy]), pooled(found["candidate"])
    share = ours[0] / ours[1] if ours[1] else math.nan
    limit = MAX_SHARE_OF_CANDIDATE * theirs[0] / theirs[1] if theirs[1] else math.nan
    criteria = [
        (
            share <= limit,
            f"fall share {percent(*ours)}, at most {MAX_SHARE_OF_CANDIDATE:g} of {of} "
            f"{percent(*theirs)}, {100 * limit:.1f}%",
        ),
        (
            all(found[remedy][key].passed for key in needed()),
            f"runs passing their teacher: {sum(found[remedy][key].passed for key in needed())} of {len(needed())}",
        ),
    ]
    for env, teacher in AVERAGE_TEACHERS:
        mine = statistics.fmean(found[remedy][env, teacher, seed].last5 for seed in REMEDY_SEEDS)
        base = [found["candidate"][env, teacher, seed].last5 for seed in REMEDY_SEEDS]
        floor = statistics.fmean(base) - statistics.stdev(base)
        criteria.append(
            (
                mine >= floor,
                f"{env} ({teacher} teacher) last-5 {mine:.1f}, not below {of} mean minus its std, {floor:.1f}",
            )
        )
    lines = [f"- {remedy}:"] + [f"  - {'met' if met else 'missed'}: {text}" for met, text in criteria]
    return all(met for met, _ in criteria), lines


def averaged_choice(found: dict) -> list[str]:
    """The averaged actor's judgement against the target actor of the same runs, and its memory."""
    met, lines = judge(found, AVERAGED)
    shares = {}
    for memory, seeds in AVERAGE_SEEDS.items():
        counts = pooled(found[AVERAGED], seeds) if met is not None else None
        shares[memory] = counts[0] / counts[1] if counts and counts[1] else math.inf
        if counts:
            named = ", ".join(map(str, seeds))
            lines.append(f"  - memory {memory // 1000}k (seeds {named}): fall share {percent(*counts)}")
    if met is None:
        choice = "pending (the choice waits for every run)"
    elif not met:
        choice = "it does not go on: it misses a criterion"
    else:
        memory = min(AVERAGE_SEEDS, key=lambda m: shares[m])  # the shorter memory on a tie
        choice = f"it goes on to a confirmation with eval.average_frames={memory} (the lower fall share)"
    return [
        "### The averaged actor against the target actor of the same runs",
        "",
        *lines,
        "",
        f"**Averaged actor: {choice}.**",
    ]


def report(roots: list[Path]) -> str:
    found = tuning_runs(roots)
    verdicts = {name: judge(found, name) for name in REMEDIES}
    lines = [
        "## Remedies of the falls on their tuning runs",
        "",
        f"Written by `benchmarks/remedy_rule.py`: 300k frames, seeds {REMEDY_SEEDS[0]}-{REMEDY_SEEDS[-1]}; runs "
        "found: " + ", ".join(f"{name} {len(results)}" for name, results in found.items() if name != AVERAGED) + ". "
        "Every row reads its runs' target actor, but the candidate's averaged actor (`eval/return_average`).",
        "",
        *table(found),
        *(line for _, lines in verdicts.values() for line in lines),
        "",
    ]
    if any(met is None for met, _ in verdicts.values()):
        choice = "pending (the choice waits for every run)"
    else:

        def share(name: str) -> float:
            falls, counted = pooled(found[name])
            return falls / counted if counted else math.inf

        lowest = min(REMEDIES, key=share)
        choice = (
            f"{lowest} (the lowest fall share) goes on to a confirmation"
            if verdicts[lowest][0]
            else f"none: {lowest}, the lowest fall share, misses a criterion"
        )
    return "\n".join([*lines, f"**Choice: {choice}.**", "", *averaged_choice(found)])


def main(argv: list[str] | None = None) -> int:
    return rule_main(report, __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
