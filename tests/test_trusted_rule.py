"""``benchmarks/trusted_rule.py``: the trusted-default decision rule on hand-made result folders."""

from __future__ import annotations

import json

import yaml
from benchmark_scripts import load_benchmark

rule = load_benchmark("trusted_rule")

TEACHER = 100.0


def write_run(root, label, env, method, seed, returns, online=None, frames=300_000, stage="trusted"):
    """A collected run folder under ``root/<stage>`` (a campaign stage): evaluations every 10k frames."""
    folder = root / stage / label / env / method / f"seed{seed}"
    folder.mkdir(parents=True)
    config = {"env": {"name": env}, "algo": {"name": method}, "seed": seed, "collector": {"total_frames": frames}}
    (folder / "config.yaml").write_text(yaml.safe_dump(config))
    summary = {"env": env, "frames": frames, "total_frames": frames, "teacher_return": TEACHER}
    (folder / "summary.json").write_text(json.dumps(summary))
    rows = ["tag,frames,value"]
    rows += [f"eval/return,{10_000 * (i + 1)},{value}" for i, value in enumerate(returns)]
    rows += [f"eval/return_online,{10_000 * (i + 1)},{value}" for i, value in enumerate(online or [])]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")


def full_set(root, skip=()):
    (root / "trusted").mkdir(parents=True)
    (root / "trusted" / "matrix.json").write_text("{}")
    for env in rule.ENVS:
        for seed in rule.SEEDS:
            for teacher in rule.TEACHERS:
                if (env, teacher, seed) not in skip:
                    # the target actor never falls after passing; the online one falls once in 4
                    write_run(
                        root,
                        f"{teacher}-trusted",
                        env,
                        "sail",
                        seed,
                        [50, 200, 200, 200, 200, 200],
                        online=[50, 200, 50, 200, 200, 200],
                    )
                # the defaults: last-5 (200 + 90 + 200 + 200 + 200) / 5 = 178, one fall in 4
                write_run(root, teacher, env, "sail", seed, [50, 200, 90, 200, 200, 200])
            write_run(root, "paper", env, "dac", seed, [50, 150, 150, 150, 150, 150])
    (root / "scale").mkdir()
    (root / "scale" / "matrix.json").write_text("{}")
    write_run(root, "paper", "Hopper-v4", "sail", 0, [1] * 10, frames=1_000_000, stage="scale")  # not read


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


def test_rule_is_pending_until_every_run_is_there(tmp_path):
    full_set(tmp_path, skip={("Walker2d-v4", "shipped", 3)})
    text = rule.report([tmp_path])
    assert "- candidate: 1 runs missing (Walker2d-v4 shipped seed 3)" in text
    assert text.count("**Verdict: pending.**") == 2 and "MISSED" not in text
    candidate, penalty = text.split("### penalty")
    # the 39 cells both have; on Hopper and Walker2d 19 of them, 4 evaluations after the pass each
    assert "on the 39 (env, teacher, seed) cells both the candidate and the defaults" in candidate
    assert "- runs passing their teacher: 39 against the defaults' 39;" in candidate
    assert "- fall share on Hopper and Walker2d: 0.0% (0/76) against the defaults' 25.0% (19/76);" in candidate
    assert "- last-5 above the defaults' on 39 of 39 cells." in candidate  # 200 against 178
    assert "- last-5 above the defaults' on 0 of 39 cells." in penalty  # 170 against 178


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
