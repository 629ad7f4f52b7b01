"""``benchmarks/remedy_rule.py``: which remedy of the falls goes on to a confirmation, on hand-made
result folders."""

from __future__ import annotations

import json

import pytest
import yaml
from benchmark_scripts import load_benchmark, nest

rule = load_benchmark("remedy_rule")

TEACHER = 100.0
# evaluations every 10k frames: a pass at the second, then four counted evaluations
HOLDS = [50, 200, 200, 200, 200, 200]  # no fall, last-5 200
FALLS_ONCE = [50, 200, 90, 200, 200, 200]  # one fall in 4, last-5 178
NEVER_PASSES = [50, 60, 70, 80, 90, 95]


def write_run(root, setting, env, teacher, seed, returns, config=None, averaged=None):
    """A collected run of ``setting`` (its stage, label and config) with ``returns`` as its target
    actor's evaluations and, for the candidate, ``averaged`` (default: ``returns``) as its averaged
    actor's; ``config`` replaces the setting's config entries it names."""
    stage, label = (
        ("average", f"{teacher}-average{10 if seed < 102 else 30}k")
        if setting == "candidate"
        else ("remedies", f"{teacher}-trusted-{setting}")
    )
    folder = root / stage / label / env / "sail" / f"seed{seed}"
    folder.mkdir(parents=True)
    (root / stage / "matrix.json").write_text("{}")  # a campaign stage: labels are its teacher folders
    values = {**rule.SETTINGS[setting], **(config or {})}
    if setting == "candidate":
        values = {"eval.average_frames": 10_000 if seed < 102 else 30_000, **values}
    nested = {"env": {"name": env}, "algo": {"name": "sail"}, "seed": seed, "collector": {"total_frames": 300_000}}
    nested["eval"] = {"episodes": 10, "every_frames": 10_000}
    nest(values, nested)  # a None value: a key the run's config lacks
    (folder / "config.yaml").write_text(yaml.safe_dump(nested))
    summary = {"env": env, "frames": 300_000, "total_frames": 300_000, "teacher_return": TEACHER}
    (folder / "summary.json").write_text(json.dumps(summary))
    rows = ["tag,frames,value", *(f"eval/return,{10_000 * (i + 1)},{v}" for i, v in enumerate(returns))]
    if setting == "candidate":
        averaged = returns if averaged is None else averaged
        rows += [f"eval/return_average,{10_000 * (i + 1)},{v}" for i, v in enumerate(averaged)]
    (folder / "scalars.csv").write_text("\n".join(rows) + "\n")
    return folder


def full_set(root, returns=None, skip=(), config=None, averaged=None):
    """Every tuning run: the candidate falls once in 4 after passing, the remedies hold, except where
    ``returns`` maps (setting, env, seed) to other returns; ``config`` maps (setting, env, seed) to
    config entries; ``averaged`` maps (env, seed) to the candidate's averaged actor's returns (default:
    its target actor's)."""
    returns, config, averaged = returns or {}, config or {}, averaged or {}
    for setting in rule.SETTINGS:
        for env, teacher in rule.AVERAGE_TEACHERS:
            for seed in rule.REMEDY_SEEDS:
                if (setting, env, seed) not in skip:
                    default = FALLS_ONCE if setting == "candidate" else HOLDS
                    write_run(
                        root,
                        setting,
                        env,
                        teacher,
                        seed,
                        returns.get((setting, env, seed), default),
                        config.get((setting, env, seed)),
                        averaged.get((env, seed)) if setting == "candidate" else None,
                    )


