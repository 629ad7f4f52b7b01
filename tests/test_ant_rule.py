"""``benchmarks/ant_rule.py``: which way to train on the authors' Ant teacher the docs recommend, on
hand-made result folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark, nest

rule = load_benchmark("ant_rule")

TEACHER = 1000.0
# ten evaluations every 10k frames; last-5 is the mean of the last five
PASSES = [500, 800, 1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800]  # last-5 1600
PASSES_LOWER = [500, 800, 1100, 1000, 1000, 1000, 1050, 1100, 1150, 1200]  # last-5 1100
NEVER_PASSES = [500, 600, 700, 800, 900, 900, 900, 900, 900, 900]  # last-5 900


def write_run(root, way, seed, returns, method="sail", config=None):
    """A collected ant-stage run of ``way`` (its label and env settings) with ``returns`` as its
    evaluations; ``config`` replaces the way's config entries it names."""
    folder = root / "ant" / way / "Ant-v4" / method / f"seed{seed}"
    folder.mkdir(parents=True)
    (root / "ant" / "matrix.json").write_text("{}")  # a campaign stage: labels are its teacher folders
    nested = {"env": {"name": "Ant-v4"}, "algo": {"name": method}, "seed": seed}
    nested |= {"collector": {"total_frames": 300_000}, "eval": {"episodes": 10, "every_frames": 10_000}}
    default = rule.SAIL_DEFAULT if method == "sail" else {}
    nest({**rule.WAYS[way], **default, **(config or {})}, nested)
    (folder / "config.yaml").write_text(yaml.safe_dump(nested))
    summary = {"env": "Ant-v4", "frames": 300_000, "total_frames": 300_000, "teacher_return": TEACHER}
    (folder / "summary.json").write_text(json.dumps(summary))
    rows = ["tag,frames,value", *(f"eval/return,{10_000 * (i + 1)},{v}" for i, v in enumerate(returns))]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")


def both_ways(root, recorded, own, dac=NEVER_PASSES):
    """SAIL's runs of seeds 0-2 each way (``recorded``, ``own``: a list of returns per seed), and DAC's."""
    for seed in rule.COMPARISON_SEEDS:
        write_run(root, "paper", seed, recorded[seed])
        write_run(root, "paper-nocontact", seed, own[seed])
        for way in rule.WAYS:
            write_run(root, way, seed, dac, method="dac")


def test_the_way_with_more_seeds_passing_is_recommended_with_its_command(tmp_path):
    """The recorded columns pass on 3 seeds, the 27 on 2: step 1 picks the recorded columns, though the
    27 columns' last-5 is higher where they pass. DAC never passes and takes no part."""
    both_ways(tmp_path, [PASSES_LOWER] * 3, [PASSES, PASSES, NEVER_PASSES])
    text = rule.report([tmp_path])
    assert "| the recorded 111 columns (`paper`) | sail | 3 | 3 | 1100.0 ± 0.0 | 0.0% (0/21) |" in text
    # last-5 1600, 1600, 900: mean 1366.7, sample std 404.1
    assert "| the 27 columns Ant-v4 reproduces (`paper-nocontact`) | sail | 3 | 2 | 1366.7 ± 404.1 |" in text
    assert "| the recorded 111 columns (`paper`) | dac | 3 | 0 | 900.0 ± 0.0 | n/a (0 counted) |" in text
    assert (
        "**Recommended way: the recorded 111 columns (step 1: 3 of its 3 seeds passed the teacher, against 2):**"
        in text
    )
    assert text.endswith(
        "```bash\npython examples/sail_td3.py env=Ant-v4 "
        "teacher.path=<teachers>/expert_data_no_img_Ant_scores_1200_episodes_1.npz\n```"
    )


def test_on_a_tie_the_higher_mean_wins_only_beyond_the_larger_std(tmp_path):
    """Every run passes. Recorded: last-5 1600 on every seed (std 0); own: 1100 (std 0): the gap 500 is
    above the larger std 0, so step 2 picks the recorded columns."""
    both_ways(tmp_path, [PASSES] * 3, [PASSES_LOWER] * 3)
    text = rule.report([tmp_path])
    assert (
        "**Recommended way: the recorded 111 columns (step 2: both passed on 3 seeds; its last-5 mean is "
        "higher by 500.0, more than the larger std, 0.0):**" in text
    )

    # own: last-5 1600, 1600, 1100 (mean 1433.3, std 288.7) against 1600 (std 0): gap 166.7, below 288.7
    close = tmp_path / "close"
    both_ways(close, [PASSES] * 3, [PASSES, PASSES, PASSES_LOWER])
    text = rule.report([close])
    assert (
        "**Recommended way: the 27 columns Ant-v4 reproduces (step 3: both passed on 3 seeds; the last-5 "
        "means differ by 166.7, not more than the larger std, 288.7):**" in text
    )
    assert "env.kwargs.use_contact_forces=false teacher.drop_columns=27-110" in text


def test_not_decided_until_every_sail_run_and_refusals_name_the_folder(tmp_path):
    for seed in rule.COMPARISON_SEEDS:
        write_run(tmp_path, "paper", seed, PASSES)
    write_run(tmp_path, "paper-nocontact", 0, PASSES)
    assert (
        rule.recommendation(rule.ant_runs([tmp_path]))
        == "**Recommended way: not decided yet (2 of SAIL's 6 runs missing).**"
    )

    wrong = tmp_path / "wrong"
    write_run(wrong, "paper-nocontact", 1, PASSES, config={"env.kwargs.use_contact_forces": True})
    with pytest.raises(
        ValueError,
        match=r"seed1: labelled paper-nocontact, but its config has env.kwargs.use_contact_forces=True "
        r"where the rule reads sail runs with False",
    ):
        rule.report([wrong])
    replaced = tmp_path / "replaced"  # a SAIL run with the replaced default
    write_run(replaced, "paper", 0, PASSES, config={"eval.actor": "online"})
    with pytest.raises(ValueError, match=r"seed0: labelled paper, but its config has eval.actor='online'"):
        rule.report([replaced])
    twice = tmp_path / "twice"
    write_run(twice, "paper", 2, PASSES)
    write_run(twice / "copy", "paper", 2, PASSES)
    with pytest.raises(ValueError, match=r"two sail runs of paper seed 2"):
        rule.report([twice])
