"""``benchmarks/trusted_rule.py``: the trusted-default decision rule on hand-made result folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark

rule = load_benchmark("trusted_rule")

TEACHER = 100.0


CANDIDATE = {"optim": {"actor_preactivation_coef": 0.001}, "eval": {"actor": "target", "other_actor": True}}


def write_run(
    root,
    label,
    env,
    method,
    seed,
    returns,
    online=None,
    frames=300_000,
    stage="trusted",
    teacher=TEACHER,
    best_policy=None,
    kept_at=None,
    config=None,
    resumes=(),
):
    """A collected run folder under ``root/<stage>`` (a campaign stage): evaluations every 10k frames,
    10 episodes each; a ``*-trusted`` label is run with the candidate's settings, any other with a
    config that predates them (as the campaign's earlier runs), unless ``config`` says otherwise."""
    folder = root / stage / label / env / method / f"seed{seed}"
    folder.mkdir(parents=True)
    if config is None:
        config = CANDIDATE if label.endswith("-trusted") else {}
    config = {
        "env": {"name": env},
        "algo": {"name": method},
        "seed": seed,
        "collector": {"total_frames": frames},
        **config,
        "eval": {"episodes": 10, "every_frames": 10_000, **config.get("eval", {})},
    }
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    summary = {"env": env, "frames": frames, "total_frames": frames, "teacher_return": teacher}
    summary["resumes"] = list(resumes)
    if best_policy is not None:
        summary["best_policy"] = {"eval_return": best_policy}
        if kept_at is not None:
            summary["best_policy"]["frames"] = kept_at
    (folder / "summary.json").write_text(json.dumps(summary))
    rows = ["tag,frames,value"]
    rows += [f"eval/return,{10_000 * (i + 1)},{value}" for i, value in enumerate(returns)]
    rows += [f"eval/return_online,{10_000 * (i + 1)},{value}" for i, value in enumerate(online or [])]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")


# the target actor never falls after passing; the online one falls once in 4; the defaults: last-5
# (200 + 90 + 200 + 200 + 200) / 5 = 178, one fall in 4; DAC: 150
CANDIDATE_RETURNS = [50, 200, 200, 200, 200, 200]
ONLINE_RETURNS = [50, 200, 50, 200, 200, 200]
DEFAULT_RETURNS = [50, 200, 90, 200, 200, 200]
DAC_RETURNS = [50, 150, 150, 150, 150, 150]


def full_set(root, skip=(), candidate=None, online=None, defaults=None):
    """Every run the rule needs; ``candidate``, ``online`` and ``defaults`` map (env, teacher, seed) to
    the returns of the cells they change."""
    (root / "trusted").mkdir(parents=True)
    (root / "trusted" / "matrix.json").write_text("{}")
    for env in rule.ENVS:
        for seed in rule.SEEDS:
            for teacher in rule.TEACHERS:
                key = (env, teacher, seed)
                if key not in skip:
                    write_run(
                        root,
                        f"{teacher}-trusted",
                        env,
                        "sail",
                        seed,
                        (candidate or {}).get(key, CANDIDATE_RETURNS),
                        online=(online or {}).get(key, ONLINE_RETURNS),
                    )
                write_run(root, teacher, env, "sail", seed, (defaults or {}).get(key, DEFAULT_RETURNS))
            write_run(root, "paper", env, "dac", seed, DAC_RETURNS)
    (root / "scale").mkdir()
    (root / "scale" / "matrix.json").write_text("{}")
    write_run(root, "paper", "Hopper-v4", "sail", 0, [1] * 10, frames=1_000_000, stage="scale")  # not read


def every(env=None, teacher=None, seeds=rule.SEEDS):
    """The (env, teacher, seed) cells of ``env`` and ``teacher`` (each None for all)."""
    return [
        (e, t, seed)
        for e in rule.ENVS
        for t in rule.TEACHERS
        for seed in seeds
        if env in (None, e) and teacher in (None, t)
    ]


def test_rule_on_hand_counted_runs(tmp_path):
    full_set(tmp_path)
    text = rule.report([tmp_path])
    assert "candidate 40, penalty 40, defaults 40, dac 20" in text
    candidate, penalty = text.split("### penalty")
    assert "MISSED" not in candidate.split("Second set")[0]  # every criterion of the first set met
    assert "met: every run passes its teacher: 40 of 40" in candidate
    assert "met: HalfCheetah-v4: last-5 200.0 = 2.00 x the teacher (100.0), at least 1.2" in candidate
    assert "met: Swimmer-v4: last-5 200.0 above DAC's 150.0" in candidate
    assert "met: fall share on Hopper and Walker2d 0.0% (0/80), at most 5%" in candidate
    assert "**Verdict: candidate meets the first set.**" in candidate
    # the penalty alone (online evaluations): last-5 (50 + 200 * 4) / 5 = 170; 20 falls in 80
    assert "MISSED: fall share on Hopper and Walker2d 25.0% (20/80), at most 5%" in penalty
    assert "MISSED: runs passing: 40 against the defaults' 40" in penalty
    assert "met: Hopper-v4: last-5 170.0, not below the defaults' 178.0 - 0.0 = 178.0" not in penalty
    assert "MISSED: Hopper-v4: last-5 170.0, not below the defaults' 178.0 - 0.0 = 178.0" in penalty
    assert "met: fall share 25.0% (20/80), not above the defaults' 25.0% (20/80)" in penalty
    assert "**Verdict: penalty meets neither set.**" in penalty
    assert text.endswith("**Decision: the candidate becomes the default** (it meets the first set).")
    # the table: every cell's five seeds alike (std 0); no run kept a best policy; falls per cell:
    # the online actor and the defaults 1 in each run's 4 evaluations after its pass, DAC none
    assert "| Hopper-v4 | paper (100.0) | candidate | 5 | 5 | 200.0 ± 0.0 | - | 0.0% (0/20) |" in text
    assert "| Hopper-v4 | paper (100.0) | penalty | 5 | 5 | 170.0 ± 0.0 | - | 25.0% (5/20) |" in text
    assert "| Hopper-v4 | paper (100.0) | defaults | 5 | 5 | 178.0 ± 0.0 | - | 25.0% (5/20) |" in text
    assert "| Hopper-v4 | paper (100.0) | dac | 5 | 5 | 150.0 ± 0.0 | - | 0.0% (0/20) |" in text
    assert "| Hopper-v4 | shipped (100.0) | defaults | 5 | 5 | 178.0 ± 0.0 | - | 25.0% (5/20) |" in text
    assert "| Hopper-v4 | shipped (100.0) | dac |" not in text  # DAC runs with the paper's teachers only


def test_rule_is_pending_until_every_run_is_there(tmp_path):
    full_set(tmp_path, skip={("Walker2d-v4", "shipped", 3)})
    text = rule.report([tmp_path])
    assert "- candidate: 1 runs missing (Walker2d-v4 shipped seed 3)" in text
    assert text.count("**Verdict: pending.**") == 2 and "MISSED" not in text
    assert text.endswith("**Decision: pending** (the verdicts wait for every run they need).")
    candidate, penalty = text.split("### penalty")
    # the 39 cells both have; on Hopper and Walker2d 19 of them, 4 evaluations after the pass each
    assert "on the 39 (env, teacher, seed) cells both the candidate and the defaults" in candidate
    assert "- runs passing their teacher: 39 against the defaults' 39;" in candidate
    assert "- fall share on Hopper and Walker2d: 0.0% (0/76) against the defaults' 25.0% (19/76);" in candidate
    assert "- last-5 above the defaults' on 39 of 39 cells." in candidate  # 200 against 178
    assert "- last-5 above the defaults' on 0 of 39 cells." in penalty  # 170 against 178
    # the candidate has fallen nowhere; the penalty alone: 19 falls in 76, and the one run to come counts at
    # most 300k / 10k - 1 = 29 evaluations: 19 / (76 + 29) = 18.1% at best, above 5%
    assert "out of reach" not in candidate
    assert (
        "- fall share on Hopper and Walker2d at most 5%: missed, as it is at least 18.1% (19/105): 19 falls in 76 "
        "evaluations so far, and 1 run to come that counts at most 29, all without a fall." in penalty
    )


def test_the_first_set_out_of_reach_before_every_run_is_in(tmp_path):
    """One Hopper candidate run that passed and fell 2 of 27 times (7.4%), a Swimmer one that never passed;
    the 19 Hopper and Walker2d runs to come could bring the share down to 2 / (27 + 19 * 29) = 0.3%: in reach."""
    (tmp_path / "trusted").mkdir(parents=True)
    (tmp_path / "trusted" / "matrix.json").write_text("{}")
    returns = [50] + [200] * 26 + [90, 90]  # passes at 20k, then 27 counted, 2 falls
    write_run(tmp_path, "paper-trusted", "Hopper-v4", "sail", 0, returns)
    write_run(tmp_path, "paper-trusted", "Swimmer-v4", "sail", 0, [50] * 6)
    text = rule.report([tmp_path]).split("### penalty")[0]
    assert "Already out of reach for the candidate, whatever its runs to come (the first set):" in text
    assert "- every run passes its teacher: missed, as Swimmer-v4 paper seed 0 never passed." in text
    assert "fall share on Hopper and Walker2d at most 5%: missed" not in text


def test_a_paper_mean_below_its_bound_is_out_of_reach_once_its_five_runs_are_in(tmp_path):
    """Five Swimmer paper-teacher runs at last-5 140 against a teacher of 100 (1.4x, the bound 1.5x), the
    other envs' runs still to come; four Hopper ones at 200 (2x): not judged until the fifth is in."""
    (tmp_path / "trusted").mkdir(parents=True)
    (tmp_path / "trusted" / "matrix.json").write_text("{}")
    for seed in rule.SEEDS:
        write_run(tmp_path, "paper-trusted", "Swimmer-v4", "sail", seed, [50] + [140] * 5)
    for seed in rule.SEEDS[:4]:
        write_run(tmp_path, "paper-trusted", "Hopper-v4", "sail", seed, [50] + [90] * 5)  # 0.9x, one run to come
    text = rule.report([tmp_path]).split("### penalty")[0]
    assert (
        "- Swimmer-v4: last-5 at least 1.5 x the teacher: missed, as it is 1.40 x (140.0 against 100.0), its "
        "five runs in." in text
    )
    assert "- Hopper-v4: last-5 at least" not in text


def candidate_and_default(root, env, default_seed) -> str:
    """The rule's report on one candidate run (seed 0, falls once after passing) and one default run."""
    (root / "trusted").mkdir(parents=True)
    (root / "trusted" / "matrix.json").write_text("{}")
    write_run(root, "paper-trusted", env, "sail", 0, [50, 200, 90, 200, 200, 200], online=[50] * 6)
    write_run(root, "paper", env, "sail", default_seed, [50, 200, 200, 200, 200, 200])
    return rule.report([root])


def test_no_interim_line_without_a_cell_both_have(tmp_path):
    text = candidate_and_default(tmp_path, "Hopper-v4", default_seed=1)
    assert "Interim" not in text and text.count("**Verdict: pending.**") == 2


def test_interim_without_a_hopper_or_walker_cell_counts_no_falls(tmp_path):
    text = candidate_and_default(tmp_path, "Swimmer-v4", default_seed=0)
    assert "- fall share on Hopper and Walker2d: n/a (0 counted) against the defaults' n/a (0 counted);" in text
    assert "- last-5 above the defaults' on 0 of 1 cells." in text  # 178 against 200


def test_decision_by_the_second_set(tmp_path):
    """The candidate falls as the defaults do (25%: first set missed), but every run passes where the
    defaults never take off with the shipped Swimmer teacher (40 against 35)."""
    full_set(
        tmp_path,
        candidate={key: DEFAULT_RETURNS for key in every()},
        defaults={key: [50] * 6 for key in every("Swimmer-v4", "shipped")},
    )
    text = rule.report([tmp_path])
    candidate = text.split("### penalty")[0]
    assert "MISSED: fall share on Hopper and Walker2d 25.0% (20/80), at most 5%" in candidate
    assert "met: runs passing: 40 against the defaults' 35" in candidate
    assert "met: Swimmer-v4: last-5 178.0, not below the defaults' 178.0 - 0.0 = 178.0" in candidate
    assert "met: fall share 25.0% (20/80), not above the defaults' 25.0% (20/80)" in candidate
    assert "**Verdict: candidate meets the second set.**" in candidate
    assert text.endswith("**Decision: the candidate becomes the default** (it meets the second set).")


def test_dacs_runs_are_awaited_only_while_the_first_set_can_be_met(tmp_path):
    """DAC's seeds 3-4 missing: the candidate that can still meet the first set (no fall) waits for them;
    one whose falls put the first set out of reach is judged by the second set without them."""
    import shutil

    def without_dac_seeds_3_4(root):
        for env in rule.ENVS:
            for seed in (3, 4):
                shutil.rmtree(root / "trusted" / "paper" / env / "dac" / f"seed{seed}")

    full_set(tmp_path / "a")
    without_dac_seeds_3_4(tmp_path / "a")
    candidate, penalty = rule.report([tmp_path / "a"]).split("### penalty")
    assert "- dac: 8 runs missing (Hopper-v4 paper seed 3, Hopper-v4 paper seed 4," in candidate
    assert "not needed for the verdict" not in candidate and "**Verdict: pending.**" in candidate
    # the penalty alone falls 20 times in 80 evaluations: its first set is missed, and DAC's runs are not needed
    assert "and 2 more) (not needed for the verdict: the first set is missed)" in penalty
    assert "**Verdict: penalty meets neither set.**" in penalty  # 40 passes against the defaults' 40

    # the candidate falls as the defaults do (25%); the defaults never pass the shipped Swimmer teacher
    full_set(
        tmp_path / "b",
        candidate={key: DEFAULT_RETURNS for key in every()},
        defaults={key: [50] * 6 for key in every("Swimmer-v4", "shipped")},
    )
    without_dac_seeds_3_4(tmp_path / "b")
    text = rule.report([tmp_path / "b"])
    candidate = text.split("### penalty")[0]
    assert (
        "- fall share on Hopper and Walker2d at most 5%: missed, as it is 25.0% (20/80) over its finished runs, "
        "all of them in.\n\nFirst set:" in candidate  # a blank line ends the list before the criteria
    )
    assert "- not judged: Hopper-v4: last-5 above DAC's (DAC's runs are not all in)" in candidate
    assert "MISSED: fall share on Hopper and Walker2d 25.0% (20/80), at most 5%" in candidate
    assert "**Verdict: candidate meets the second set.**" in candidate
    assert text.endswith("**Decision: the candidate becomes the default** (it meets the second set).")


def test_the_defaults_runs_that_only_count_passes_are_awaited_only_while_the_count_is_open(tmp_path):
    """The defaults' shipped Swimmer and HalfCheetah seeds 3-4 count in the second set's first criterion
    alone. The defaults' other 36 runs pass 33 times (the shipped Swimmer seeds 0-2 never do), so with the
    4 they pass at most 37 times: 40 candidate passes decide the count without them; 36 (the candidate's
    shipped Swimmer seeds 0-3 never passing) do not."""
    import shutil

    late = [(env, "shipped", seed) for env in ("Swimmer-v4", "HalfCheetah-v4") for seed in (3, 4)]

    def report(root, candidate):
        full_set(root, candidate=candidate, defaults={key: [50] * 6 for key in every("Swimmer-v4", "shipped")})
        for env, teacher, seed in late:
            shutil.rmtree(root / "trusted" / teacher / env / "sail" / f"seed{seed}")
        return rule.report([root]).split("### penalty")[0]

    falling = {key: DEFAULT_RETURNS for key in every()}  # the first set missed: DAC's runs not awaited
    text = report(tmp_path / "a", falling)
    assert (
        "- defaults: 4 runs missing (Swimmer-v4 shipped seed 3, Swimmer-v4 shipped seed 4, HalfCheetah-v4 shipped "
        "seed 3, HalfCheetah-v4 shipped seed 4) (not needed for the verdict: the count of runs passing is decided)"
    ) in text
    assert "met: runs passing: 40 against the defaults' 33, at most 37 with their 4 runs not in" in text
    assert "**Verdict: candidate meets the second set.**" in text

    stalled = {**falling, **{key: [50] * 6 for key in every("Swimmer-v4", "shipped", seeds=(0, 1, 2, 3))}}
    text = report(tmp_path / "b", stalled)
    assert "- defaults: 4 runs missing (Swimmer-v4 shipped seed 3," in text and "count of runs passing" not in text
    assert "**Verdict: pending.**" in text


def test_decision_falls_back_to_the_penalty_then_to_the_defaults(tmp_path):
    """The target actor falls after passing and ends at (200 + 4 x 50) / 5 = 80: neither set. Its
    online actor never falls and ends at 200: the penalty alone meets the first set; where the online
    actor does as the target, the defaults stay."""
    falling = [50, 200, 50, 50, 50, 50]
    full_set(
        tmp_path / "a", candidate={key: falling for key in every()}, online={key: CANDIDATE_RETURNS for key in every()}
    )
    text = rule.report([tmp_path / "a"])
    assert "MISSED: Hopper-v4: last-5 80.0 = 0.80 x the teacher (100.0), at least 1.5" in text
    assert "MISSED: fall share on Hopper and Walker2d 100.0% (80/80), at most 5%" in text
    assert "**Verdict: candidate meets neither set.**" in text and "**Verdict: penalty meets the first set.**" in text
    assert text.endswith(
        "**Decision: the penalty alone becomes the default** (it meets the first set; the candidate neither)."
    )

    full_set(tmp_path / "b", candidate={key: falling for key in every()}, online={key: falling for key in every()})
    text = rule.report([tmp_path / "b"])
    assert "**Verdict: penalty meets neither set.**" in text
    assert text.endswith(
        "**Decision: the defaults stay**; the candidate and the penalty alone remain options (neither meets a set)."
    )


def test_criteria_at_their_boundaries(tmp_path):
    """An evaluation equal to the teacher's return does not pass it; last-5 exactly 1.5 x the teacher is
    enough, equal to DAC's is not; 4 falls in 80 evaluations is 5%, enough; and the defaults' spread
    is the sample standard deviation (160-200: 15.8, where the population one is 14.1)."""
    candidate = {("Swimmer-v4", "shipped", 0): [50, 100, 100, 100, 100, 100]}
    candidate |= {key: [50, 150, 150, 150, 150, 150] for key in every("Hopper-v4", "paper")}
    candidate |= {key: DEFAULT_RETURNS for key in every("Walker2d-v4", "paper", seeds=(0, 1, 2, 3))}
    candidate |= {key: [50] + [164.5] * 5 for key in every("Swimmer-v4", "paper")}
    defaults = {("Swimmer-v4", "paper", seed): [50] + [160 + 10 * seed] * 5 for seed in rule.SEEDS}
    full_set(tmp_path, candidate=candidate, defaults=defaults)
    text = rule.report([tmp_path])
    candidate_text = text.split("### penalty")[0]
    assert "MISSED: every run passes its teacher: 39 of 40" in candidate_text
    assert "met: Hopper-v4: last-5 150.0 = 1.50 x the teacher (100.0), at least 1.5" in candidate_text
    assert "MISSED: Hopper-v4: last-5 150.0 above DAC's 150.0" in candidate_text
    assert "met: fall share on Hopper and Walker2d 5.0% (4/80), at most 5%" in candidate_text
    assert "met: Swimmer-v4: last-5 164.5, not below the defaults' 180.0 - 15.8 = 164.2" in candidate_text
    # the table: Walker2d's paper seeds 0-3 at 178 (one fall each in 4), seed 4 at 200; Swimmer's
    # shipped seed 0 never passes (at, not above, its teacher): last-5 (100 + 4 * 200) / 5 = 180, sample
    # std sqrt((80^2 + 4 * 20^2) / 4) = 44.7, and none of its evaluations is counted for falls
    assert "| Walker2d-v4 | paper (100.0) | candidate | 5 | 5 | 182.4 ± 9.8 | - | 20.0% (4/20) |" in text
    assert "| Swimmer-v4 | paper (100.0) | candidate | 5 | 5 | 164.5 ± 0.0 | - | 0.0% (0/20) |" in text
    assert "| Swimmer-v4 | paper (100.0) | defaults | 5 | 5 | 180.0 ± 15.8 | - | 0.0% (0/20) |" in text
    assert "| Swimmer-v4 | shipped (100.0) | candidate | 5 | 4 | 180.0 ± 44.7 | - | 0.0% (0/16) |" in text


def test_a_fall_share_with_no_evaluation_after_a_pass_meets_no_criterion(tmp_path):
    """No candidate run on Hopper or Walker2d passes its teacher: its fall share counts nothing, and
    neither criterion on it is met (a share of 0 would meet both)."""
    full_set(tmp_path, candidate={key: [50] * 6 for env in rule.FALL_ENVS for key in every(env)})
    candidate = rule.report([tmp_path]).split("### penalty")[0]
    assert "MISSED: fall share on Hopper and Walker2d n/a (0 counted), at most 5%" in candidate
    assert "MISSED: fall share n/a (0 counted), not above the defaults' 25.0% (20/80)" in candidate


def test_best_policy_is_reported_beside_last5(tmp_path):
    (tmp_path / "trusted").mkdir(parents=True)
    (tmp_path / "trusted" / "matrix.json").write_text("{}")
    for seed, best in ((0, 210.0), (1, 230.0)):
        write_run(tmp_path, "paper-trusted", "Hopper-v4", "sail", seed, CANDIDATE_RETURNS, best_policy=best)
    # mean 220, sample std sqrt(2 * 10^2 / 1) = 14.1, two of five seeds, 4 evaluations each counted for
    # falls; a defaults seed from before the best policy was kept, beside one with it: over one of two
    write_run(tmp_path, "paper", "Hopper-v4", "sail", 0, DEFAULT_RETURNS)
    write_run(tmp_path, "paper", "Hopper-v4", "sail", 1, DEFAULT_RETURNS, best_policy=190.0)
    text = rule.report([tmp_path])
    assert "| Hopper-v4 | paper (100.0) | candidate | 2 | 2 | 200.0 ± 0.0 | 220.0 ± 14.1 | 0.0% (0/8) |" in text
    assert "| Hopper-v4 | paper (100.0) | defaults | 2 | 2 | 178.0 ± 0.0 | 190.0 (1 of 2) | 25.0% (2/8) |" in text
    assert "| Hopper-v4 | paper (100.0) | dac | 0 | 0 | - | - | - |" in text
    assert text.endswith("**Decision: pending** (the verdicts wait for every run they need).")
    assert "Where the best policy was kept" not in text  # no run says the frame it kept its policy at


def test_where_the_best_policy_was_kept(tmp_path):
    (tmp_path / "trusted").mkdir(parents=True)
    (tmp_path / "trusted" / "matrix.json").write_text("{}")
    # last-5 200, teacher 100: kept at the end above both; late and below last-5 (twice); early and below
    # both; at 290k exactly, not in the last 10k frames
    kept = ((0, 250.0, 300_000), (1, 150.0, 295_000), (2, 90.0, 280_000), (3, 210.0, 290_000), (4, 180.0, 299_000))
    for seed, best, frames in kept:
        write_run(
            tmp_path, "paper-trusted", "Hopper-v4", "sail", seed, CANDIDATE_RETURNS, best_policy=best, kept_at=frames
        )
    write_run(tmp_path, "paper", "Hopper-v4", "sail", 0, DEFAULT_RETURNS, best_policy=50.0)  # frame not recorded
    text = rule.report([tmp_path])
    assert (
        "- candidate: of its 5 runs with a best policy, 3 kept it in the last 10k frames; it is below the run's "
        "last-5 in 3 and below the teacher in 1." in text
    )
    assert "- defaults:" not in text.split("Where the best policy was kept")[1].split("###")[0]


def test_cells_whose_every_run_kept_its_best_policy_late(tmp_path):
    (tmp_path / "trusted").mkdir(parents=True)
    (tmp_path / "trusted" / "matrix.json").write_text("{}")
    # Hopper paper: both late (295k, 300k); Walker2d paper: one late, one at 290k (not in the last 10k)
    for env, frames in (("Hopper-v4", (295_000, 300_000)), ("Walker2d-v4", (300_000, 290_000))):
        for seed, kept_at in enumerate(frames):
            write_run(
                tmp_path, "paper-trusted", env, "sail", seed, CANDIDATE_RETURNS, best_policy=210.0, kept_at=kept_at
            )
    text = rule.report([tmp_path])
    assert (
        "- candidate: of its 4 runs with a best policy, 3 kept it in the last 10k frames; it is below the run's "
        "last-5 in 0 and below the teacher in 0. Every run with a best policy kept it there with the "
        "Hopper-v4 paper teacher." in text
    )


@pytest.mark.parametrize(
    "runs, message",
    [
        (  # a candidate run that evaluated its online actor
            [("paper-trusted", "sail", {"optim": {"actor_preactivation_coef": 0.001}})],
            r"paper-trusted/Hopper-v4/sail/seed0: counted as a candidate run, but its config has "
            r"eval.actor='online' where the candidate setting has 'target'",
        ),
        (  # a defaults run with the penalty
            [("paper", "sail", {"optim": {"actor_preactivation_coef": 0.001}})],
            r"counted as a defaults run, but its config has optim.actor_preactivation_coef=0.001 where the "
            r"defaults setting has 0.0",
        ),
        (  # fewer episodes per evaluation
            [("paper", "dac", {"eval": {"episodes": 5}})],
            r"counted as a dac run, but its config has eval.episodes=5 where the dac setting has 10",
        ),
        (  # a candidate run resumed with the online actor evaluated from 150k frames
            [
                (
                    "paper-trusted",
                    "sail",
                    CANDIDATE,
                    {"resumes": [{"frames": 150_000, "changes": {"eval.actor": ["target", "online"]}}]},
                )
            ],
            r"paper-trusted/Hopper-v4/sail/seed0: counted as a candidate run, but it was resumed at frame 150000 "
            r"with eval.actor changed from 'target' to 'online': it ran with two settings",
        ),
        (  # too few evaluations for a last-5
            [("paper", "sail", {}, {"returns": [50, 200, 200, 200]})],
            r"Hopper-v4/sail/seed0: 4 eval/return evaluations, fewer than the 5 of last-5",
        ),
        (
            [("paper", "sail", {}, {"returns": [50, 200, float("nan"), 200, 200, 200]})],
            r"Hopper-v4/sail/seed0: eval/return is nan at frame 30000",
        ),
        ([("paper", "sail", {}, {"teacher": None})], r"seed0/summary.json: teacher_return is None, not a number"),
        (  # one env, one teacher label, two teacher returns
            [("paper", "sail", {}), ("paper", "dac", {}, {"teacher": 120.0})],
            r"teacher return 120.0 in .*dac/seed0 but 100.0 in .*sail/seed0: the paper teacher of Hopper-v4 must "
            r"be one file",
        ),
        (  # the same cell in two stages
            [("paper", "sail", {}), ("paper", "sail", {}, {"stage": "main"})],
            r"two defaults runs of \('Hopper-v4', 'paper', 0\): .*main/paper.* and .*trusted/paper",
        ),
    ],
)
def test_rule_refuses_a_run_it_cannot_count(tmp_path, runs, message):
    for stage in ("main", "trusted"):
        (tmp_path / stage).mkdir()
        (tmp_path / stage / "matrix.json").write_text("{}")
    for label, method, config, *more in runs:
        options = {"returns": CANDIDATE_RETURNS, **(more[0] if more else {})}
        returns = options.pop("returns")
        write_run(tmp_path, label, "Hopper-v4", method, 0, returns, config=config, **options)
    with pytest.raises(ValueError, match=message):
        rule.report([tmp_path])


def test_a_fall_share_with_no_run_to_come_is_its_own(tmp_path):
    """Every Hopper and Walker2d candidate run is in, falling once in its 4 counted evaluations; a Swimmer
    run is missing, so the verdict waits, but the fall share is final: 20 / 80."""
    falling = {key: ONLINE_RETURNS for key in every("Hopper-v4") + every("Walker2d-v4")}
    full_set(tmp_path, skip={("Swimmer-v4", "paper", 0)}, candidate=falling)
    candidate = rule.report([tmp_path]).split("### penalty")[0]
    assert "**Verdict: pending.**" in candidate
    assert (
        "- fall share on Hopper and Walker2d at most 5%: missed, as it is 25.0% (20/80) over its finished runs, "
        "all of them in." in candidate
    )
