"""Tests for RNDReward (envs/rnd_reward.py): the RND bonus at sample time."""

from __future__ import annotations

import argparse

import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs
from torchrl.testing.mocking_classes import ContinuousActionVecMockEnv

from torchrl_sail import RNDReward


def _linear(weight):
    layer = nn.Linear(len(weight[0]), len(weight), bias=False)
    with torch.no_grad():
        layer.weight.copy_(torch.tensor(weight))
    return layer


def _batch(next_obs, reward):
    n = len(next_obs)
    return TensorDict(
        {"next": {"observation": torch.tensor(next_obs), "reward": torch.tensor(reward).unsqueeze(-1)}}, batch_size=[n]
    )


class TestRNDReward:
    def test_bonus_against_hand_values(self):
        # target = identity, predictor = 2 * identity: error = mean(x^2) over the 2 features
        rnd = RNDReward(
            _linear([[1.0, 0.0], [0.0, 1.0]]),
            _linear([[2.0, 0.0], [0.0, 2.0]]),
            coef=0.5,
            normalize_obs=False,
            normalize_reward=False,
        )
        out = rnd(_batch([[1.0, 3.0], [0.0, 2.0]], [10.0, 20.0]))
        # bonus: (1 + 9) / 2 = 5 and (0 + 4) / 2 = 2; reward + 0.5 * bonus
        assert out["next", "reward"].squeeze(-1).tolist() == [12.5, 21.0]

    def test_statistics_normalise_and_are_not_updated_at_sample_time(self):
        rnd = RNDReward(
            _linear([[1.0, 0.0], [0.0, 1.0]]), _linear([[2.0, 0.0], [0.0, 2.0]]), reward_clip=100.0, obs_clip=100.0
        )
        env = TransformedEnv(ContinuousActionVecMockEnv(), RNDReward(nn.Linear(7, 4), nn.Linear(7, 4)))
        check_env_specs(env)  # the inherited env path
        rnd._maybe_init_rms(torch.zeros(2))
        rnd.obs_rms.update(torch.tensor([[1.0, 1.0], [3.0, 5.0]]))  # mean [2, 3], var [1, 4]
        rnd.reward_rms.update(torch.tensor([1.0, 3.0]))  # var 1
        counts = rnd.obs_rms.count.clone(), rnd.reward_rms.count.clone()
        out = rnd(_batch([[4.0, 7.0]], [0.0]))
        # normalised obs: (4 - 2) / 1 = 2, (7 - 3) / 2 = 2; error = mean(2^2, 2^2) = 4; / sqrt(var ~ 1)
        std = rnd.reward_rms.var.sqrt().item()
        assert out["next", "reward"].item() == pytest.approx(4.0 / std, rel=1e-3)  # (the initial count 1e-4)
        assert rnd.obs_rms.count == counts[0] and rnd.reward_rms.count == counts[1]

    def test_chunked_equals_whole(self):
        torch.manual_seed(0)
        net = lambda: nn.Sequential(nn.Linear(3, 8), nn.ReLU(), nn.Linear(8, 4))  # noqa: E731
        target, predictor = net(), net()
        obs = torch.randn(5, 7, 3)
        whole = RNDReward(target, predictor, normalize_obs=False, normalize_reward=False).bonus(obs)
        chunked = RNDReward(target, predictor, normalize_obs=False, normalize_reward=False, chunk_size=4).bonus(obs)
        assert whole.shape == (5, 7, 1)
        torch.testing.assert_close(chunked, whole)

    def test_row_ids_evaluate_each_distinct_row_once(self):
        torch.manual_seed(0)
        calls = []
        target = nn.Linear(3, 4)
        predictor = nn.Linear(3, 4)
        predictor.register_forward_hook(lambda module, args, out: calls.append(args[0].shape[0]))
        rnd = RNDReward(target, predictor, normalize_obs=False, normalize_reward=False, row_id_key="row_id")
        stored = torch.randn(5, 3)
        ids = torch.tensor([[0, 3, 3, 1], [4, 0, 1, 1]])  # a [2, 4] block drawing 4 distinct rows
        block = TensorDict(
            {"row_id": ids, "next": {"observation": stored[ids], "reward": torch.zeros(2, 4, 1)}}, batch_size=[2, 4]
        )
        out = rnd(block.clone())
        assert calls == [4]
        expected = RNDReward(target, predictor, normalize_obs=False, normalize_reward=False).bonus(stored[ids])
        torch.testing.assert_close(out["next", "reward"], expected)

    def test_bad_chunk_size(self):
        with pytest.raises(ValueError, match="chunk_size"):
            RNDReward(nn.Linear(2, 2), nn.Linear(2, 2), chunk_size=0)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
