"""``benchmarks/falls.py``: both actors' falls and the logs before them, on a hand-made run folder."""

from __future__ import annotations

import json

import pytest
from benchmark_scripts import load_benchmark

falls = load_benchmark("falls")


def write_run(folder, rows, evaluated="target", summary=True):
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(f"eval:\n  actor: {evaluated}\n")
    if summary:
        (folder / "summary.json").write_text(json.dumps({"teacher_return": 100.0}))
    lines = ["tag,frames,value"] + [f"{tag},{frames},{value}" for tag, frames, value in rows]
    (folder / "scalars.csv").write_text("\n".join(lines) + "\n")


def rows(online_tag="eval/return_online", target_tag="eval/return"):
    online = {10_000: 50, 20_000: 150, 30_000: 40, 40_000: 160, 50_000: 30}
    target = {10_000: 50, 20_000: 140, 30_000: 120, 40_000: 150, 50_000: 90}
    return [
        *((online_tag, f, v) for f, v in online.items()),
        *((target_tag, f, v) for f, v in target.items()),
        *(("actor/change", f, v) for f, v in {25_000: 0.5, 35_000: 0.1, 45_000: 0.9}.items()),
        *(("teacher/num_promoted", f, v) for f, v in {15_000: 1, 25_000: 3, 45_000: 6}.items()),
    ]


def test_falls_of_both_actors_and_the_logs_before_them(tmp_path):
    write_run(tmp_path / "run", rows())
    line, after = falls.run_rows(tmp_path / "run", window=10_000)
    # the online actor passed at 20k; after it 40 and 30 fell of (40, 160, 30); the target: 90 of (120, 150, 90)
    assert line["passed_at"] == 20_000
    assert line["online"] == {"share": 2 / 3, "falls": 2, "evaluations": 3}
    assert line["target"] == {"share": 1 / 3, "falls": 1, "evaluations": 3}
    assert (line["online_only"], line["target_only"]) == (1, 0)  # 30k: online alone; 50k: both
    assert [row["fell"] for row in after] == [True, False, True]
    assert [row["actor/change"] for row in after] == [0.5, 0.1, 0.9]
    assert [row["promoted"] for row in after] == [2, 0, 3]  # 3 - 1, 3 - 3, 6 - 3
    text = falls.report([tmp_path / "run"], window=10_000)
    assert "| 66.7% (2/3) | 33.3% (1/3) | 1 | 0 |" in text
    # z-scores within the run: actor/change (0.5, 0.1, 0.9) has mean 0.5 and standard deviation
    # sqrt(0.32 / 3) = 0.3266, so (0, -1.225, 1.225); promoted (2, 0, 3): mean 5/3, sd sqrt(42 / 27) = 1.247,
    # so (0.2673, -1.336, 1.069). Online falls (30k, 50k) against 40k; the target's fall (50k) against 30k, 40k
    assert "| `actor/change` | 0.61 (n=2) | -1.22 (n=1) | 1.22 (n=1) | -0.61 (n=2) |" in text
    assert "| `promoted` | 0.67 (n=2) | -1.34 (n=1) | 1.07 (n=1) | -0.53 (n=2) |" in text
    assert "target actor's 1 falls against its 2 others" in text
    # 30k's fall is back above at 40k; 50k's is the last evaluation; the target's only fall is at 50k
    assert [(row["back"], row["target_back"]) for row in after] == [(True, False), (False, False), (False, False)]
    assert "by the next evaluation (a dip of one evaluation, not a collapse): 1 of the online " in text
    assert "actor's 2 falls, 0 of the target actor's 1 (a run's last" in text
    assert (
        "Both actors fell at the same evaluation: 1 of the target actor's 1 falls came with a fall of the online actor"
        in text
    )  # 50k


