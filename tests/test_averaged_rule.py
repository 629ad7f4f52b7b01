"""``benchmarks/averaged_rule.py``: whether the averaged actor becomes the default, on hand-made result
folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark, nest

rule = load_benchmark("averaged_rule")

TEACHER = 100.0
# evaluations every 10k frames: a pass at the second, then four counted evaluations
HOLDS = [50, 200, 200, 200, 200, 200]  # no fall, last-5 200
FALLS_ONCE = [50, 200, 90, 200, 200, 200]  # one fall in 4, last-5 178
LOW = [50, 110, 110, 110, 110, 110]  # 1.10 x the teacher: below HalfCheetah's 1.2 x
DAC = [50, 150, 150, 150, 150, 150]


def write_run(root, stage, label, env, method, seed, returns, target=None, config=None):
    """A collected run: ``returns`` as its evaluated actor's evaluations, ``target`` (if given) as its
    target actor's beside them; a ``*-averaged`` run has the confirmation's config, but for ``config``'s
    dotted keys (a None value: a key its config lacks)."""
    folder = root / stage / label / env / method / f"seed{seed}"
    folder.mkdir(parents=True)
    (root / stage / "matrix.json").write_text("{}")  # a campaign stage: labels are its teacher folders
    nested = {"env": {"name": env}, "algo": {"name": method}, "seed": seed, "collector": {"total_frames": 300_000}}
    nested["eval"] = {"episodes": 10, "every_frames": 10_000}
    if label.endswith("-averaged"):
        nest({**rule.SETTINGS, **(config or {})}, nested)
    (folder / "config.yaml").write_text(yaml.safe_dump(nested))
    summary = {"env": env, "frames": 300_000, "total_frames": 300_000, "teacher_return": TEACHER}
    (folder / "summary.json").write_text(json.dumps(summary))
    rows = ["tag,frames,value", *(f"eval/return,{10_000 * (i + 1)},{v}" for i, v in enumerate(returns))]
    rows += [f"eval/return_target,{10_000 * (i + 1)},{v}" for i, v in enumerate(target or [])]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")
    return folder


def full_set(root, averaged=None, target=None, skip=(), dac_seeds=rule.SEEDS):
    """Every confirmation run (the averaged actor holds, the target actor falls once in 4, unless
    ``averaged`` or ``target`` map (env, teacher, seed) to other returns) and DAC's runs of ``dac_seeds``."""
    averaged, target = averaged or {}, target or {}
    for key in rule.needed("averaged"):
        if key not in skip:
            env, teacher, seed = key
            returns, beside = averaged.get(key, HOLDS), target.get(key, FALLS_ONCE)
            write_run(root, "averaged", f"{teacher}-averaged", env, "sail", seed, returns, beside)
    for env in rule.ENVS:
        for seed in dac_seeds:
            write_run(root, "trusted", "paper", env, "dac", seed, DAC)


def cheetah(returns):
    """``returns`` on every HalfCheetah cell with the paper's teacher."""
    return {("HalfCheetah-v4", "paper", seed): returns for seed in rule.SEEDS}


def test_first_set_met(tmp_path):
    full_set(tmp_path)
    text = rule.report([tmp_path])
    assert "runs found: averaged 40, target 40, dac 20" in text
    # 20 Hopper and Walker2d runs, 4 counted evaluations each; the target actor falls in one of each's 4
    assert "- met: fall share on Hopper and Walker2d 0.0% (0/80), at most 5%" in text
    assert "- met: HalfCheetah-v4: last-5 200.0 above DAC's 150.0" in text
    half = "at most 0.5 of the target actor's 25.0% (20/80), 12.5%"
    assert f"- met: fall share on Hopper and Walker2d 0.0% (0/80), {half}" in text
    assert text.endswith("**Decision: the averaged actor becomes the default** (it meets the first set).")


def test_second_set_met_when_halfcheetah_misses_its_bound(tmp_path):
    # HalfCheetah's last-5 1.10 x the teacher for both actors: the first set is missed whatever DAC's
    # runs do, so its seeds 3-4 are not awaited; the target actor's own mean is the floor (std 0)
    full_set(tmp_path, averaged=cheetah(LOW), target=cheetah(LOW), dac_seeds=(0, 1, 2))
    text = rule.report([tmp_path])
    assert "- dac: 8 runs missing" in text and "(not needed for the decision: it is decided without them)" in text
    assert "- MISSED: HalfCheetah-v4: last-5 110.0 = 1.10 x the teacher (100.0), at least 1.2" in text
    assert "- met: HalfCheetah-v4: last-5 110.0, not below the target actor's 110.0 - 0.0 = 110.0" in text
    assert text.endswith("**Decision: the averaged actor becomes the default** (it meets the second set of criteria).")


def test_default_stays_when_the_averaged_actor_falls_more_than_half_as_often(tmp_path):
    # the averaged actor falls like the target actor on 11 of the 20 fall-env runs: 11/80 = 13.75% > 12.5%
    falls = {key: FALLS_ONCE for key in rule.needed("averaged") if key[0] in ("Hopper-v4", "Walker2d-v4")}
    falls = dict(list(falls.items())[:11])
    full_set(tmp_path, averaged={**falls, **cheetah(LOW)}, target=cheetah(LOW))
    text = rule.report([tmp_path])
    assert "- MISSED: fall share on Hopper and Walker2d 13.8% (11/80), at most 0.5 of the target" in text
    stays = "**Decision: the default stays**; `eval.actor=average` remains an option (it misses a criterion)."
    assert text.endswith(stays)


