"""Which way to train on the authors' Ant teacher the docs recommend (``docs/results.md``, "Ant-v4: the
recorded columns or the env's"), applied to the committed runs of ``benchmarks/campaign.py --stages ant``.

    python benchmarks/ant_rule.py benchmarks/results/campaign

The two ways are the teacher as recorded (label ``paper``: Ant-v2's 111 columns, the contact forces on)
and the 27 columns Ant-v4 reproduces (``paper-nocontact``: :data:`campaign.ANT_OWN_COLUMNS`), each on
SAIL's runs at 300k frames, seeds :data:`campaign.COMPARISON_SEEDS`. In the rule's order:

1. the way with more seeds that pass the teacher (an evaluation above its return);
2. on a tie, the way with the higher last-5 mean, if the two means are further apart than the larger
   of their two sample standard deviations;
3. otherwise the 27 columns.

DAC's runs of the stage are shown beside SAIL's and take no part in the choice. The choice is
"not decided yet" until every SAIL run of the stage is finished. A run is refused, naming its
folder, when its config was not run with its way's settings (:data:`WAYS`), the rule's evaluations
(``trusted_rule.EVALUATIONS``) and, for SAIL, its default (:data:`SAIL_DEFAULT`), when two runs
claim the same cell, or when its evaluations cannot be read.
"""

from __future__ import annotations

import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import find_run_folders, load_run  # noqa: E402
from campaign import COMPARISON_SEEDS, OTHER_TEACHERS  # noqa: E402
from trusted_rule import (  # noqa: E402
    EVALUATIONS,
    FRAMES,
    Result,
    percent,
    readable,
    refuse_unless_ran_with,
    rule_main,
    spread,
)

ENV = "Ant-v4"
FILE = OTHER_TEACHERS[ENV]
METHODS = ("sail", "dac")  # SAIL's runs decide; DAC's are shown beside them
# each way's teacher label and what its runs were run with
WAYS = {
    "paper": {"env.kwargs.use_contact_forces": True, "teacher.drop_columns": None},
    "paper-nocontact": {"env.kwargs.use_contact_forces": False, "teacher.drop_columns": "27-110"},
}
# each way in words, and the command line that trains that way
NAMES = {"paper": "the recorded 111 columns", "paper-nocontact": "the 27 columns Ant-v4 reproduces"}
COMMANDS = {
    "paper": "python examples/sail_td3.py env=Ant-v4 teacher.path=<teachers>/{file}",
    "paper-nocontact": "python examples/sail_td3.py env=Ant-v4 env.kwargs.use_contact_forces=false "
    "teacher.drop_columns=27-110 teacher.path=<teachers>/{file}",
}
DEFAULT_WAY = "paper-nocontact"  # step 3
# SAIL's default, which the ant stage's SAIL runs train with (conf/algo/sail.yaml)
SAIL_DEFAULT = {"optim.actor_preactivation_coef": 0.001, "eval.actor": "target"}


def checked(run, way: str) -> list[tuple[int, float]]:
    """The evaluations of ``run``, after checking that it ran ``way`` (SAIL: with its default) and the
    rule's evaluations, and that they can be read."""
    expected = {**WAYS[way], **EVALUATIONS, **(SAIL_DEFAULT if run.method == "sail" else {})}
    refuse_unless_ran_with(run, expected, f"labelled {way}", f"the rule reads {run.method} runs with")
    return readable(run, run.curve, "eval/return")


def ant_runs(roots: list[Path]) -> dict[tuple[str, str], dict[int, Result]]:
    """Every finished 300k Ant run of either way, by (method, way) and seed."""
    found = {(method, way): {} for method in METHODS for way in WAYS}
    folders = {}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        total = (run.config.get("collector") or {}).get("total_frames")
        cell = (run.method, run.teacher)
        if run.env != ENV or cell not in found or run.problem is not None or total != FRAMES:
            continue
        if run.seed not in COMPARISON_SEEDS:
            continue
        if (cell, run.seed) in folders:
            raise ValueError(
                f"two {run.method} runs of {run.teacher} seed {run.seed}: {folders[cell, run.seed]} and {folder}"
            )
        folders[cell, run.seed] = folder
        found[cell][run.seed] = Result(ENV, run.teacher, run.seed, run.teacher_return, checked(run, run.teacher))
    return found