def test_the_changes_since_the_previous_window_before_each_fall(tmp_path):
    """The change table, hand-computed on rows(): actor/change's windows (0.5, 0.1, 0.9) at 30k, 40k, 50k
    change by (-, -0.4, +0.8), z-scores (-1, 1) (mean 0.2, sd 0.6); promoted (2, 0, 3) by (-, -2, +3),
    z-scores (-1, 1) (mean 0.5, sd 2.5). The online actor fell at 30k (no change: the first row) and 50k,
    the target at 50k; where in the run the falls came, as a z-score of their frames."""
    write_run(tmp_path / "run", rows())
    _, after = falls.run_rows(tmp_path / "run", window=10_000)
    deltas = falls.changes(after)
    assert deltas[0]["actor/change"] is None and deltas[1]["actor/change"] == pytest.approx(-0.4)
    assert [row["promoted"] for row in deltas] == [None, -2, 3]
    text = falls.report([tmp_path / "run"], window=10_000)
    table = text.split("| diagnostic, change since the previous window |")[1]
    assert "| `actor/change` | 1.00 (n=1) | -1.00 (n=1) | 1.00 (n=1) | -1.00 (n=1) |" in table
    assert "| `promoted` | 1.00 (n=1) | -1.00 (n=1) | 1.00 (n=1) | -1.00 (n=1) |" in table
    assert "| `teacher/threshold` | - | - | - | - |" in table  # not logged by this run
    # positions: 30k, 40k, 50k are (-1.22, 0, 1.22) within the run (mean 40k, sd 8165)
    assert "the online actor's falls 0.00 (n=2), its other evaluations 0.00 (n=1)" in text
    assert "the target actor's falls 1.22 (n=1), its others -0.61 (n=2)" in text


def test_falls_after_the_thresholds_largest_rises_in_each_half_of_the_run(tmp_path):
    """Both actors pass at 20k; evaluations 30k-90k follow, 30k-60k the first half (60k the middle).
    C's window means (10, 10, 20, 21, 21, 40, 40) change by (-, 0, +10, +1, 0, +19, 0): of 6 changes the
    largest ceil(6 / 4) = 2 are +19 (80k) and +10 (50k). Online falls at 50k, 80k, 90k; target at 40k, 90k."""
    online = {10_000: 50, 20_000: 150, 30_000: 150, 40_000: 150, 50_000: 40}
    online |= {60_000: 150, 70_000: 150, 80_000: 30, 90_000: 30}
    target = {10_000: 50, 20_000: 140, 30_000: 140, 40_000: 90, 50_000: 140}
    target |= {60_000: 140, 70_000: 140, 80_000: 140, 90_000: 90}
    threshold = {25_000: 10, 35_000: 10, 45_000: 20, 55_000: 21, 65_000: 21, 75_000: 40, 85_000: 40}
    write_run(
        tmp_path / "run",
        [
            *(("eval/return_online", f, v) for f, v in online.items()),
            *(("eval/return", f, v) for f, v in target.items()),
            *(("teacher/threshold", f, v) for f, v in threshold.items()),
        ],
    )
    _, after = falls.run_rows(tmp_path / "run", window=10_000)
    marked = falls.largest_rises(falls.changes(after))
    assert [row["largest_rise"] for row in marked] == [None, False, True, False, False, True, False]
    assert [row["late"] for row in marked] == [False, False, False, False, True, True, True]
    text = falls.report([tmp_path / "run"], window=10_000)
    table = text.split("| half of the run | C's change | online actor fell | target actor fell |")[1]
    assert "| first | a largest rise | 100% (1/1) | 0% (0/1) |" in table  # 50k
    assert "| first | other | 0% (0/2) | 50% (1/2) |" in table  # 40k, 60k
    assert "| second | a largest rise | 100% (1/1) | 0% (0/1) |" in table  # 80k
    assert "| second | other | 50% (1/2) | 50% (1/2) |" in table  # 70k, 90k


def test_the_share_of_episodes_below_the_teacher_at_each_actors_falls(tmp_path):
    below_online = {20_000: 0.0, 30_000: 0.8, 40_000: 0.0, 50_000: 1.0}
    below_target = {20_000: 0.0, 30_000: 0.1, 40_000: 0.0, 50_000: 0.6}
    write_run(
        tmp_path / "run",
        [
            *rows(),
            *(("eval/below_teacher_online", f, v) for f, v in below_online.items()),
            *(("eval/below_teacher", f, v) for f, v in below_target.items()),
        ],
    )
    text = falls.report([tmp_path / "run"], window=10_000)
    # online falls at 30k and 50k (0.8, 1.0) against 40k (0.0); the target's at 50k (0.6) against 30k, 40k
    assert "(`eval/below_teacher`, not a z-score) | 0.90 (n=2) | 0.00 (n=1) | 0.60 (n=1) | 0.05 (n=2) |" in text
    # a run that did not log it
    write_run(tmp_path / "old", rows())
    assert "not a z-score) | - | - | - | - |" in falls.report([tmp_path / "old"], window=10_000)


