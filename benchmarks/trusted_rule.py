"""The trusted-default decision rule (``docs/results.md``, "The trusted default: decision rule"), applied
to the committed runs: each criterion's figures and whether it is met, or what is still missing.

    python benchmarks/trusted_rule.py benchmarks/results/campaign [--out benchmarks/results/trusted/rule.md]

The rule compares three settings at 300k frames, seeds 0-4, on the paper's four teachers and the
four shipped ones (``examples/teachers``): the candidate (teacher labels ``paper-trusted`` and
``shipped-trusted``, the target actor's evaluations ``eval/return``), the penalty alone (the same
runs' ``eval/return_online``: training does not depend on the evaluated actor) and the defaults
(labels ``paper`` and ``shipped``, SAIL), with DAC (label ``paper``) beside them. Per run: whether
an evaluation passed the teacher, the last-5 mean and the fall share
(:func:`torchrl_sail.harness.fall_share`), and the best policy's evaluation, reported beside last-5
in a table with a row per env, teacher and setting.
After the table, where each setting's runs kept their best policy (late in the run, below their
last-5, below their teacher). The verdict is ``pending`` until every run that can change it is
finished (:func:`not_awaited` names those that cannot); meanwhile an
interim block compares each setting with the defaults on the cells both have, and names the
criteria of the first set that the finished runs already miss whatever the runs to come.
The decision then follows the rule's order: the candidate by the first set, then by the second;
then the penalty alone; else the defaults stay.

A run the rule reads is refused, naming its folder, when it was not run with its setting
(:data:`SETTINGS`; a key an older run's config lacks is at the default of its time), when two runs
claim the same cell, when it has fewer than five evaluations or a non-finite one, or when its
teacher's return is missing or differs from another run's of the same env and teacher. A fall share
that counts no evaluation (no run passed its teacher) is undefined, and a criterion on it is missed.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import HEADLINE_EVALS, examples_module, find_run_folders, listed, load_run  # noqa: E402

from torchrl_sail.harness import fall_share, read_scalar, write_atomic  # noqa: E402

SEEDS = (0, 1, 2, 3, 4)
FRAMES = 300_000
TEACHERS = ("paper", "shipped")
# criterion 2 of the first set: the last-5 mean over the teacher's return, per env (paper's teachers)
MIN_VS_TEACHER = {"Hopper-v4": 1.5, "Walker2d-v4": 1.5, "Swimmer-v4": 1.5, "HalfCheetah-v4": 1.2}
ENVS = tuple(MIN_VS_TEACHER)
FALL_ENVS = ("Hopper-v4", "Walker2d-v4")  # where a fall ends an episode
MAX_FALL_SHARE = 0.05
LATE = 10_000  # a best policy kept in a run's last LATE frames is close to its last actor
# What each setting's runs were run with; an older run's config that lacks a key ran at its default then
SETTINGS = {
    "candidate": {"optim.actor_preactivation_coef": 0.001, "eval.actor": "target", "eval.other_actor": True},
    "defaults": {"optim.actor_preactivation_coef": 0.0, "eval.actor": "online"},
    "dac": {"optim.actor_preactivation_coef": 0.0, "eval.actor": "online"},
}
EVALUATIONS = {"eval.episodes": 10, "eval.every_frames": 10_000}  # every setting's
# the most evaluations a run's fall share counts: every one after its first (the earliest it can pass)
MAX_COUNTED = FRAMES // EVALUATIONS["eval.every_frames"] - 1
# what a run ran with at a setting its config lacks (its version predates the setting)
BEFORE_THE_KEY = examples_module("config_schema").SAVED_BEFORE


@dataclass
class Result:
    """One run's figures under one setting."""

    env: str
    teacher: str  # paper | shipped
    seed: int
    teacher_return: float
    evals: list[tuple[int, float]]
    best_policy: float | None = None  # the kept policy's 50-episode return (the penalty alone keeps none)
    best_policy_frames: int | None = None  # the frame it was kept at

    @property
    def passed(self) -> bool:
        return any(value > self.teacher_return for _, value in self.evals)

    @property
    def last5(self) -> float:
        return statistics.fmean(value for _, value in self.evals[-HEADLINE_EVALS:])

    @property
    def falls(self) -> tuple[int, int]:
        share = fall_share(self.evals, self.teacher_return)
        return (0, 0) if share is None else (share["falls"], share["evaluations"])


