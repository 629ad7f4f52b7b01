"""The trusted-default decision rule (``docs/results.md``, "The trusted default: decision rule"), applied
to the committed runs: each criterion's figures and whether it is met, or what is still missing.

    python benchmarks/trusted_rule.py benchmarks/results/campaign [--out benchmarks/results/trusted/rule.md]

The rule compares three settings at 300k frames, seeds 0-4, on the paper's four teachers and the
four shipped ones (``examples/teachers``): the candidate (teacher labels ``paper-trusted`` and
``shipped-trusted``, the target actor's evaluations ``eval/return``), the penalty alone (the same
runs' ``eval/return_online``: training does not depend on the evaluated actor) and the defaults
(labels ``paper`` and ``shipped``, SAIL), with DAC (label ``paper``) beside them. Per run: whether
an evaluation passed the teacher, the last-5 mean and the fall share
(:func:`torchrl_sail.harness.fall_share`). The verdict is ``pending`` until every run the rule needs
is finished; meanwhile an interim block compares each setting with the defaults on the cells both have.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import HEADLINE_EVALS, find_run_folders, load_run  # noqa: E402

from torchrl_sail.harness import fall_share, read_scalar, write_atomic  # noqa: E402

SEEDS = (0, 1, 2, 3, 4)
FRAMES = 300_000
TEACHERS = ("paper", "shipped")
# criterion 2 of the first set: the last-5 mean over the teacher's return, per env (paper's teachers)
MIN_VS_TEACHER = {"Hopper-v4": 1.5, "Walker2d-v4": 1.5, "Swimmer-v4": 1.5, "HalfCheetah-v4": 1.2}
ENVS = tuple(MIN_VS_TEACHER)
FALL_ENVS = ("Hopper-v4", "Walker2d-v4")  # where a fall ends an episode
MAX_FALL_SHARE = 0.05


@dataclass
class Result:
    """One run's figures under one setting."""

    env: str
    teacher: str  # paper | shipped
    seed: int
    teacher_return: float
    evals: list[tuple[int, float]]

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


def settings(roots: list[Path]) -> dict[str, dict[tuple[str, str, int], Result]]:
    """Every finished 300k run the rule reads, by setting and (env, teacher, seed)."""
    found = {"candidate": {}, "penalty": {}, "defaults": {}, "dac": {}}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        total = (run.config.get("collector") or {}).get("total_frames")
        if run.problem is not None or total != FRAMES or run.seed not in SEEDS or run.env not in ENVS:
            continue
        base = run.teacher.removesuffix("-trusted")
        if base not in TEACHERS or run.method not in ("sail", "dac"):
            continue
        key = (run.env, base, run.seed)
        if run.teacher.endswith("-trusted"):
            if run.method != "sail":
                continue
            found["candidate"][key] = Result(*key, run.teacher_return, run.curve)
            online = sorted(dict(read_scalar(folder, "eval/return_online")).items())
            if online:
                found["penalty"][key] = Result(*key, run.teacher_return, online)
        else:
            if run.method == "dac" and base == "paper":
                found["dac"][key] = Result(*key, run.teacher_return, run.curve)
            elif run.method == "sail":
                found["defaults"][key] = Result(*key, run.teacher_return, run.curve)
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


def percent(falls: int, counted: int) -> str:
    return f"{100 * falls / counted:.1f}% ({falls}/{counted})" if counted else "n/a (0 counted)"


def interim(ours: dict, defaults: dict, setting: str) -> list[str]:
    """What the finished runs show so far, on the cells both ``setting`` and the defaults have: not the
    verdict, which waits for every run, but its direction."""
    keys = sorted(set(ours) & set(defaults))
    if not keys:
        return []
    above = sum(ours[key].last5 > defaults[key].last5 for key in keys)
    return [
        "",
        f"Interim, not the verdict: on the {len(keys)} (env, teacher, seed) cells both the {setting} "
        "and the defaults have finished:",
        "",
        f"- runs passing their teacher: {sum(ours[k].passed for k in keys)} against the defaults' "
        f"{sum(defaults[k].passed for k in keys)};",
        f"- fall share on Hopper and Walker2d: {percent(*pooled_falls(ours, keys))} against the defaults' "
        f"{percent(*pooled_falls(defaults, keys))};",
        f"- last-5 above the defaults' on {above} of {len(keys)} cells.",
    ]


def judge(found: dict, setting: str) -> list[str]:
    """The rule on ``setting`` (``candidate`` or ``penalty``) against the defaults and DAC, as Markdown."""
    ours, defaults, dac = found[setting], found["defaults"], found["dac"]
    lines = [f"### {setting}", ""]
    missing = {name: [k for k in needed(name) if k not in found[name]] for name in (setting, "defaults", "dac")}
    if any(missing.values()):
        for name, keys in missing.items():
            if keys:
                shown = ", ".join(f"{env} {teacher} seed {seed}" for env, teacher, seed in keys[:6])
                more = f" and {len(keys) - 6} more" if len(keys) > 6 else ""
                lines.append(f"- {name}: {len(keys)} runs missing ({shown}{more})")
        return [*lines, *interim(ours, defaults, setting), "", "**Verdict: pending.**", ""]
    passed = sum(r.passed for r in ours.values())
    default_passed = sum(r.passed for r in defaults.values())
    falls, counted = pooled_falls(ours)
    default_falls, default_counted = pooled_falls(defaults)
    share = falls / counted if counted else 0.0
    default_share = default_falls / default_counted if default_counted else 0.0
    first, second = [], []
    first.append((f"every run passes its teacher: {passed} of {len(ours)}", passed == len(ours)))
    for env in ENVS:
        mean, _ = paper_mean(ours, env)
        teacher = ours[env, "paper", 0].teacher_return
        ratio = mean / teacher
        first.append(
            (
                f"{env}: last-5 {mean:.1f} = {ratio:.2f} x the teacher ({teacher:.1f}), at least {MIN_VS_TEACHER[env]}",
                ratio >= MIN_VS_TEACHER[env],
            )
        )
    for env in ENVS:
        mean, dac_mean = paper_mean(ours, env)[0], paper_mean(dac, env)[0]
        first.append((f"{env}: last-5 {mean:.1f} above DAC's {dac_mean:.1f}", mean > dac_mean))
    first.append(
        (
            f"fall share on Hopper and Walker2d {100 * share:.1f}% ({falls}/{counted}), at most 5%",
            share <= MAX_FALL_SHARE,
        )
    )
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
            f"fall share {100 * share:.1f}% ({falls}/{counted}), not above the defaults' "
            f"{100 * default_share:.1f}% ({default_falls}/{default_counted})",
            share <= default_share,
        )
    )
    for title, criteria in (("First set", first), ("Second set", second)):
        lines += [f"{title}:", ""] + [f"- {'met' if ok else 'MISSED'}: {text}" for text, ok in criteria] + [""]
    met_first, met_second = all(ok for _, ok in first), all(ok for _, ok in second)
    verdict = "meets the first set" if met_first else "meets the second set" if met_second else "meets neither set"
    return [*lines, f"**Verdict: {setting} {verdict}.**", ""]


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
    lines += judge(found, "candidate")
    lines += judge(found, "penalty")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=Path, help="results folders (e.g. benchmarks/results/campaign)")
    parser.add_argument("--out", type=Path, help="also write the report to this Markdown file")
    args = parser.parse_args(argv)
    text = report(args.roots)
    print(text)
    if args.out:
        write_atomic(args.out, text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