def test_the_target_actors_falls_count_from_its_own_first_pass(tmp_path):
    online = {10_000: 150, 20_000: 40, 30_000: 160, 40_000: 170}
    target = {10_000: 50, 20_000: 60, 30_000: 120, 40_000: 80}  # first above the teacher (100) at 30k
    write_run(
        tmp_path / "run",
        [
            *(("eval/return_online", f, v) for f, v in online.items()),
            *(("eval/return", f, v) for f, v in target.items()),
            *(("actor/change", f, v) for f, v in {15_000: 1.0, 25_000: 2.0, 35_000: 3.0}.items()),
        ],
    )
    line, after = falls.run_rows(tmp_path / "run", window=10_000)
    assert line["target"] == {"share": 1.0, "falls": 1, "evaluations": 1}  # 80 at 40k, after its pass at 30k
    # 20k (60) and 30k (120) are before or at the target's pass: not judged, not falls
    assert [row["target_fell"] for row in after] == [None, None, True]
    assert (line["online_only"], line["target_only"]) == (0, 1)  # 20k, the online fall, has no target verdict
    assert "target actor's 1 falls against its 0 others" in falls.report([tmp_path / "run"], window=10_000)


def test_z_scores_pool_runs_of_other_scales_and_signs():
    rows = [{**{key: None for key in falls.DIAGNOSTICS}, "promoted": 0.0} for _ in range(3)]
    for row, value in zip(rows, (-30.0, -10.0, -20.0), strict=True):  # a logit reward's negative Q
        row["sail/q_mean"] = value
    z = [row["sail/q_mean"] for row in falls.standardized(rows)]
    assert z == pytest.approx([-1.2247, 1.2247, 0.0], abs=1e-4)  # mean -20, sd sqrt(200 / 3) = 8.165
    assert all(row["promoted"] is None and row["actor/change"] is None for row in falls.standardized(rows))


def test_a_run_that_evaluated_the_online_actor_reads_its_target_actor_as_the_other(tmp_path):
    write_run(tmp_path / "run", rows("eval/return", "eval/return_target"), evaluated="online")
    line, _ = falls.run_rows(tmp_path / "run", window=10_000)
    assert line["online"]["falls"] == 2 and line["target"]["falls"] == 1


def test_a_run_that_evaluated_the_online_actor_alone_has_no_target_figures(tmp_path):
    write_run(
        tmp_path / "run",
        [r for r in rows("eval/return", "eval/return_target") if r[0] != "eval/return_target"],
        evaluated="online",
    )
    line, after = falls.run_rows(tmp_path / "run", window=10_000)
    assert line["online"] == {"share": 2 / 3, "falls": 2, "evaluations": 3} and line["target"] is None
    assert line["online_only"] is None and [row["fell"] for row in after] == [True, False, True]
    text = falls.report([tmp_path / "run"], window=10_000)
    assert "| 66.7% (2/3) | not evaluated | - | - |" in text
    assert "| `actor/change` | 0.61 (n=2) | -1.22 (n=1) | - | - |" in text


def test_a_run_that_evaluated_the_target_actor_alone_is_refused(tmp_path):
    write_run(tmp_path / "run", [("eval/return", 10_000, 50.0)])
    with pytest.raises(ValueError, match="no eval/return_online: the run evaluated its target actor alone"):
        falls.run_rows(tmp_path / "run", window=10_000)


def test_the_averaged_actors_fall_share_beside_the_other_two(tmp_path):
    """A run that evaluated the averaged actor too: its fall share on its own curve from its own first
    pass, its falls that came with an online fall, and the pooled line; runs without it add nothing."""
    average = {10_000: 120, 20_000: 90, 30_000: 130, 40_000: 140, 50_000: 80}
    write_run(
        tmp_path / "run",
        [*rows("eval/return", "eval/return_target"), *(("eval/return_average", f, v) for f, v in average.items())],
        evaluated="online",
    )
    config = tmp_path / "run" / "config.yaml"
    config.write_text(config.read_text() + "  average_frames: 20000\n")
    line, _ = falls.run_rows(tmp_path / "run", window=10_000)
    # passed at 10k (120 > 100); after it 90 and 80 fell of (90, 130, 140, 80)
    assert line["average"] == {"share": 0.5, "falls": 2, "evaluations": 4} and line["average_frames"] == 20_000
    # 20k: the online actor had just passed (150), not a fall; 50k: the online actor fell (30)
    assert line["average_with_online"] == 1
    text = falls.report([tmp_path / "run"], window=10_000)
    assert "| `" + str(tmp_path / "run") + "` | 20000 | 50.0% (2/4) | 66.7% (2/3) | 33.3% (1/3) | 1 of 2 |" in text
    assert "Pooled over these runs: the averaged actor 50.0% (2/4), the online actor 66.7% (2/3)" in text
    write_run(tmp_path / "plain", rows("eval/return", "eval/return_target"), evaluated="online")
    assert "averaged actor" not in falls.report([tmp_path / "plain"], window=10_000)
    write_run(tmp_path / "alone", [("eval/return", 10_000, 50.0)], evaluated="average")
    with pytest.raises(ValueError, match="the run evaluated its average actor alone"):
        falls.run_rows(tmp_path / "alone", window=10_000)