def setting_of(run) -> str | None:
    """The setting whose runs ``run`` claims to be by its teacher label and method, or None."""
    base = run.teacher.removesuffix("-trusted")
    if base not in TEACHERS or run.method not in ("sail", "dac"):
        return None
    if run.teacher.endswith("-trusted"):
        return "candidate" if run.method == "sail" else None
    if run.method == "sail":
        return "defaults"
    return "dac" if base == "paper" else None


def config_value(config: dict, key: str):
    """``config``'s value at the dotted ``key``; a key the config lacks is at :data:`BEFORE_THE_KEY`."""
    value = config
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return BEFORE_THE_KEY.get(key)
        value = value[part]
    return value


def refuse_unless_ran_with(run, expected: dict, claim: str, holder: str) -> None:
    """Refuse ``run``, naming its folder, at the first key of ``expected`` its config has at another value:
    ``"<folder>: <claim>, but its config has <key>=<value> where <holder> <expected>"``; or that a resume
    changed (its ``summary.json``'s ``resumes``), as its frames before and after ran with two settings."""
    for key, wanted in expected.items():
        value = config_value(run.config, key)
        if value != wanted:
            raise ValueError(f"{run.folder}: {claim}, but its config has {key}={value!r} where {holder} {wanted!r}")
    for resume in (run.summary or {}).get("resumes") or []:
        for key, (before, after) in resume.get("changes", {}).items():
            if key in expected:
                raise ValueError(
                    f"{run.folder}: {claim}, but it was resumed at frame {resume['frames']} with {key} changed "
                    f"from {before!r} to {after!r}: it ran with two settings"
                )


def checked_evals(run, setting: str, evals: list[tuple[int, float]], tag: str) -> list[tuple[int, float]]:
    """``evals``, after checking that ``run`` was run with ``setting`` and that the rule can read them."""
    refuse_unless_ran_with(
        run, {**SETTINGS[setting], **EVALUATIONS}, f"counted as a {setting} run", f"the {setting} setting has"
    )
    return readable(run, evals, tag)


def readable(run, evals: list[tuple[int, float]], tag: str) -> list[tuple[int, float]]:
    """``evals`` (``run``'s ``tag``), after checking that a rule can read them: the run's teacher return a
    number, at least the five evaluations of last-5, every one finite."""
    if run.teacher_return is None or not math.isfinite(run.teacher_return):
        raise ValueError(f"{run.folder / 'summary.json'}: teacher_return is {run.teacher_return!r}, not a number")
    if len(evals) < HEADLINE_EVALS:
        raise ValueError(f"{run.folder}: {len(evals)} {tag} evaluations, fewer than the {HEADLINE_EVALS} of last-5")
    bad = [(frames, value) for frames, value in evals if not math.isfinite(value)]
    if bad:
        raise ValueError(f"{run.folder}: {tag} is {bad[0][1]} at frame {bad[0][0]}")
    return evals


def refuse_another_teacher(teachers: dict, key: tuple[str, str, int], run) -> None:
    """Refuse ``run`` if its teacher's return differs from the first one seen (``teachers``, by env and
    teacher label, which this fills) for the same env and teacher label, naming both folders."""
    first = teachers.setdefault(key[:2], (run.teacher_return, run.folder))
    if abs(first[0] - run.teacher_return) > 1e-6 * max(1.0, abs(first[0])):
        raise ValueError(
            f"teacher return {first[0]} in {first[1]} but {run.teacher_return} in {run.folder}: "
            f"the {key[1]} teacher of {key[0]} must be one file"
        )


def settings(roots: list[Path]) -> dict[str, dict[tuple[str, str, int], Result]]:
    """Every finished 300k run the rule reads, by setting and (env, teacher, seed), each checked
    (:func:`checked_evals`): two runs of one cell, or two teacher returns of one env and teacher, are
    refused, naming both folders."""
    found = {"candidate": {}, "penalty": {}, "defaults": {}, "dac": {}}
    folders, teachers = {}, {}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        total = (run.config.get("collector") or {}).get("total_frames")
        if run.problem is not None or total != FRAMES or run.seed not in SEEDS or run.env not in ENVS:
            continue
        setting = setting_of(run)
        if setting is None:
            continue
        key = (run.env, run.teacher.removesuffix("-trusted"), run.seed)
        if (setting, key) in folders:
            raise ValueError(f"two {setting} runs of {key}: {folders[setting, key]} and {folder}")
        folders[setting, key] = folder
        evals = checked_evals(run, setting, run.curve, "eval/return")
        refuse_another_teacher(teachers, key, run)
        kept = ((run.summary or {}).get("best_policy") or {}).get("frames")
        found[setting][key] = Result(*key, run.teacher_return, evals, run.best_policy_return, kept)
        if setting == "candidate":
            online = sorted(dict(read_scalar(folder, "eval/return_online")).items())
            if online:
                found["penalty"][key] = Result(
                    *key, run.teacher_return, checked_evals(run, setting, online, "eval/return_online")
                )
    return found


