"""``benchmarks/hold_rule.py``: the runs that held the teacher buffer against their pairs, on
hand-made result folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark

rule = load_benchmark("hold_rule")

TEACHER = 100.0
# evaluations every 10k frames from 10k; promotions reach 10 at 80k: the window is 90k-200k (12)
BEFORE = [50, 60, 80, 150, 300, 300, 300, 300]  # a pass at 40k
# 5 drops (120 is below half of the best earlier, 300, not of the one before, 20), 4 falls in 12
DROPPING = BEFORE + [300, 20, 120, 300, 20, 300, 300, 20, 300, 300, 20, 300]
STEADY = BEFORE + [300, 300, 200, 300, 300, 120, 300, 300, 300, 300, 300, 300]  # 1 drop (120; not 200), no fall
THREE = BEFORE + [300, 20, 300, 300, 20, 300, 300, 20, 300, 300, 300, 300]  # 3 drops
PROMOTED = [0, 0, 0, 1, 4, 6, 8, 10]  # the tenth at 80k


def write_run(root, arm, seed, returns, *, online=None, config=None, promoted=PROMOTED):
    """A collected run: the average stage's (``baseline``, 300k frames, evaluations after 200k at 300)
    or the hold stage's (``hold``, 200k), with ``returns`` as its target actor's evaluations."""
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
    count = list(promoted) + [promoted[-1] if arm == "hold" else promoted[-1] + 3 * (i + 1) for i in range(30)]
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


def test_fewer_drops_when_held_name_the_teacher_buffers_change_a_cause(tmp_path):
    """Per seed: held 1 drop and 0 falls in 12, the other run 5 drops and 4 falls in 12; pooled 4/48
    (8.3%) against 20/48 (41.7%): at most half of it, with at least 4 drops there."""
    full_set(tmp_path)
    text = rule.report([tmp_path])
    row = next(line for line in text.splitlines() if line.startswith("| 100 |"))
    assert row == ("| 100 | 80k | yes | 150 / 150, 150 / 210 | 0/12 / 4/12 | 1/12 / 5/12 | 0/12 / 4/12 | 1/12 / 5/12 |")
    pooled = next(line for line in text.splitlines() if line.startswith("| pooled |"))
    assert "0.0% (0/48) / 33.3% (16/48) | 8.3% (4/48) / 41.7% (20/48)" in pooled
    assert (
        "**Reading: the teacher buffer's change causes falls: the held runs' target actor dropped in 8.3% (4/48)"
        in text
    )


def test_as_many_drops_when_held_is_not_shown(tmp_path):
    full_set(tmp_path, hold=DROPPING, baseline=STEADY)
    assert (
        "**Reading: not shown: the held runs' target actor dropped in 41.7% (20/48) of their evaluations, not fewer"
        in (rule.report([tmp_path]))
    )


def test_between_the_two_is_inconclusive(tmp_path):
    """3 drops per seed against 5: 25% is below 41.7% but above half of it."""
    full_set(tmp_path, hold=THREE)
    assert "**Reading: inconclusive: the held runs' target actor dropped in 25.0% (12/48)" in rule.report([tmp_path])


def test_the_online_actor_is_reported_and_does_not_decide(tmp_path):
    full_set(tmp_path)
    folder = tmp_path / "hold" / "paper-average10k-hold" / "Hopper-v4" / "sail" / "seed100"
    rows = (folder / "scalars.csv").read_text().replace("eval/return_online,100000,300", "eval/return_online,100000,5")
    (folder / "scalars.csv").write_text(rows)
    text = rule.report([tmp_path])
    row = next(line for line in text.splitlines() if line.startswith("| 100 |"))
    assert row.endswith("| 1/12 / 4/12 | 2/12 / 5/12 |")  # the online actor's extra fall is also a drop
    assert "causes falls" in text


def test_a_pair_that_trained_apart_before_the_hold_is_shown(tmp_path):
    full_set(tmp_path, skip={("hold", 101)})
    write_run(tmp_path, "hold", 101, [50, 60, 80, 150, 310, *STEADY[5:]])
    row = next(line for line in rule.report([tmp_path]).splitlines() if line.startswith("| 101 |"))
    assert "| no: first differs at 50k |" in row


def test_a_held_run_that_never_promoted_ten_counts_for_neither_side(tmp_path):
    full_set(tmp_path, skip={("hold", 102)})
    write_run(tmp_path, "hold", 102, STEADY, promoted=[0, 0, 0, 1, 2, 3, 4, 5])
    text = rule.report([tmp_path])
    assert "| 102 | never: 10 trajectories not promoted by 200k |" in text
    assert "8.3% (3/36) / 41.7% (15/36)" in text


def test_too_few_drops_to_halve_are_inconclusive(tmp_path):
    """No held run drops, but the others drop 3 times in all (fewer than 4): not enough to name a cause."""
    flat = BEFORE + [300] * 12
    full_set(tmp_path, hold=flat, baseline=flat, skip={("baseline", 100)})
    write_run(tmp_path, "baseline", 100, THREE)
    expected = "inconclusive: the held runs' target actor dropped in 0.0% (0/48) of their evaluations against the "
    assert f"**Reading: {expected}other runs' 6.2% (3/48)" in rule.report([tmp_path])


def test_a_run_that_passes_in_the_window_counts_falls_after_its_pass_only(tmp_path):
    """The other run of seed 100 passes at 110k: of the window's 12, the 9 after it count, one falls
    (20 at 120k, also a drop: below half of 150)."""
    full_set(tmp_path, skip={("baseline", 100)})
    write_run(tmp_path, "baseline", 100, [50] * 10 + [150, 20])
    row = next(line for line in rule.report([tmp_path]).splitlines() if line.startswith("| 100 |"))
    assert "| 0/12 / 1/9 | 1/12 / 1/12 |" in row


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
