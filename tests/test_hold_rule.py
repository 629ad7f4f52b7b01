"""``benchmarks/hold_rule.py``: the runs that held the teacher buffer against their pairs, on
hand-made result folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark

rule = load_benchmark("hold_rule")

TEACHER = 100.0
# Evaluations every 10k frames from 10k. Promotions reach 10 at 80k (the hold); the other run has 13
# at 90k (the split): the window is 100k-200k, 11 evaluations.
BEFORE = [50, 60, 80, 150, 300, 300, 300, 300, 300]  # to 90k, a pass at 40k
# 5 drops (120 is below half of the best earlier, 300, not of the one before, 20), 4 falls in 11
DROPPING = BEFORE + [20, 120, 300, 20, 300, 300, 20, 300, 300, 20, 300]
STEADY = BEFORE + [300, 200, 300, 300, 120, 300, 300, 300, 300, 300, 300]  # 1 drop (120; not 200), no fall
FOUR = BEFORE + [20, 300, 300, 20, 300, 300, 20, 300, 300, 20, 300]  # 4 drops
THREE = BEFORE + [20, 300, 300, 20, 300, 300, 20, 300, 300, 300, 300]
TWO = BEFORE + [20, 300, 300, 20, 300, 300, 300, 300, 300, 300, 300]
FLAT = BEFORE + [300] * 11
PROMOTED = [0, 0, 0, 1, 4, 6, 8, 10]  # the tenth at 80k


def write_run(root, arm, seed, returns, *, online=None, config=None, promoted=PROMOTED, more=True):
    """A collected run: the average stage's (``baseline``, 300k frames, evaluations after 200k at 300)
    or the hold stage's (``hold``, 200k), with ``returns`` as its target actor's evaluations. After
    ``promoted``, a baseline run promotes 3 more every 10k (none if not ``more``), a held run none."""
    memory = 10 if seed in rule.AVERAGE_SEEDS[10_000] else 30
    label = f"paper-average{memory}k" + ("-hold" if arm == "hold" else "")
    stage = "hold" if arm == "hold" else "average"
    folder = root / stage / label / "Hopper-v4" / "sail" / f"seed{seed}"
    folder.mkdir(parents=True)
    (root / stage / "matrix.json").write_text("{}")
    total = 200_000 if arm == "hold" else 300_000
    settings = {
        "optim": {"actor_preactivation_coef": 0.001},
        "eval": {"actor": "target", "other_actor": True, "episodes": 10, "every_frames": 10_000},
        "algo": {"name": "sail", **({"max_promoted": 10} if arm == "hold" else {})},
    }
    for key, value in (config or {}).items():
        section, name = key.split(".")
        settings[section][name] = value
    nested = {"env": {"name": "Hopper-v4"}, "seed": seed, "collector": {"total_frames": total}, **settings}
    (folder / "config.yaml").write_text(yaml.safe_dump(nested))
    summary = {"env": "Hopper-v4", "frames": total, "total_frames": total, "teacher_return": TEACHER}
    (folder / "summary.json").write_text(json.dumps(summary))
    curve = list(returns) + [300] * (total // 10_000 - len(returns))
    online = curve if online is None else list(online) + [300] * (total // 10_000 - len(online))
    step = 3 if arm == "baseline" and more else 0
    count = list(promoted) + [promoted[-1] + step * (i + 1) for i in range(30)]
    threshold = [100 if n < 10 else 150 if arm == "hold" or i < 8 else 150 + 5 * (i - 7) for i, n in enumerate(count)]
    rows = ["tag,frames,value"]
    for i in range(total // 10_000):
        frames = 10_000 * (i + 1)
        rows += [
            f"eval/return,{frames},{curve[i]}",
            f"eval/return_online,{frames},{online[i]}",
            f"teacher/num_promoted,{frames},{count[i]}",
            f"teacher/threshold,{frames},{threshold[i]}",
        ]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")
    return folder


def full_set(root, hold=STEADY, baseline=DROPPING, skip=()):
    for seed in rule.SEEDS:
        if ("baseline", seed) not in skip:
            write_run(root, "baseline", seed, baseline)
        if ("hold", seed) not in skip:
            write_run(root, "hold", seed, hold)


def row_of(text, seed):
    return next(line for line in text.splitlines() if line.startswith(f"| {seed} |"))


def test_fewer_drops_when_held_name_the_teacher_buffers_change_a_cause(tmp_path):
    """Per seed: held 1 drop and 0 falls in 11, the other run 5 drops and 4 falls in 11; pooled 4/44
    (9.1%) against 20/44 (45.5%): at most half of it, with at least 4 drops there, in all 4 seeds."""
    full_set(tmp_path)
    text = rule.report([tmp_path])
    assert row_of(text, 100) == (
        "| 100 | 80k (10) | 90k | yes | 150 / 150, 150 / 210 | 0/11 / 4/11 | 1/11 / 5/11 | 0/11 / 4/11 | 1/11 / 5/11 |"
    )
    pooled = row_of(text, "pooled")
    assert "0.0% (0/44) / 36.4% (16/44) | 9.1% (4/44) / 45.5% (20/44)" in pooled
    assert (
        "**Reading: the teacher buffer's change is a cause of the drops: the held runs' target actor dropped in "
        in text
    )
    assert (
        "9.1% (4/44) of their evaluations, at most 0.5 of the other runs' 45.5% (20/44), and no more often than" in text
    )


def test_exactly_half_is_a_cause_and_as_often_is_not_shown(tmp_path):
    """2 drops against 4 per seed: 8/44 is exactly half of 16/44; then 4 against 4."""
    full_set(tmp_path / "half", hold=TWO, baseline=FOUR)
    assert "**Reading: the teacher buffer's change is a cause" in rule.report([tmp_path / "half"])
    full_set(tmp_path / "same", hold=FOUR, baseline=FOUR)
    assert "**Reading: not shown: the held runs' target actor dropped in 36.4% (16/44) of their evaluations, not " in (
        rule.report([tmp_path / "same"])
    )


def test_as_many_drops_when_held_is_not_shown(tmp_path):
    full_set(tmp_path, hold=DROPPING, baseline=STEADY)
    text = rule.report([tmp_path])
    assert "**Reading: not shown: the held runs' target actor dropped in 45.5% (20/44) of their evaluations" in text


def test_between_the_two_is_inconclusive(tmp_path):
    """3 drops per seed against 5: 27.3% is below 45.5% but above half of it."""
    full_set(tmp_path, hold=THREE)
    assert "**Reading: inconclusive: the held runs' target actor dropped in 27.3% (12/44)" in rule.report([tmp_path])


def test_too_few_drops_to_halve_are_inconclusive(tmp_path):
    """No held run drops, but the others drop 3 times in all (fewer than 4): not enough to name a cause."""
    full_set(tmp_path, hold=FLAT, baseline=FLAT, skip={("baseline", 100)})
    write_run(tmp_path, "baseline", 100, THREE)
    expected = "inconclusive: the held runs' target actor dropped in 0.0% (0/44) of their evaluations against the "
    assert f"**Reading: {expected}other runs' 6.8% (3/44), no more often than its pair in 4 of 4 seeds" in (
        rule.report([tmp_path])
    )


def test_four_drops_are_enough(tmp_path):
    full_set(tmp_path, hold=FLAT, baseline=FLAT, skip={("baseline", 100)})
    write_run(tmp_path, "baseline", 100, FOUR)
    assert "**Reading: the teacher buffer's change is a cause of the drops" in rule.report([tmp_path])


def test_a_lower_pooled_share_from_two_seeds_alone_is_inconclusive(tmp_path):
    """Seeds 100-101: held 0 drops against 5; seeds 102-103: held 1 against 0. Pooled 2/44 (4.5%)
    against 10/44 (22.7%) is below half, but only 2 seeds held no worse than their pair."""
    for seed in rule.SEEDS:
        write_run(tmp_path, "hold", seed, FLAT if seed < 102 else STEADY)
        write_run(tmp_path, "baseline", seed, DROPPING if seed < 102 else FLAT)
    assert (
        "4.5% (2/44) of their evaluations against the other runs' 22.7% (10/44), no more often than its pair in "
        in (rule.report([tmp_path]))
    )
    assert "in 2 of 4 seeds (a cause needs" in rule.report([tmp_path])


def test_drops_are_measured_from_the_best_evaluation_before_the_window(tmp_path):
    """The held run of seed 101 evaluated 600 at 70k: 250 at 100k is a drop (below 300), 300 is not."""
    full_set(tmp_path, skip={("hold", 101)})
    write_run(tmp_path, "hold", 101, [50, 60, 80, 150, 300, 300, 600, 300, 300, 250] + [300] * 10)
    row = row_of(rule.report([tmp_path]), 101)
    assert "| no: first differs at 70k |" in row and "| 0/11 / 4/11 | 1/11 / 5/11 |" in row


def test_the_online_actor_is_reported_and_does_not_decide(tmp_path):
    full_set(tmp_path)
    folder = tmp_path / "hold" / "paper-average10k-hold" / "Hopper-v4" / "sail" / "seed100"
    rows = (folder / "scalars.csv").read_text().replace("eval/return_online,100000,300", "eval/return_online,100000,5")
    (folder / "scalars.csv").write_text(rows)
    text = rule.report([tmp_path])
    assert row_of(text, 100).endswith("| 1/11 / 4/11 | 2/11 / 5/11 |")  # the online actor's fall is also a drop
    assert "is a cause of the drops" in text


def test_a_pair_that_trained_apart_before_the_hold_is_shown_and_counted(tmp_path):
    full_set(tmp_path, skip={("hold", 101)})
    write_run(tmp_path, "hold", 101, [50, 60, 80, 150, 310, *STEADY[5:]])
    text = rule.report([tmp_path])
    assert "| no: first differs at 50k |" in row_of(text, 101)
    assert "9.1% (4/44) / 45.5% (20/44)" in row_of(text, "pooled")


def test_a_seed_counts_for_neither_side_without_a_hold_or_a_split(tmp_path):
    """Seed 102's held run never promoted 10; seed 103's pair promoted no more than it by 200k."""
    full_set(tmp_path, skip={("hold", 102), ("baseline", 103)})
    write_run(tmp_path, "hold", 102, STEADY, promoted=[0, 0, 0, 1, 2, 3, 4, 5])
    write_run(tmp_path, "baseline", 103, DROPPING, more=False)
    text = rule.report([tmp_path])
    assert "| 102 | never: 10 trajectories not promoted by 200k |" in text
    assert "| 103 | 80k | none: the other run promoted no more by 200k |" in text
    assert "9.1% (2/22) / 45.5% (10/22)" in row_of(text, "pooled")


def test_a_run_that_passes_in_the_window_counts_falls_after_its_pass_only(tmp_path):
    """The other run of seed 100 passes at 110k: of the window's 11, the 9 after it count, one falls
    (20 at 120k, also a drop: below half of 150)."""
    full_set(tmp_path, skip={("baseline", 100)})
    write_run(tmp_path, "baseline", 100, [50] * 10 + [150, 20])
    assert "| 0/11 / 1/9 | 1/11 / 1/11 |" in row_of(rule.report([tmp_path]), 100)


def test_pending_until_every_run_is_there(tmp_path):
    full_set(tmp_path, skip={("hold", 103), ("baseline", 100)})
    assert "**Reading: pending (2 runs missing: seed 100 baseline, seed 103 hold).**" in rule.report([tmp_path])


@pytest.mark.parametrize(
    "arm, config, message",
    [
        ("hold", {"algo.max_promoted": 20}, "counted as a hold run, but its config has algo.max_promoted=20"),
        ("baseline", {"algo.max_promoted": 10}, "counted as a baseline run, but its config has algo.max_promoted=10"),
        ("hold", {"eval.actor": "online"}, "its config has eval.actor='online' where the hold runs have 'target'"),
    ],
)
def test_a_run_not_run_with_its_stages_settings_is_refused_by_folder(tmp_path, arm, config, message):
    full_set(tmp_path, skip={(arm, 100)})
    folder = write_run(tmp_path, arm, 100, STEADY, config=config)
    with pytest.raises(ValueError, match=message) as err:
        rule.report([tmp_path])
    assert str(folder) in str(err.value)


def test_two_runs_of_one_seed_are_refused(tmp_path):
    full_set(tmp_path)
    write_run(tmp_path / "copy", "hold", 100, STEADY)
    with pytest.raises(ValueError, match="two hold runs of seed 100"):
        rule.report([tmp_path, tmp_path / "copy"])


def test_out_writes_the_report_into_a_new_folder(tmp_path, capsys):
    full_set(tmp_path / "runs")
    assert rule.main([str(tmp_path / "runs"), "--out", str(tmp_path / "hold" / "rule.md")]) == 0
    assert (tmp_path / "hold" / "rule.md").read_text() == capsys.readouterr().out