def needed(setting: str) -> list[tuple[str, str, int]]:
    teachers = ("paper",) if setting == "dac" else TEACHERS
    return [(env, teacher, seed) for env in ENVS for teacher in teachers for seed in SEEDS]


def paper_mean(results: dict, env: str) -> tuple[float, float]:
    values = [results[env, "paper", seed].last5 for seed in SEEDS]
    return statistics.fmean(values), statistics.stdev(values)


def pooled_falls(results: dict, keys: list[tuple[str, str, int]] | None = None) -> tuple[int, int]:
    """All falls over all counted evaluations of the Hopper and Walker2d runs (of ``keys`` alone if given)."""
    if keys is None:
        keys = [(env, teacher, seed) for env in FALL_ENVS for teacher in TEACHERS for seed in SEEDS]
    counts = [results[key].falls for key in keys if key[0] in FALL_ENVS]
    return sum(f for f, _ in counts), sum(n for _, n in counts)


def runs(n: int) -> str:
    return f"{n} run" if n == 1 else f"{n} runs"


def percent(falls: int, counted: int) -> str:
    return f"{100 * falls / counted:.1f}% ({falls}/{counted})" if counted else "n/a (0 counted)"


def interim(ours: dict, defaults: dict, setting: str, base: str = "the defaults") -> list[str]:
    """What the finished runs show so far, on the cells both ``setting`` and ``base`` (``defaults``'
    setting) have: not the verdict, which waits for every run, but its direction."""
    keys = sorted(set(ours) & set(defaults))
    if not keys:
        return []
    of = base + ("'" if base.endswith("s") else "'s")
    above = sum(ours[key].last5 > defaults[key].last5 for key in keys)
    return [
        "",
        f"Interim, not the verdict: on the {len(keys)} (env, teacher, seed) cells both the {setting} "
        f"and {base} have finished:",
        "",
        f"- runs passing their teacher: {sum(ours[k].passed for k in keys)} against {of} "
        f"{sum(defaults[k].passed for k in keys)};",
        f"- fall share on Hopper and Walker2d: {percent(*pooled_falls(ours, keys))} against {of} "
        f"{percent(*pooled_falls(defaults, keys))};",
        f"- last-5 above {of} on {above} of {len(keys)} cells.",
    ]


def out_of_reach(ours: dict, setting: str) -> list[str]:
    """The criteria of the first set that ``setting``'s finished runs already miss, whatever its runs
    still to come: a run that never passed its teacher, a paper-teacher last-5 mean below its bound
    (:data:`MIN_VS_TEACHER`) with all five of the env's runs in, or a fall share above
    :data:`MAX_FALL_SHARE` even if every Hopper and Walker2d run to come counts the most evaluations a
    run can (:data:`MAX_COUNTED`) and falls in none."""
    lines = []
    failed = [f"{env} {teacher} seed {seed}" for (env, teacher, seed), run in sorted(ours.items()) if not run.passed]
    if failed:
        shown = failed[:6] + ([f"{len(failed) - 6} more"] if len(failed) > 6 else [])
        lines.append(f"- every run passes its teacher: missed, as {listed(shown)} never passed.")
    for env in ENVS:
        if all((env, "paper", seed) in ours for seed in SEEDS):
            mean, teacher = paper_mean(ours, env)[0], ours[env, "paper", SEEDS[0]].teacher_return
            if mean / teacher < MIN_VS_TEACHER[env]:
                lines.append(
                    f"- {env}: last-5 at least {MIN_VS_TEACHER[env]} x the teacher: missed, as it is "
                    f"{mean / teacher:.2f} x ({mean:.1f} against {teacher:.1f}), its five runs in."
                )
    falls, counted = pooled_falls(ours, list(ours))
    to_come = sum(key not in ours for key in needed(setting) if key[0] in FALL_ENVS)
    best = counted + to_come * MAX_COUNTED
    if best and falls / best > MAX_FALL_SHARE:
        if to_come:
            each = (
                f"that {'counts' if to_come == 1 else 'count'} at most {MAX_COUNTED}{'' if to_come == 1 else ' each'}"
            )
            how = f"at least {percent(falls, best)}: {falls} falls in {counted} evaluations so far, and "
            how += f"{runs(to_come)} to come {each}, all without a fall"
        else:
            how = f"{percent(falls, best)} over its finished runs, all of them in"
        lines.append(f"- fall share on Hopper and Walker2d at most 5%: missed, as it is {how}.")
    if not lines:
        return []
    return ["", f"Already out of reach for the {setting}, whatever its runs to come (the first set):", "", *lines]