def test_default_stays_when_a_paper_teacher_mean_drops_more_than_a_std(tmp_path):
    # Swimmer, the paper's teacher: target last-5 200 on every seed (std 0), averaged 178 on every seed
    swimmer = {("Swimmer-v4", "paper", seed): FALLS_ONCE for seed in rule.SEEDS}
    full_set(tmp_path, averaged={**swimmer, **cheetah(LOW)}, target={**cheetah(LOW), **{k: HOLDS for k in swimmer}})
    text = rule.report([tmp_path])
    assert "- MISSED: Swimmer-v4: last-5 178.0, not below the target actor's 200.0 - 0.0 = 200.0" in text
    assert "(it misses a criterion)" in text


def test_half_the_target_actors_fall_share_is_met_and_the_floor_uses_its_sample_std(tmp_path):
    # falls: like the target actor on 10 of the 20 fall-env runs, 10/80 = 12.5%, exactly half of 25%.
    # Swimmer with the paper's teacher: the target actor's last-5 200, 178, 200, 178, 200 over the seeds
    # (mean 191.2, sample std 12.05: floor 179.15, shown 179.2); the averaged actor's 178 on every seed is below it,
    # where a population std (10.78: floor 180.42) or the averaged actor's own std (0) would differ too
    falls = {key: FALLS_ONCE for key in rule.needed("averaged") if key[0] in ("Hopper-v4", "Walker2d-v4")}
    falls = dict(list(falls.items())[:10])
    swimmer = {("Swimmer-v4", "paper", seed): FALLS_ONCE for seed in rule.SEEDS}
    target = {("Swimmer-v4", "paper", seed): HOLDS if seed % 2 == 0 else FALLS_ONCE for seed in rule.SEEDS}
    full_set(tmp_path, averaged={**falls, **swimmer, **cheetah(LOW)}, target={**target, **cheetah(LOW)})
    text = rule.report([tmp_path])
    assert "- met: fall share on Hopper and Walker2d 12.5% (10/80), at most 0.5 of the target actor's 25.0%" in text
    assert "- MISSED: Swimmer-v4: last-5 178.0, not below the target actor's 191.2 - 12.0 = 179.2" in text


def test_a_run_that_never_passed_decides_at_once(tmp_path):
    never = [50, 60, 70, 80, 90, 95]
    full_set(tmp_path, averaged={("Swimmer-v4", "shipped", 0): never}, skip=[("Hopper-v4", "paper", 4)])
    text = rule.report([tmp_path])
    assert "- averaged: 1 runs missing (Hopper-v4 paper seed 4)" in text
    assert text.endswith(
        "**Decision: the default stays**; `eval.actor=average` remains an option (a run never passed its "
        "teacher: Swimmer-v4 shipped seed 0)."
    )


def test_waits_for_dac_where_only_the_first_set_can_decide(tmp_path):
    # every averaged run in and the first set within reach, but the second set missed (Swimmer's mean
    # below the target actor's floor): DAC's seeds 3-4 decide whether the first set is met
    swimmer = {("Swimmer-v4", "paper", seed): FALLS_ONCE for seed in rule.SEEDS}
    full_set(tmp_path, averaged=swimmer, target={k: HOLDS for k in swimmer}, dac_seeds=(0, 1, 2))
    text = rule.report([tmp_path])
    assert "- dac: 8 runs missing" in text and "not needed" not in text
    assert text.endswith("**Decision: pending** (it waits for every run it needs).")


def test_pending_until_every_run_is_in(tmp_path):
    full_set(tmp_path, skip=[("Hopper-v4", "shipped", 4)])
    text = rule.report([tmp_path])
    assert "- averaged: 1 runs missing (Hopper-v4 shipped seed 4)" in text
    # the interim compares the 39 cells in: the target actor's falls on 19 fall-env runs
    assert "- fall share on Hopper and Walker2d: 0.0% (0/76) against the target actor's 25.0% (19/76);" in text
    assert text.endswith("**Decision: pending** (it waits for every run it needs).")


def test_refuses_a_run_at_another_memory(tmp_path):
    full_set(tmp_path)
    folder = write_run(
        tmp_path / "more",
        "averaged",
        "paper-averaged",
        "Hopper-v4",
        "sail",
        0,
        HOLDS,
        FALLS_ONCE,
        config={"eval.average_frames": 30_000},
    )
    with pytest.raises(ValueError, match=rf"{folder}: .*eval.average_frames=30000 where the confirmation has 10000"):
        rule.report([tmp_path / "more"])


def test_refuses_a_run_without_the_target_actor_beside(tmp_path):
    folder = write_run(tmp_path, "averaged", "paper-averaged", "Hopper-v4", "sail", 0, HOLDS)
    with pytest.raises(ValueError, match=rf"{folder}: 0 eval/return_target evaluations, fewer than the 5"):
        rule.report([tmp_path])


def test_refuses_two_teacher_returns_of_one_env_and_teacher(tmp_path):
    write_run(tmp_path, "averaged", "paper-averaged", "Hopper-v4", "sail", 0, HOLDS, FALLS_ONCE)
    folder = write_run(tmp_path, "averaged", "paper-averaged", "Hopper-v4", "sail", 1, HOLDS, FALLS_ONCE)
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, "teacher_return": 120.0}))
    with pytest.raises(ValueError, match=r"teacher return 100.0 in .*seed0 but 120.0 in .*seed1: the paper teacher"):
        rule.report([tmp_path])


def test_refuses_two_runs_of_one_cell(tmp_path):
    write_run(tmp_path / "a", "averaged", "paper-averaged", "Hopper-v4", "sail", 0, HOLDS, FALLS_ONCE)
    write_run(tmp_path / "b", "averaged", "paper-averaged", "Hopper-v4", "sail", 0, HOLDS, FALLS_ONCE)
    with pytest.raises(ValueError, match=r"two averaged runs of \('Hopper-v4', 'paper', 0\)"):
        rule.report([tmp_path / "a", tmp_path / "b"])