def test_an_unfinished_run_needs_its_teachers_return(tmp_path):
    write_run(tmp_path / "run", rows(), summary=False)
    with pytest.raises(ValueError, match="no summary.json .* --teacher-return"):
        falls.run_rows(tmp_path / "run", window=10_000)
    line, _ = falls.run_rows(tmp_path / "run", window=10_000, given_teacher=100.0)
    assert line["online"]["falls"] == 2


def curves_run(folder, online, target):
    write_run(
        folder,
        [
            *(("eval/return_online", f, v) for f, v in online.items()),
            *(("eval/return", f, v) for f, v in target.items()),
        ],
    )
    return falls.run_rows(folder, window=10_000)


def test_a_target_fall_before_the_online_actors_first_pass_counts_everywhere(tmp_path):
    """The target passes at 10k and dips at 20k, where the online actor passes: the target's fall is
    in its fall share, its falls, its dips, and fell alone (the online actor at 150 held)."""
    line, after = curves_run(
        tmp_path / "run", {10_000: 50, 20_000: 150, 30_000: 150}, {10_000: 150, 20_000: 40, 30_000: 150}
    )
    assert (line["passed_at"], line["target_passed_at"]) == (20_000, 10_000)
    assert line["target"] == {"share": 0.5, "falls": 1, "evaluations": 2} and line["online"]["falls"] == 0
    assert [(row["fell"], row["target_fell"]) for row in after] == [(None, True), (False, False)]
    assert (line["online_only"], line["target_only"]) == (0, 1)
    text = falls.report([tmp_path / "run"], window=10_000)
    assert "1 of the target actor's 1 (a run's last" in text
    assert "same evaluation: 0 of the target actor's 1 falls" in text  # the online actor held (150) at 20k


def test_a_target_fall_beside_an_online_actor_below_the_teacher_before_its_pass_is_not_a_shared_fall(tmp_path):
    """At 20k the target falls (after its pass at 10k) while the online actor is at 60, below the teacher
    but before its own first pass (30k): not a fall of the online actor, so the target's fall is not shared."""
    curves_run(tmp_path / "run", {10_000: 50, 20_000: 60, 30_000: 150}, {10_000: 150, 20_000: 40, 30_000: 150})
    text = falls.report([tmp_path / "run"], window=10_000)
    assert "Both actors fell at the same evaluation: 0 of the target actor's 1 falls" in text


def test_fell_alone_needs_the_other_actor_at_or_above_the_teacher(tmp_path):
    """At 20k the online actor falls (after its pass at 10k) while the target, at its own first pass
    (120), holds: the online actor fell alone. A next evaluation exactly at the teacher is not back above."""
    line, after = curves_run(
        tmp_path / "a", {10_000: 150, 20_000: 40, 30_000: 100}, {10_000: 50, 20_000: 120, 30_000: 150}
    )
    assert (line["online_only"], line["target_only"]) == (1, 0)
    assert [row["back"] for row in after] == [False, False]  # 30k's 100 is not above 100
    # a target evaluated at every frame but never above the teacher: "never passed", and nothing alone
    line, _ = curves_run(tmp_path / "b", {10_000: 150, 20_000: 40, 30_000: 150}, {10_000: 50, 20_000: 50, 30_000: 50})
    assert line["target"] is None and (line["online_only"], line["target_only"]) == (0, 0)
    assert "| 50.0% (1/2) | never passed | 0 | 0 |" in falls.report([tmp_path / "b"], window=10_000)


def test_each_actors_fall_share_reads_its_own_curve(tmp_path):
    """The target has no 30k evaluation: the online actor's 30k fall still counts (1 of 2)."""
    line, _ = curves_run(tmp_path / "run", {10_000: 150, 20_000: 150, 30_000: 40}, {10_000: 150, 20_000: 150})
    assert line["online"] == {"share": 0.5, "falls": 1, "evaluations": 2}
    assert line["target"] == {"share": 0.0, "falls": 0, "evaluations": 1}