def cells(keys: list[tuple[str, str, int]]) -> str:
    """The first six (env, teacher, seed) cells of ``keys``, and how many more."""
    shown = ", ".join(f"{env} {teacher} seed {seed}" for env, teacher, seed in keys[:6])
    return shown + (f" and {len(keys) - 6} more" if len(keys) > 6 else "")


def unneeded(keys: list, skipped, reason: str) -> str:
    """What of a setting's missing ``keys`` the verdict does not wait for (``skipped``), and why."""
    if not skipped:
        return ""
    if len(skipped) == len(keys):
        return f" (not needed for the verdict: {reason})"
    return f" ({len(skipped)} not needed for the verdict, as {reason}: {cells(list(skipped))})"


def not_awaited(
    ours: dict, defaults: dict, missing: dict, setting: str, first_missed: bool
) -> dict[str, tuple[list, str]]:
    """The missing runs the verdict does not wait for, per setting, with why: none of them can change it.

    DAC's runs count in the first set alone (its third criterion): not awaited once that set is missed.
    The defaults' with the shipped Swimmer and HalfCheetah teachers count in the second set's first
    criterion alone (the runs passing their teacher): not awaited once every run of the setting is in and
    that criterion is decided whatever the defaults' missing runs do (the setting's passes above the most
    the defaults can reach, or not above what they have).
    """
    skipped = {}
    if first_missed and missing["dac"]:
        skipped["dac"] = (missing["dac"], "the first set is missed")
    counted_only = [key for key in missing["defaults"] if key[1] != "paper" and key[0] not in FALL_ENVS]
    if counted_only and not missing[setting]:
        passed, default_passed = sum(r.passed for r in ours.values()), sum(r.passed for r in defaults.values())
        if passed > default_passed + len(missing["defaults"]) or passed <= default_passed:
            skipped["defaults"] = (counted_only, "the count of runs passing is decided")
    return skipped


def first_set(ours: dict, dac: dict, dac_missing: bool) -> list[tuple[str, bool | None]]:
    """The first set's criteria on ``ours`` (every run of the setting in), each with whether it is met
    (None: not judged, as DAC's runs are not all in)."""
    passed = sum(r.passed for r in ours.values())
    falls, counted = pooled_falls(ours)
    share = falls / counted if counted else math.inf  # no evaluation after a pass: not met
    criteria = [(f"every run passes its teacher: {passed} of {len(ours)}", passed == len(ours))]
    for env in ENVS:
        mean, _ = paper_mean(ours, env)
        teacher = ours[env, "paper", 0].teacher_return
        ratio = mean / teacher
        criteria.append(
            (
                f"{env}: last-5 {mean:.1f} = {ratio:.2f} x the teacher ({teacher:.1f}), at least {MIN_VS_TEACHER[env]}",
                ratio >= MIN_VS_TEACHER[env],
            )
        )
    for env in ENVS:
        if dac_missing:
            criteria.append((f"{env}: last-5 above DAC's (DAC's runs are not all in)", None))
            continue
        mean, dac_mean = paper_mean(ours, env)[0], paper_mean(dac, env)[0]
        criteria.append((f"{env}: last-5 {mean:.1f} above DAC's {dac_mean:.1f}", mean > dac_mean))
    text = f"fall share on Hopper and Walker2d {percent(falls, counted)}, at most 5%"
    criteria.append((text, share <= MAX_FALL_SHARE))
    return criteria