def table(found: dict) -> list[str]:
    lines = [
        "| way | method | seeds | passed teacher | last-5 | fall share |",
        "|---|---|---|---|---|---|",
    ]
    for way in WAYS:
        for method in METHODS:
            runs = [found[method, way][seed] for seed in sorted(found[method, way])]
            falls = [run.falls for run in runs]
            share = percent(sum(f for f, _ in falls), sum(n for _, n in falls)) if runs else "-"
            lines.append(
                f"| {NAMES[way]} (`{way}`) | {method} | {len(runs)} | {sum(run.passed for run in runs)} "
                f"| {spread([run.last5 for run in runs])} | {share} |"
            )
    return lines


def choose(found: dict) -> tuple[str | None, str]:
    """The way the rule picks (None: not decided yet) and the step that picked it."""
    missing = [(way, seed) for way in WAYS for seed in COMPARISON_SEEDS if seed not in found["sail", way]]
    if missing:
        return None, f"{len(missing)} of SAIL's {len(WAYS) * len(COMPARISON_SEEDS)} runs missing"
    runs = {way: list(found["sail", way].values()) for way in WAYS}
    passed = {way: sum(run.passed for run in runs[way]) for way in WAYS}
    first, second = WAYS
    if passed[first] != passed[second]:
        way = max(WAYS, key=passed.get)
        other = second if way == first else first
        return (
            way,
            f"step 1: {passed[way]} of its {len(COMPARISON_SEEDS)} seeds passed the teacher, against {passed[other]}",
        )
    means = {way: statistics.fmean(run.last5 for run in runs[way]) for way in WAYS}
    stds = {way: statistics.stdev(run.last5 for run in runs[way]) for way in WAYS}
    gap, larger = abs(means[first] - means[second]), max(stds.values())
    tie = f"both passed on {passed[first]} seeds"
    if gap > larger:
        way = max(WAYS, key=means.get)
        return way, f"step 2: {tie}; its last-5 mean is higher by {gap:.1f}, more than the larger std, {larger:.1f}"
    return (
        DEFAULT_WAY,
        f"step 3: {tie}; the last-5 means differ by {gap:.1f}, not more than the larger std, {larger:.1f}",
    )


def recommendation(found: dict) -> str:
    """The way the rule picks on ``found`` (:func:`ant_runs`), with its command, or that it is not decided yet."""
    way, why = choose(found)
    if way is None:
        return f"**Recommended way: not decided yet ({why}).**"
    return "\n".join(
        [f"**Recommended way: {NAMES[way]} ({why}):**", "", "```bash", COMMANDS[way].format(file=FILE), "```"]
    )


def report_of(found: dict) -> str:
    """The table of ``found`` (:func:`ant_runs`) and the way the rule picks."""
    teacher = next((run.teacher_return for runs in found.values() for run in runs.values()), None)
    shown = f" (return {teacher:.1f})" if teacher is not None else ""
    lines = [
        f"Written by `benchmarks/ant_rule.py`: SAIL and DAC on {ENV} with the authors' Ant teacher{shown}, "
        f"300k frames, seeds {COMPARISON_SEEDS[0]}-{COMPARISON_SEEDS[-1]}.",
        "",
        *table(found),
        "",
    ]
    return "\n".join([*lines, recommendation(found)])


def report(roots: list[Path]) -> str:
    return report_of(ant_runs(roots))


def main(argv: list[str] | None = None) -> int:
    return rule_main(report, __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
