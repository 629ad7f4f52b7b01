"""Whether the averaged actor becomes the default (``docs/results.md``, "What a fall on Hopper is"),
applied to its confirmation runs: its figures against the target actor's of the same runs, each
criterion met or not, and the decision, or what is still missing.

    python benchmarks/averaged_rule.py benchmarks/results/campaign [--out benchmarks/results/averaged/rule.md]

The runs are ``benchmarks/campaign.py --stages averaged``: the trusted stage's 40 candidate runs
again (seeds 0-4, the paper's four teachers and the four shipped ones, 300k frames; teacher labels
``paper-averaged`` and ``shipped-averaged``), with the averaged actor at
:data:`campaign.AVERAGED_MEMORY` evaluated, kept and shipped (``eval/return``) and the target actor
evaluated beside it on the same start states (``eval/return_target``). Training is the default's
either way, so each run gives both actors on the same training. DAC's runs with the paper's teachers
(label ``paper``, seeds 0-4) are the trusted rule's (``trusted_rule.py``).

The averaged actor becomes the default if it meets the trusted rule's first set
(:func:`trusted_rule.first_set`); otherwise if it meets all of: every one of its 40 runs passes its
teacher; with no paper teacher is its last-5 mean below the target actor's by more than the target
actor's sample standard deviation; and its fall share pooled over the Hopper and Walker2d runs of
both teacher sets is at most :data:`MAX_SHARE_OF_TARGET` of the target actor's on the same runs.
Otherwise the default stays. The decision is ``pending`` until the runs to come cannot change it: a
run that never passed its teacher decides it at once (both sets ask every run to pass), and DAC's runs,
which count in the first set alone, are not awaited once every averaged run is in and the first set is
out of reach or the second set met.

A run is refused, naming its folder, when its config was not run with the confirmation's settings
(:data:`SETTINGS`), when two runs claim the same cell, or when its evaluations cannot be read
(:func:`trusted_rule.readable`'s checks).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import find_run_folders, load_run  # noqa: E402
from campaign import AVERAGED_MEMORY  # noqa: E402
from trusted_rule import (  # noqa: E402
    ENVS,
    EVALUATIONS,
    FRAMES,
    SEEDS,
    TEACHERS,
    Result,
    cells,
    criteria_lines,
    first_set,
    interim,
    kept_policies,
    needed,
    out_of_reach,
    paper_mean,
    percent,
    pooled_falls,
    readable,
    refuse_another_teacher,
    refuse_unless_ran_with,
    rule_main,
    table,
)
from trusted_rule import SETTINGS as TRUSTED_SETTINGS  # noqa: E402
from trusted_rule import settings as trusted_settings  # noqa: E402

from torchrl_sail.harness import read_scalar  # noqa: E402

MAX_SHARE_OF_TARGET = 0.5
SUFFIX = "-averaged"
TARGET_TAG = "eval/return_target"
# what the confirmation's runs were run with (campaign.AVERAGED): the candidate's, the averaged actor shipped
SETTINGS = {**TRUSTED_SETTINGS["candidate"], "eval.actor": "average", "eval.average_frames": AVERAGED_MEMORY}


def confirmation_runs(roots: list[Path]) -> dict[str, dict[tuple[str, str, int], Result]]:
    """The averaged actor's and the target actor's figures of every finished confirmation run, and DAC's
    of the trusted rule, by (env, teacher, seed)."""
    found = {"averaged": {}, "target": {}}
    folders, teachers = {}, {}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        teacher = run.teacher.removesuffix(SUFFIX)
        total = (run.config.get("collector") or {}).get("total_frames")
        if not run.teacher.endswith(SUFFIX) or teacher not in TEACHERS or run.method != "sail":
            continue
        if run.problem is not None or total != FRAMES or run.seed not in SEEDS or run.env not in ENVS:
            continue
        key = (run.env, teacher, run.seed)
        if key in folders:
            raise ValueError(f"two averaged runs of {key}: {folders[key]} and {folder}")
        folders[key] = folder
        claim = "counted as an averaged-actor confirmation run"
        refuse_unless_ran_with(run, {**SETTINGS, **EVALUATIONS}, claim, "the confirmation has")
        refuse_another_teacher(teachers, key, run)
        averaged = readable(run, run.curve, "eval/return")
        target = readable(run, sorted(dict(read_scalar(folder, TARGET_TAG)).items()), TARGET_TAG)
        kept = ((run.summary or {}).get("best_policy") or {}).get("frames")
        found["averaged"][key] = Result(*key, run.teacher_return, averaged, run.best_policy_return, kept)
        found["target"][key] = Result(*key, run.teacher_return, target)
    found["dac"] = trusted_settings(roots)["dac"]
    return found


def second_set(averaged: dict, target: dict) -> list[tuple[str, bool]]:
    """The criteria the averaged actor must meet where it misses the first set, against the target actor."""
    passed = sum(run.passed for run in averaged.values())
    criteria = [(f"every run passes its teacher: {passed} of {len(averaged)}", passed == len(averaged))]
    for env in ENVS:
        mean, (base, std) = paper_mean(averaged, env)[0], paper_mean(target, env)
        criteria.append(
            (
                f"{env}: last-5 {mean:.1f}, not below the target actor's {base:.1f} - {std:.1f} = {base - std:.1f}",
                mean >= base - std,
            )
        )
    (falls, counted), (their_falls, their_counted) = pooled_falls(averaged), pooled_falls(target)
    share = falls / counted if counted else math.inf  # no evaluation after a pass: not met
    limit = MAX_SHARE_OF_TARGET * their_falls / their_counted if their_counted else -math.inf
    criteria.append(
        (
            f"fall share on Hopper and Walker2d {percent(falls, counted)}, at most {MAX_SHARE_OF_TARGET:g} of the "
            f"target actor's {percent(their_falls, their_counted)}, {100 * limit:.1f}%",
            share <= limit,
        )
    )
    return criteria


def judge(found: dict) -> list[str]:
    """The rule on the averaged actor, as Markdown, ending with the decision: decided as soon as the runs
    to come cannot change it (a run that never passed its teacher misses both sets; DAC's runs count in
    the first set alone), else pending."""
    averaged, target, dac = found["averaged"], found["target"], found["dac"]
    missing = {name: [key for key in needed(name) if key not in found[name]] for name in ("averaged", "dac")}
    missed = out_of_reach(averaged, "averaged actor")
    never = [key for key, run in sorted(averaged.items()) if not run.passed]
    second = None if missing["averaged"] or never else second_set(averaged, target)
    decided = bool(never) or (second is not None and (not missing["dac"] or missed or all(ok for _, ok in second)))
    lines = ["### The averaged actor", ""]
    if missing["averaged"]:
        lines.append(f"- averaged: {len(missing['averaged'])} runs missing ({cells(missing['averaged'])})")
    if missing["dac"]:
        why = " (not needed for the decision: it is decided without them)" if decided else ""
        lines.append(f"- dac: {len(missing['dac'])} runs missing ({cells(missing['dac'])}){why}")
    if never:  # both sets ask every run to pass its teacher
        return [
            *lines,
            *missed,
            "",
            "**Decision: the default stays**; `eval.actor=average` remains an option (a run never passed its "
            f"teacher: {cells(never)}).",
        ]
    if not decided:
        return [
            *lines,
            *interim(averaged, target, "averaged actor", base="the target actor"),
            *missed,
            "",
            "**Decision: pending** (it waits for every run it needs).",
        ]
    first = first_set(averaged, dac, bool(missing["dac"]))
    lines += [*missed, "", *criteria_lines("First set", first), *criteria_lines("Otherwise, all of", second)]
    if all(ok for _, ok in first):
        decision = "**Decision: the averaged actor becomes the default** (it meets the first set)."
    elif all(ok for _, ok in second):
        decision = "**Decision: the averaged actor becomes the default** (it meets the second set of criteria)."
    else:
        decision = "**Decision: the default stays**; `eval.actor=average` remains an option (it misses a criterion)."
    return [*lines, decision]


def report(roots: list[Path]) -> str:
    found = confirmation_runs(roots)
    return "\n".join(
        [
            "## The averaged actor's confirmation on the committed runs",
            "",
            f"Written by `benchmarks/averaged_rule.py`: 300k frames, seeds {SEEDS[0]}-{SEEDS[-1]}, the averaged "
            f"actor's memory {AVERAGED_MEMORY} frames; runs found: "
            + ", ".join(f"{name} {len(results)}" for name, results in found.items())
            + ". The averaged and target rows are the same runs' two actors.",
            "",
            *table(found, keeps_none="the target actor here"),
            *kept_policies(found),
            *judge(found),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    return rule_main(report, __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