def judge(found: dict, setting: str) -> list[str]:
    """The rule on ``setting`` (``candidate`` or ``penalty``) against the defaults and DAC, as Markdown."""
    ours, defaults, dac = found[setting], found["defaults"], found["dac"]
    lines = [f"### {setting}", ""]
    missing = {name: [k for k in needed(name) if k not in found[name]] for name in (setting, "defaults", "dac")}
    missed = out_of_reach(ours, setting)
    skipped = not_awaited(ours, defaults, missing, setting, bool(missed))
    awaited = [name for name, keys in missing.items() if set(keys) - set(skipped.get(name, ((), ""))[0])]
    for name, keys in missing.items():
        if keys:
            why = unneeded(keys, *skipped.get(name, ((), "")))
            lines.append(f"- {name}: {len(keys)} runs missing ({cells(keys)}){why}")
    if awaited:
        return [
            *lines,
            *interim(ours, defaults, setting),
            *missed,
            "",
            "**Verdict: pending.**",
            "",
        ]
    if missing["dac"]:
        lines += [*missed, ""]
    passed = sum(r.passed for r in ours.values())
    default_passed = sum(r.passed for r in defaults.values())
    falls, counted = pooled_falls(ours)
    default_falls, default_counted = pooled_falls(defaults)
    # no evaluation after a pass: the share is undefined, and a criterion on it is not met
    share = falls / counted if counted else math.inf
    default_share = default_falls / default_counted if default_counted else -math.inf
    first, second = first_set(ours, dac, bool(missing["dac"])), []
    if missing["defaults"]:  # their runs not in cannot change this count (not_awaited)
        most = default_passed + len(missing["defaults"])
        text = f"runs passing: {passed} against the defaults' {default_passed}, at most {most} with their "
        second.append((text + f"{runs(len(missing['defaults']))} not in", passed > most))
    else:
        second.append((f"runs passing: {passed} against the defaults' {default_passed}", passed > default_passed))
    for env in ENVS:
        mean, (base, std) = paper_mean(ours, env)[0], paper_mean(defaults, env)
        second.append(
            (
                f"{env}: last-5 {mean:.1f}, not below the defaults' {base:.1f} - {std:.1f} = {base - std:.1f}",
                mean >= base - std,
            )
        )
    second.append(
        (
            f"fall share {percent(falls, counted)}, not above the defaults' {percent(default_falls, default_counted)}",
            share <= default_share,
        )
    )
    lines += [*criteria_lines("First set", first), *criteria_lines("Second set", second)]
    met_first, met_second = all(ok for _, ok in first), all(ok for _, ok in second)
    verdict = "meets the first set" if met_first else "meets the second set" if met_second else "meets neither set"
    return [*lines, f"**Verdict: {setting} {verdict}.**", ""]


def criteria_lines(title: str, criteria: list[tuple[str, bool | None]]) -> list[str]:
    """A set of criteria as a Markdown list, each marked met, MISSED or not judged (None)."""
    marks = {True: "met", False: "MISSED", None: "not judged"}
    return [f"{title}:", "", *(f"- {marks[ok]}: {text}" for text, ok in criteria), ""]


def verdict(lines: list[str]) -> str:
    """``pending``, ``first``, ``second`` or ``neither``, from :func:`judge`'s last line."""
    last = next(line for line in reversed(lines) if line.startswith("**Verdict"))
    return next(word for word in ("pending", "first", "second", "neither") if word in last)


def decision(candidate: str, penalty: str) -> str:
    """The rule's decision from the two verdicts, in the rule's order."""
    if candidate in ("first", "second"):  # the penalty alone is judged only where the candidate meets neither
        return f"**Decision: the candidate becomes the default** (it meets the {candidate} set)."
    if "pending" in (candidate, penalty):
        return "**Decision: pending** (the verdicts wait for every run they need)."
    if penalty in ("first", "second"):
        return (
            f"**Decision: the penalty alone becomes the default** (it meets the {penalty} set; the candidate neither)."
        )
    return "**Decision: the defaults stay**; the candidate and the penalty alone remain options (neither meets a set)."


def spread(values: list[float]) -> str:
    """Mean ± sample std of ``values`` (the mean alone for one value); ``-`` if there are none."""
    if not values:
        return "-"
    std = f" ± {statistics.stdev(values):.1f}" if len(values) > 1 else ""
    return f"{statistics.fmean(values):.1f}{std}"