def test_the_remedy_with_the_lowest_fall_share_goes_on_when_it_meets_every_criterion(tmp_path):
    """The candidate falls 8 times in 32 counted evaluations (25%: a remedy may have 12.5%); ln and fifo
    fall once each (1/32 = 3.1%), actor_lr never: all three meet every criterion, and actor_lr's share
    is the lowest. An average-stage config that predates network.critic_layer_norm and optim.actor_lr
    reads as their values then (False, null)."""
    full_set(
        tmp_path,
        returns={("fifo", "Hopper-v4", 100): FALLS_ONCE, ("ln", "Walker2d-v4", 102): FALLS_ONCE},
        config={("candidate", "Hopper-v4", 100): {"network.critic_layer_norm": None, "optim.actor_lr": None}},
    )
    text = rule.report([tmp_path])
    assert "runs found: candidate 8, ln 8, fifo 8, actor_lr 8." in text
    assert "| Hopper-v4 | paper (100.0) | candidate | 4 | 4 | 178.0 ± 0.0 | 25.0% (4/16) |" in text
    assert "| Hopper-v4 | paper (100.0) | fifo | 4 | 4 | 194.5 ± 11.0 | 6.2% (1/16) |" in text
    assert "| Walker2d-v4 | shipped (100.0) | actor_lr | 4 | 4 | 200.0 ± 0.0 | 0.0% (0/16) |" in text
    assert "- actor_lr:\n  - met: fall share 0.0% (0/32), at most 0.5 of the candidate's 25.0% (8/32), 12.5%" in text
    assert "- ln:\n  - met: fall share 3.1% (1/32), at most 0.5 of the candidate's 25.0% (8/32), 12.5%" in text
    # the candidate's last-5 is 178 on every seed: std 0, so the floor is 178.0
    assert (
        "  - met: Walker2d-v4 (shipped teacher) last-5 200.0, not below the candidate's mean minus its std, 178.0"
        in text
    )
    assert "**Choice: actor_lr (the lowest fall share) goes on to a confirmation.**" in text


def test_none_goes_on_when_the_lowest_fall_share_misses_a_criterion(tmp_path):
    """ln's one run that never passes its teacher counts no evaluation: ln's share stays the lowest
    (0/28, tied with actor_lr's 0/32 and first in campaign.REMEDIES) but it misses 'every run passes';
    fifo (3.1%) and actor_lr meet all, yet the rule judges the lowest alone."""
    full_set(
        tmp_path,
        returns={("ln", "Walker2d-v4", 103): NEVER_PASSES, ("fifo", "Hopper-v4", 100): FALLS_ONCE},
    )
    text = rule.report([tmp_path])
    assert "  - missed: runs passing their teacher: 7 of 8" in text
    assert "  - met: fall share 0.0% (0/28)" in text
    assert "**Choice: none: ln, the lowest fall share, misses a criterion.**" in text


def test_a_remedy_misses_on_last5_below_the_candidates_mean_minus_its_std(tmp_path):
    """The candidate's Hopper last-5 are 178, 178, 178 and 200 (mean 183.5, std 11.0: floor 172.5);
    ln's Hopper runs end lower, last-5 (200 + 4 * 150) / 5 = 160, without a fall: its share (0%) is
    the lowest and it misses on last-5, so none goes on."""
    low = [50, 200, 150, 150, 150, 150]
    full_set(
        tmp_path,
        returns={
            ("candidate", "Hopper-v4", 103): HOLDS,
            **{("ln", "Hopper-v4", seed): low for seed in rule.REMEDY_SEEDS},
        },
    )
    text = rule.report([tmp_path])
    assert (
        "  - missed: Hopper-v4 (paper teacher) last-5 160.0, not below the candidate's mean minus its std, 172.5"
        in text
    )
    assert "**Choice: none: ln, the lowest fall share, misses a criterion.**" in text


