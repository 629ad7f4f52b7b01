"""``benchmarks/checkpoint_rewards.py``: D's reward per row group at a run's checkpoint."""

from __future__ import annotations

import math
import shutil

import pytest
import torch
from benchmark_scripts import load_benchmark
from example_runner import run
from omegaconf import OmegaConf
from tensordict import TensorDict
from test_example import HOPPER, TINY

from torchrl_sail import Discriminator, DiscriminatorReward

checkpoint_rewards = load_benchmark("checkpoint_rewards")


def constant_discriminator(logit: float) -> Discriminator:
    """A D whose logit is ``logit`` for every row: last layer zero, its bias ``logit``."""
    discriminator = Discriminator(3, 2, num_cells=(4,))
    last = discriminator.module.mlp[-1]
    with torch.no_grad():
        last.weight.zero_()
        last.bias.fill_(logit)
    return discriminator


def rows(n: int) -> TensorDict:
    return TensorDict(
        {"observation": torch.randn(n, 3), "action": torch.rand(n, 2), ("next", "reward"): torch.zeros(n, 1)}, [n]
    )


@pytest.mark.parametrize(
    ("kind", "clip", "coef", "expected"),
    [
        ("gail", None, 1.0, math.log1p(math.exp(-1.5))),  # -log(1 - D) = softplus(logit)
        ("airl", None, 1.0, -1.5),  # the logit itself
        ("airl", (0.01, 0.99), 0.1, 0.1 * -1.5),  # inside the clip: unchanged, times coef
        ("gail", (0.3, 0.99), 1.0, -math.log(0.7)),  # D = sigmoid(-1.5) = 0.18 clipped up to 0.3
    ],
)
def test_summarize_against_hand_computed_values(kind, clip, coef, expected):
    reward = DiscriminatorReward(constant_discriminator(-1.5), kind=kind, clip=clip, coef=coef, keep_logit=True)
    stats = checkpoint_rewards.summarize(reward, rows(5))
    assert stats["count"] == 5
    assert stats["D"] == pytest.approx(1 / (1 + math.exp(1.5)))
    assert stats["logit"] == pytest.approx(-1.5)
    assert stats["reward"] == pytest.approx(expected, rel=1e-6)
    assert stats["reward_std"] == pytest.approx(0.0, abs=1e-6)
    assert checkpoint_rewards.summarize(reward, rows(0)) == {"count": 0}
    line = checkpoint_rewards.table({"agent": stats, "none": {"count": 0}}).splitlines()
    assert line[2] == f"| agent | 5 | 0.182 | -1.50 | {expected:.3f} | 0.000 |"
    assert line[3] == "| none | 0 | - | - | - | - |"


def test_summarize_leaves_out_the_stored_env_reward():
    """source=shaped adds D's reward to the stored delayed reward: the tool reports D's part alone."""
    reward = DiscriminatorReward(constant_discriminator(0.5), kind="airl", coef=0.3, mode="add", keep_logit=True)
    stored = rows(4)
    stored["next", "reward"] += 7.0
    assert checkpoint_rewards.summarize(reward, stored)["reward"] == pytest.approx(0.3 * 0.5)


def test_groups_without_absorbing_states_keep_the_write_order():
    agent = rows(6)
    agent["observation"][:, 0] = torch.arange(6.0)  # the write order
    named = checkpoint_rewards.groups(OmegaConf.create({"algo": {"absorbing_state": False}}), rows(2), agent, 4)
    assert list(named) == ["teacher buffer", "agent, all", "agent, latest 4"]
    assert named["agent, latest 4"]["observation"][:, 0].tolist() == [2.0, 3.0, 4.0, 5.0]
    assert checkpoint_rewards.groups(OmegaConf.create({"algo": {"absorbing_state": False}}), rows(2), agent, 10)[
        "agent, latest 6"
    ].shape == (6,)


def test_recent_must_be_positive():
    with pytest.raises(SystemExit):
        checkpoint_rewards.parse_args(["run", "--recent", "0"])


@pytest.mark.slow  # runs the example
def test_groups_of_a_dac_published_checkpoint(tmp_path, teacher_dir, capsys):
    run_dir = tmp_path / "dac_published"
    run(
        run_dir,
        "algo=dac_published",
        f"teacher.path={teacher_dir / HOPPER}",
        "env=Hopper-v4",
        "collector.total_frames=2000",
        "logger.backends=[csv]",
        "checkpoint.every_frames=1000",
        "optim.actor_updates_after=60",
        "optim.actor_lr_decay.every_frames=1000",
        "env.replay_size=1500",  # 2000 frames and their absorbing rows wrap the ring
        *TINY,
    )
    stats = checkpoint_rewards.main([str(run_dir), "--recent", "500"])
    out = capsys.readouterr().out
    assert "checkpoint at 2000 frames; D reward: source discriminator, kind airl, clip None, coef 1.0" in out
    assert list(stats) == [
        f"{group}, {part}"
        for group in ("teacher buffer", "agent, all", "agent, latest 500")
        for part in ("live", "absorbing")
    ]
    # the ring holds the last 1500 rows (live ones and each fall's absorbing row) ...
    assert stats["agent, all, live"]["count"] + stats["agent, all, absorbing"]["count"] == 1500
    assert stats["agent, all, absorbing"]["count"] >= 1
    # ... in write order: each row's next observation is the next row's observation, except where an episode starts
    agent = checkpoint_rewards.load(run_dir)[4]
    time_feature = agent["observation"][:, -2]  # before the absorbing indicator
    continues = (agent["next", "observation"][:-1] == agent["observation"][1:]).all(-1)
    assert bool((continues | (time_feature[1:] == 1.0)).all())
    assert int((time_feature == 1.0).sum()) < 1500 // 2  # (the check is not vacuous)
    assert stats["agent, latest 500, live"]["count"] + stats["agent, latest 500, absorbing"]["count"] == 500
    # the paper's Hopper teacher falls once (step 425): one demonstration, one absorbing row
    assert stats["teacher buffer, live"]["count"] == 425 and stats["teacher buffer, absorbing"]["count"] == 1
    assert "teacher buffer: 1 trajectories held, of 1 demonstrations and 0 promoted" in out
    for group in stats.values():  # dac_published's reward is the logit itself
        assert group["reward"] == pytest.approx(group["logit"], abs=1e-5)
        assert 0 < group["D"] < 1
    # absorbing rows are one state with the zero action: one logit
    assert stats["agent, all, absorbing"]["reward_std"] == pytest.approx(0.0, abs=1e-6)
    # a method without a discriminator reward (the same checkpoint, its config saying so) is refused
    other = tmp_path / "td3_delayed"
    shutil.copytree(run_dir, other)
    config = OmegaConf.load(other / "config.yaml")
    config.algo.name, config.algo.reward.source = "td3_delayed", "env"
    OmegaConf.save(config, other / "config.yaml")
    with pytest.raises(ValueError, match="algo=td3_delayed learns from the env's reward"):
        checkpoint_rewards.main([str(other)])
    config.algo.name, config.algo.learner = "gail", "ppo"
    OmegaConf.save(config, other / "config.yaml")
    with pytest.raises(ValueError, match="algo=gail is on-policy"):
        checkpoint_rewards.main([str(other)])