def table(found: dict, keeps_none: str = "the penalty alone") -> list[str]:
    """One row per env, teacher (its return) and setting: the seeds finished so far, how many passed
    their teacher, last-5, the best policy and the fall share pooled over those seeds. The penalty
    alone keeps no best policy (its actor is not the one kept); DAC runs with the paper's teachers only."""
    lines = [
        "Per env, teacher and setting, over the seeds finished so far: how many passed their teacher; the "
        "mean ± sample std of each run's last-5 and of its best policy (50 episodes, kept by the SAIL "
        f"authors' rule; not part of the rule; `-` where the setting keeps none, as {keeps_none}, or "
        "its runs predate it, with how many seeds have one where only some do); and the fall share pooled "
        "over those seeds (the rule counts falls on Hopper and Walker2d only, pooled over both teachers).",
        "",
        "| env | teacher | setting | seeds | passed teacher | last-5 | best policy | fall share |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for env in ENVS:
        for teacher in TEACHERS:
            runs = {
                name: [results[env, teacher, seed] for seed in SEEDS if (env, teacher, seed) in results]
                for name, results in found.items()
                if name != "dac" or teacher == "paper"
            }
            returns = [run.teacher_return for setting_runs in runs.values() for run in setting_runs]
            shown = f"{teacher} ({returns[0]:.1f})" if returns else teacher
            for name, setting_runs in runs.items():
                best = [run.best_policy for run in setting_runs if run.best_policy is not None]
                # runs from before the best policy was kept have none: say over how many seeds it is
                some = f" ({len(best)} of {len(setting_runs)})" if 0 < len(best) < len(setting_runs) else ""
                falls = [run.falls for run in setting_runs]
                share = percent(sum(f for f, _ in falls), sum(n for _, n in falls)) if setting_runs else "-"
                lines.append(
                    f"| {env} | {shown} | {name} | {len(setting_runs)} | {sum(run.passed for run in setting_runs)} "
                    f"| {spread([run.last5 for run in setting_runs])} | {spread(best)}{some} | {share} |"
                )
    return [*lines, ""]


def kept_policies(found: dict) -> list[str]:
    """Where each setting's runs kept their best policy: how many within the last :data:`LATE` frames
    of the run, below their own last-5, and below their teacher; and the env and teacher cells where
    every run kept it that late."""
    lines = []
    for name, results in found.items():
        kept = [run for run in results.values() if run.best_policy is not None and run.best_policy_frames is not None]
        if not kept:
            continue
        late = sum(run.best_policy_frames > FRAMES - LATE for run in kept)
        below_last5 = sum(run.best_policy < run.last5 for run in kept)
        below_teacher = sum(run.best_policy < run.teacher_return for run in kept)
        # (env, teacher) cells whose every run kept it late: runs still climbing when they stopped
        climbing = [
            f"{env} {teacher}"
            for env in ENVS
            for teacher in TEACHERS
            if (cell := [run for run in kept if (run.env, run.teacher) == (env, teacher)])
            and all(run.best_policy_frames > FRAMES - LATE for run in cell)
        ]
        plural = "s" if len(climbing) > 1 else ""
        every = (
            f" Every run with a best policy kept it there with the {listed(climbing)} teacher{plural}."
            if climbing
            else ""
        )
        lines.append(
            f"- {name}: of its {runs(len(kept))} with a best policy, {late} kept it in the last {LATE // 1000}k "
            f"frames; it is below the run's last-5 in {below_last5} and below the teacher in {below_teacher}.{every}"
        )
    if not lines:
        return []
    return [
        "Where the best policy was kept. The authors' rule keeps the policy at the highest mean return of the "
        "last `eval.best_policy.window` training episodes, a span of many thousand frames, so where that mean "
        "is still climbing at the end of a run, the policy kept is close to the last one, fallen or not.",
        "",
        *lines,
        "",
    ]


def report(roots: list[Path]) -> str:
    found = settings(roots)
    lines = [
        "## The trusted-default rule on the committed runs",
        "",
        f"Written by `benchmarks/trusted_rule.py`: 300k frames, seeds {SEEDS[0]}-{SEEDS[-1]}; runs found: "
        + ", ".join(f"{name} {len(results)}" for name, results in found.items())
        + ".",
        "",
    ]
    candidate, penalty = judge(found, "candidate"), judge(found, "penalty")
    lines += [
        *table(found),
        *kept_policies(found),
        *candidate,
        *penalty,
        decision(verdict(candidate), verdict(penalty)),
    ]
    return "\n".join(lines)


def rule_main(make_report: Callable[[list[Path]], str], doc: str, argv: list[str] | None = None) -> int:
    """The command line of a rule script (this one, ``hold_rule.py``, ``remedy_rule.py``): its report of
    the results folders given (``make_report``), printed and, with ``--out``, written (the folder made if
    new). ``doc`` is the script's docstring, whose first line describes it."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=Path, help="results folders (e.g. benchmarks/results/campaign)")
    parser.add_argument("--out", type=Path, help="also write the report to this Markdown file")
    args = parser.parse_args(argv)
    text = make_report(args.roots)
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(args.out, text + "\n")
    return 0


def main(argv: list[str] | None = None) -> int:
    return rule_main(report, __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