def test_pending_until_every_run_and_refusals_name_the_folder(tmp_path):
    full_set(tmp_path, skip={("fifo", "Walker2d-v4", 101)})
    text = rule.report([tmp_path])
    assert "- fifo: pending, 1 of its and the candidate's runs missing." in text
    assert "- ln:\n  - met:" in text
    assert "**Choice: pending (the choice waits for every run).**" in text

    # a run labelled ln that was not run with the LayerNorm critic
    other = tmp_path / "other"
    full_set(other, config={("ln", "Hopper-v4", 102): {"network.critic_layer_norm": False}})
    with pytest.raises(
        ValueError, match=r"seed102: counted as a ln run, but its config has network.critic_layer_norm=False"
    ):
        rule.report([other])
    # two candidate runs of one cell
    twice = tmp_path / "twice"
    full_set(twice)
    write_run(twice / "copy", "candidate", "Hopper-v4", "paper", 100, HOLDS)
    with pytest.raises(ValueError, match=r"two candidate runs of \('Hopper-v4', 'paper', 100\)"):
        rule.report([twice])


def test_the_averaged_actor_goes_on_with_the_memory_of_the_lower_fall_share(tmp_path):
    """The target actor falls once in 4 on every run (8/32 = 25%: the averaged actor may have 12.5%).
    The averaged actor holds on the 10k seeds (100, 101) and falls once on one 30k run: 1/32 = 3.1%,
    last-5 at least the target actor's 178 everywhere; 10k's share (0/16) is below 30k's (1/16)."""
    holds = {(env, seed): HOLDS for env, _ in rule.AVERAGE_TEACHERS for seed in rule.REMEDY_SEEDS}
    full_set(tmp_path, averaged={**holds, ("Hopper-v4", 102): FALLS_ONCE})
    text = rule.report([tmp_path])
    assert "| Hopper-v4 | paper (100.0) | candidate, averaged actor | 4 | 4 | 194.5 ± 11.0 | 6.2% (1/16) |" in text
    assert "  - met: fall share 3.1% (1/32), at most 0.5 of the target actor's 25.0% (8/32), 12.5%" in text
    assert "  - memory 10k (seeds 100, 101): fall share 0.0% (0/16)" in text
    assert "  - memory 30k (seeds 102, 103): fall share 6.2% (1/16)" in text
    assert text.endswith(
        "**Averaged actor: it goes on to a confirmation with eval.average_frames=10000 (the lower fall share).**"
    )


def test_the_averaged_actor_stops_at_a_missed_criterion_and_waits_for_every_run(tmp_path):
    """Its falls are the target actor's (25%, above half of it): it does not go on. With one average-stage
    run missing it is pending."""
    full_set(tmp_path)
    text = rule.report([tmp_path])
    assert "  - missed: fall share 25.0% (8/32), at most 0.5 of the target actor's 25.0% (8/32), 12.5%" in text
    assert text.endswith("**Averaged actor: it does not go on: it misses a criterion.**")

    missing = tmp_path / "missing"
    full_set(missing, skip={("candidate", "Walker2d-v4", 103)})
    text = rule.report([missing])
    assert "- averaged: pending, 1 of the average stage's runs missing." in text
    assert text.endswith("**Averaged actor: pending (the choice waits for every run).**")


def test_an_average_run_whose_memory_or_seed_is_not_its_labels_is_refused(tmp_path):
    full_set(tmp_path, config={("candidate", "Hopper-v4", 102): {"eval.average_frames": 10_000}})
    with pytest.raises(
        ValueError,
        match=r"seed102: labelled paper-average30k, but its config has "
        r"eval.average_frames=10000 where the label names 30000",
    ):
        rule.report([tmp_path])
    elsewhere = tmp_path / "elsewhere"
    full_set(elsewhere, skip={("candidate", "Walker2d-v4", 101)})
    folder = write_run(elsewhere / "moved", "candidate", "Walker2d-v4", "shipped", 101, HOLDS)
    label = folder.parent.parent.parent
    label.rename(label.with_name("shipped-average30k"))  # a 30k label on a 10k seed
    config = folder.parents[3] / "shipped-average30k" / "Walker2d-v4" / "sail" / "seed101" / "config.yaml"
    config.write_text(config.read_text().replace("average_frames: 10000", "average_frames: 30000"))
    with pytest.raises(ValueError, match=r"labelled shipped-average30k on seed 101, not one of that memory's seeds"):
        rule.report([elsewhere])
