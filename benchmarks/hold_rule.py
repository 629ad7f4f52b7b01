"""Whether the teacher buffer's change causes the falls (``docs/results.md``, "What a fall on Hopper
is"): the runs that held it after its first refill against the same seeds' runs that went on
raising it, read by the rule written before the runs.

    python benchmarks/hold_rule.py benchmarks/results/campaign [--out benchmarks/results/hold/rule.md]

The runs are ``benchmarks/campaign.py``'s: ``--stages average`` trains the trusted-default candidate
with the paper's Hopper teacher on seeds 100-103 (teacher labels ``paper-average10k`` and
``paper-average30k``), ``--stages hold`` the same cells with ``algo.max_promoted=10`` (labels
``<the average run's label>-hold``, 200k frames): promotions stop once 10 agent trajectories are in
the teacher buffer. With the paper's one-episode teacher, the top-K buffer (K = 10) fills its empty
places with the first 9 promotions while C stays at the demonstration's r_e; the tenth evicts the
demonstration and C rises once, to the lowest of the 10 agent trajectories. A batch may promote
several trajectories, so a held run can end past 10 (the report gives its count, and C at the
hold and at 200k). Per seed, the hold frame is the first logged frame at which the held run had
promoted 10; the split is the first logged frame at which the other run had promoted more than the
held run ever did: up to there the hold changed nothing, and on one commit and machine, without a
restart before it, both runs train alike (the report says where a pair's evaluations first differ
before the hold, if they do; such a pair still counts, as two runs of the same setting but the
hold). The window is each run's evaluations after the split, up to 200k frames. In it, per actor
(the target actor, shipped by the candidate, decides; the online actor is reported beside it):

- a fall is an evaluation below the teacher's return after the run's first pass (the fall share's
  own definition, :func:`torchrl_sail.harness.fall_share`);
- a drop is an evaluation below half of the best earlier evaluation of the same actor in the same
  run: a held buffer keeps C near the teacher's own level, so a held run may stay close above its
  teacher, and falls below the teacher, counted alone, would favour the runs whose C rose.

The reading, of the target actor's drops pooled over the seeds: the teacher buffer's change **is a
cause** of the drops if the held runs dropped in at most :data:`MAX_SHARE_OF_BASELINE` of the other
runs' share, those had at least :data:`MIN_BASELINE_DROPS` drops, and in at least
:data:`MIN_SEEDS_AGREEING` seeds the held run dropped no more often than its pair; it is **not
shown** to be if the held runs dropped at least as often as the others; **inconclusive** otherwise.
``pending`` until every run of both stages is finished. A run is refused, naming its folder, when
its config was not run with its stage's settings or when two runs claim one seed.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from aggregate import find_run_folders, load_run  # noqa: E402
from campaign import AVERAGE_SEEDS, HOLD_FRAMES  # noqa: E402
from trusted_rule import percent, refuse_unless_ran_with, rule_main  # noqa: E402

from torchrl_sail.harness import read_scalar  # noqa: E402

MAX_PROMOTED = 10
MAX_SHARE_OF_BASELINE = 0.5
MIN_BASELINE_DROPS = 4
MIN_SEEDS_AGREEING = 3  # seeds whose held run dropped no more often than its pair
ENV = "Hopper-v4"
SEEDS = tuple(seed for seeds in AVERAGE_SEEDS.values() for seed in seeds)
CANDIDATE = {"optim.actor_preactivation_coef": 0.001, "eval.actor": "target", "eval.other_actor": True}
ACTORS = {"target": "eval/return", "online": "eval/return_online"}  # the candidate evaluates the target actor


@dataclass
class Arm:
    """One run of a pair: its folder, teacher return, evaluations per actor, and its logged C and promotions."""

    folder: Path
    teacher_return: float
    evals: dict[str, list[tuple[int, float]]]
    threshold: list[tuple[int, float]]
    promoted: list[tuple[int, float]]


def label_of(teacher: str) -> tuple[str, int] | None:
    """``("baseline"|"hold", memory)`` of a teacher label, e.g. ``paper-average10k-hold`` -> ``("hold", 10000)``."""
    for memory in AVERAGE_SEEDS:
        base = f"paper-average{memory // 1000}k"
        if teacher == base:
            return "baseline", memory
        if teacher == f"{base}-hold":
            return "hold", memory
    return None


def arm_of(run, arm: str) -> Arm:
    expected = {**CANDIDATE, "algo.max_promoted": MAX_PROMOTED if arm == "hold" else None}
    refuse_unless_ran_with(run, expected, f"counted as a {arm} run", f"the {arm} runs have")
    evals = {actor: sorted(dict(read_scalar(run.folder, tag)).items()) for actor, tag in ACTORS.items()}
    for actor, curve in evals.items():
        if not curve or not all(math.isfinite(value) for _, value in curve):
            raise ValueError(f"{run.folder}: no finite {ACTORS[actor]} evaluations")
    return Arm(
        run.folder,
        float(run.teacher_return),
        evals,
        read_scalar(run.folder, "teacher/threshold"),
        read_scalar(run.folder, "teacher/num_promoted"),
    )


def pairs(roots: list[Path]) -> dict[int, dict[str, Arm]]:
    """The finished runs of both stages by seed: ``{seed: {"baseline": Arm, "hold": Arm}}`` (either may lack)."""
    found: dict[int, dict[str, Arm]] = {}
    for folder in find_run_folders(roots):
        run = load_run(folder)
        claimed = label_of(run.teacher)
        if claimed is None or run.env != ENV or run.method != "sail" or run.problem is not None:
            continue
        arm, memory = claimed
        if run.seed not in AVERAGE_SEEDS[memory]:
            continue
        if arm in found.get(run.seed, {}):
            raise ValueError(f"two {arm} runs of seed {run.seed}: {found[run.seed][arm].folder} and {folder}")
        found.setdefault(run.seed, {})[arm] = arm_of(run, arm)
    return found


def hold_frame(held: Arm) -> int | None:
    """The first logged frame at which the held run had promoted :data:`MAX_PROMOTED` trajectories."""
    return next((frames for frames, value in held.promoted if value >= MAX_PROMOTED), None)


def value_at(series: list[tuple[int, float]], frames: int) -> float | None:
    """The last logged value at or before ``frames``."""
    values = [value for at, value in series if at <= frames]
    return values[-1] if values else None


def first_difference(a: list[tuple[int, float]], b: list[tuple[int, float]], until: int) -> int | None:
    """The first evaluation frame up to ``until`` where the two curves differ (None: identical there)."""
    other = dict(b)
    return next((frames for frames, value in a if frames <= until and other.get(frames) != value), None)


def window_counts(curve: list[tuple[int, float]], teacher: float, after: int) -> dict[str, int]:
    """Evaluations in (``after``, :data:`HOLD_FRAMES`], falls among those after the first pass, and drops."""
    passed_at = next((frames for frames, value in curve if value > teacher), None)
    counts = {"evaluations": 0, "counted": 0, "falls": 0, "drops": 0}
    best = -math.inf
    for frames, value in curve:
        if after < frames <= HOLD_FRAMES:
            counts["evaluations"] += 1
            counts["drops"] += value < best / 2
            if passed_at is not None and frames > passed_at:
                counts["counted"] += 1
                counts["falls"] += value < teacher
        best = max(best, value)
    return counts


def split_frame(held: Arm, other: Arm) -> int | None:
    """The first logged frame at which the other run had promoted more than the held run ever did:
    up to there the hold changed nothing (None: not by :data:`HOLD_FRAMES`)."""
    most = max(value for _, value in held.promoted)
    return next((f for f, value in other.promoted if value > most and f <= HOLD_FRAMES), None)


def report(roots: list[Path]) -> str:
    found = pairs(roots)
    lines = [
        "## The teacher buffer held after its first refill",
        "",
        f"Written by `benchmarks/hold_rule.py`: {ENV}, the paper's teacher, the trusted-default candidate, seeds "
        f"{SEEDS[0]}-{SEEDS[-1]}; held runs stop promoting at {MAX_PROMOTED} promoted trajectories "
        f"(`algo.max_promoted={MAX_PROMOTED}`), their pairs go on. Window: both runs' evaluations after the split "
        f"(the first frame at which the other run had promoted more than the held run), up to "
        f"{HOLD_FRAMES // 1000}k. A fall: below the teacher after the run's first pass; a drop: below half of the "
        "actor's best earlier evaluation.",
        "",
        "| seed | hold frame (held run's promotions) | split | same training up to the hold "
        "| C at the hold, at the end (held / other) "
        "| target actor falls (held / other) | target actor drops (held / other) "
        "| online actor falls (held / other) | online actor drops (held / other) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    pooled = {
        (arm, actor, kind): [0, 0] for arm in ("hold", "baseline") for actor in ACTORS for kind in ("falls", "drops")
    }
    missing, agreeing, counted = [], 0, 0
    for seed in SEEDS:
        pair = found.get(seed, {})
        if set(pair) != {"hold", "baseline"}:
            missing += [f"seed {seed} {arm}" for arm in ("hold", "baseline") if arm not in pair]
            continue
        held_run, other_run = pair["hold"], pair["baseline"]
        at = hold_frame(held_run)
        split = None if at is None else split_frame(held_run, other_run)
        if at is None or split is None:
            why = (
                f"never: {MAX_PROMOTED} trajectories not promoted by {HOLD_FRAMES // 1000}k"
                if at is None
                else f"{at // 1000}k | none: the other run promoted no more by {HOLD_FRAMES // 1000}k"
            )
            lines.append(f"| {seed} | {why} |" + " |" * (8 if at is None else 7))
            continue
        counted += 1
        promoted = max(value for _, value in held_run.promoted)
        differs = first_difference(held_run.evals["target"], other_run.evals["target"], at)
        same = "yes" if differs is None else f"no: first differs at {differs // 1000}k"
        c = f"{value_at(held_run.threshold, at):.0f} / {value_at(other_run.threshold, at):.0f}, "
        c += f"{value_at(held_run.threshold, HOLD_FRAMES):.0f} / {value_at(other_run.threshold, HOLD_FRAMES):.0f}"
        cells = []
        for actor in ACTORS:
            counts = {arm: window_counts(run.evals[actor], run.teacher_return, split) for arm, run in pair.items()}
            for kind, total in (("falls", "counted"), ("drops", "evaluations")):
                for arm in ("hold", "baseline"):
                    pooled[arm, actor, kind][0] += counts[arm][kind]
                    pooled[arm, actor, kind][1] += counts[arm][total]
                mine, theirs = counts["hold"], counts["baseline"]
                cells.append(f"{mine[kind]}/{mine[total]} / {theirs[kind]}/{theirs[total]}")
                if (actor, kind) == ("target", "drops"):
                    agreeing += share(mine[kind], mine[total]) <= share(theirs[kind], theirs[total])
        lines.append(
            f"| {seed} | {at // 1000}k ({promoted:.0f}) | {split // 1000}k | {same} | {c} | " + " | ".join(cells) + " |"
        )
    lines.append(
        "| pooled | | | | | "
        + " | ".join(
            f"{percent(*pooled['hold', actor, kind])} / {percent(*pooled['baseline', actor, kind])}"
            for actor in ACTORS
            for kind in ("falls", "drops")
        )
        + " |"
    )
    return "\n".join([*lines, "", f"**Reading: {reading(pooled, missing, agreeing, counted)}.**"])


def share(part: int, whole: int) -> float:
    return part / whole if whole else 0.0


def reading(pooled: dict, missing: list[str], agreeing: int, counted: int) -> str:
    """The rule's reading of the target actor's drops pooled over the seeds; ``agreeing`` of the
    ``counted`` seeds had a held drop share no higher than the other run's."""
    if missing:
        return f"pending ({len(missing)} runs missing: {', '.join(missing)})"
    if not counted:
        return "no pair reached a split: nothing to compare"
    (held, held_n), (other, other_n) = pooled["hold", "target", "drops"], pooled["baseline", "target", "drops"]
    mine, theirs = percent(held, held_n), percent(other, other_n)
    if (
        other >= MIN_BASELINE_DROPS
        and share(held, held_n) <= MAX_SHARE_OF_BASELINE * share(other, other_n)
        and agreeing >= MIN_SEEDS_AGREEING
    ):
        return (
            f"the teacher buffer's change is a cause of the drops: the held runs' target actor dropped in {mine} of "
            f"their evaluations, at most {MAX_SHARE_OF_BASELINE:g} of the other runs' {theirs}, and no more often "
            f"than its pair in {agreeing} of {counted} seeds"
        )
    if share(held, held_n) >= share(other, other_n):
        return (
            f"not shown: the held runs' target actor dropped in {mine} of their evaluations, not less often than "
            f"the other runs' {theirs}"
        )
    return (
        f"inconclusive: the held runs' target actor dropped in {mine} of their evaluations against the other "
        f"runs' {theirs}, no more often than its pair in {agreeing} of {counted} seeds (a cause needs at most "
        f"{MAX_SHARE_OF_BASELINE:g} of it, at least {MIN_BASELINE_DROPS} drops there and at least "
        f"{MIN_SEEDS_AGREEING} seeds)"
    )


def main(argv: list[str] | None = None) -> int:
    return rule_main(report, __doc__, argv)


if __name__ == "__main__":
    sys.exit(main())
