"""Tests for DiscriminatorReward (envs/discriminator_reward.py)."""

from __future__ import annotations

import argparse
import math

import pytest
import torch
import torch.nn.functional as F
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.envs import Compose, ParallelEnv, SerialEnv, TransformedEnv
from torchrl.envs.utils import check_env_specs
from torchrl.testing.mocking_classes import ContinuousActionVecMockEnv

from torchrl_sail import Discriminator, DiscriminatorLoss, DiscriminatorReward

OBS_DIM, ACT_DIM = 7, 7  # ContinuousActionVecMockEnv


def _linear_disc(weight, bias=0.0):
    """logit = weight @ [obs, act] + bias, no observation normalisation (obs 1-d, act 1-d)."""
    disc = Discriminator(1, 1, num_cells=(), normalize_observations=False)
    with torch.no_grad():
        disc.net.mlp[0].weight.copy_(torch.tensor([weight]))
        disc.net.mlp[0].bias.fill_(bias)
    return disc


def _transitions(n, obs_dim=3, act_dim=1):
    return TensorDict(
        observation=torch.randn(n, obs_dim),
        action=torch.rand(n, act_dim) * 2 - 1,
        next=TensorDict(
            observation=torch.randn(n, obs_dim),
            reward=torch.arange(n, dtype=torch.float32).unsqueeze(-1),
            batch_size=[n],
        ),
        batch_size=[n],
    )


def _softplus_logit(disc, td):
    return F.softplus(disc.net(td["observation"], td["action"])).detach()


def _mock_env(out_key="imitation_reward"):
    disc = Discriminator(OBS_DIM, ACT_DIM, num_cells=(8,))
    return TransformedEnv(ContinuousActionVecMockEnv(), DiscriminatorReward(disc, out_key=out_key))


class TestDiscriminatorReward:
    @pytest.mark.parametrize("out_key", ["reward", "imitation_reward"])
    def test_single_trans_env_check(self, out_key):
        env = _mock_env(out_key)
        check_env_specs(env)
        assert out_key in env.reward_keys
        assert env.full_reward_spec[out_key].shape == (1,)
        if out_key != "reward":
            assert "reward" in env.reward_keys

    def test_serial_trans_env_check(self):
        check_env_specs(SerialEnv(2, _mock_env))

    def test_parallel_trans_env_check(self):
        env = ParallelEnv(2, _mock_env, mp_start_method="fork")
        try:
            check_env_specs(env)
        finally:
            env.close()

    def test_trans_serial_env_check(self):
        disc = Discriminator(OBS_DIM, ACT_DIM, num_cells=(8,))
        env = TransformedEnv(
            SerialEnv(2, ContinuousActionVecMockEnv),
            DiscriminatorReward(disc, out_key="imitation_reward"),
        )
        check_env_specs(env)
        td = env.rollout(3)
        assert td["next", "imitation_reward"].shape == (2, 3, 1)
        torch.testing.assert_close(td["next", "imitation_reward"], _softplus_logit(disc, td))

    def test_transform_no_env(self):
        # reward = softplus(logit) = -log(1 - D), by hand
        logits = torch.tensor([-20.0, -1.0, 0.0, 1.0, 5.0, 30.0, 200.0])
        td = TensorDict(observation=logits.unsqueeze(-1), action=torch.zeros(7, 1), batch_size=[7])
        out = DiscriminatorReward(_linear_disc([1.0, 0.0]))(td)
        r = out["next", "reward"]
        assert r.shape == (7, 1)
        expected = [math.log1p(math.exp(z)) for z in logits.tolist()]
        assert r.squeeze(-1).tolist() == pytest.approx(expected, rel=1e-6, abs=1e-12)
        assert r[2].item() == pytest.approx(math.log(2.0))  # D = 0.5
        # -log(1 - D) itself overflows where softplus stays finite (no 18.42 cap)
        naive = -torch.log(1 - torch.sigmoid(logits))
        assert torch.isinf(naive[-1]) and r[-1].item() == pytest.approx(200.0)
        finite = torch.isfinite(naive)
        assert finite.sum() == 5  # logits -20 .. 5
        torch.testing.assert_close(r.squeeze(-1)[finite], naive[finite], atol=1e-5, rtol=1e-5)

    def test_transform_compose(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = _transitions(6)
        out = Compose(DiscriminatorReward(disc))(td.clone())
        assert torch.equal(out["next", "reward"], _softplus_logit(disc, td))

    def test_transform_env(self):
        env = _mock_env("reward")
        disc = env.transform.discriminator
        td = env.rollout(4)
        torch.testing.assert_close(td["next", "reward"], _softplus_logit(disc, td))
        assert not td["next", "reward"].requires_grad
        assert "d_logit" not in td.keys(True)

    @pytest.mark.parametrize("rbclass", [ReplayBuffer, TensorDictReplayBuffer])
    def test_transform_rb(self, rbclass):
        disc = Discriminator(3, 1, num_cells=(16,))
        disc.train()
        data = _transitions(10)
        rb = rbclass(
            storage=LazyTensorStorage(10),
            sampler=SamplerWithoutReplacement(shuffle=False),
            batch_size=10,
        )
        rb.extend(data)
        t = DiscriminatorReward(disc)
        rb.append_transform(t)
        # append_transform called t.eval(): the transform is in eval mode, D is not
        assert not t.training
        assert disc.training and disc.net.training
        s1 = rb.sample()
        torch.testing.assert_close(s1["next", "reward"], _softplus_logit(disc, data))
        # rewards are recomputed with the current discriminator at every sample
        with torch.no_grad():
            disc.net.mlp[-1].bias.add_(1.5)
        s2 = rb.sample()
        assert (s2["next", "reward"] > s1["next", "reward"]).all()
        torch.testing.assert_close(s2["next", "reward"], _softplus_logit(disc, data))

    def test_transform_inverse(self):
        # no inverse: the storage never receives the imitation reward or the logit
        data = _transitions(10)
        rb = TensorDictReplayBuffer(storage=LazyTensorStorage(10), batch_size=4)
        rb.append_transform(DiscriminatorReward(Discriminator(3, 1, num_cells=(8,)), keep_logit=True))
        rb.extend(data)
        rb.sample()
        stored = rb.storage[:]
        assert torch.equal(stored["next", "reward"], data["next", "reward"])
        assert "d_logit" not in stored.keys()

    def test_equals_softplus_of_logit(self):
        disc = Discriminator(3, 1, num_cells=(16, 16))
        disc.net.obs_norm.update(torch.randn(50, 3) * 2)
        td = _transitions(12)
        out = DiscriminatorReward(disc, keep_logit=True)(td.clone())
        logit = disc.net(td["observation"], td["action"])
        assert torch.equal(out["d_logit"], logit.detach())
        assert torch.equal(out["next", "reward"], F.softplus(logit).detach())
        p = torch.sigmoid(logit)
        torch.testing.assert_close(out["next", "reward"], -torch.log(1 - p).detach(), atol=1e-5, rtol=1e-5)

    def test_kinds_coef_and_mode_against_hand_values(self):
        # logit = 2 * obs - 1 * act + 0.5: obs 1, act 0.5 -> 2.0; obs -1, act 0 -> -1.5
        disc = _linear_disc([2.0, -1.0], bias=0.5)
        td = TensorDict(
            observation=torch.tensor([[1.0], [-1.0]]),
            action=torch.tensor([[0.5], [0.0]]),
            next=TensorDict(reward=torch.tensor([[10.0], [20.0]]), batch_size=[2]),
            batch_size=[2],
        )
        logit = torch.tensor([[2.0], [-1.5]])
        gail = DiscriminatorReward(disc)(td.clone())["next", "reward"]
        torch.testing.assert_close(gail, torch.log1p(torch.exp(logit)))  # -log(1 - sigmoid)
        airl = DiscriminatorReward(disc, kind="airl")(td.clone())["next", "reward"]
        p = torch.sigmoid(logit)
        torch.testing.assert_close(airl, torch.log(p) - torch.log(1 - p))
        shaped = DiscriminatorReward(disc, coef=0.1, mode="add")(td.clone())["next", "reward"]
        torch.testing.assert_close(shaped, torch.tensor([[10.0], [20.0]]) + 0.1 * torch.log1p(torch.exp(logit)))
        scaled = DiscriminatorReward(disc, kind="airl", coef=0.5)(td.clone())["next", "reward"]
        torch.testing.assert_close(scaled, 0.5 * logit)

    def test_clip_against_hand_values(self):
        # logit = obs: D = sigmoid(6) = 0.9975 -> 0.99, sigmoid(-6) = 0.0025 -> 0.01, sigmoid(0) = 0.5 kept
        disc = _linear_disc([1.0, 0.0])
        td = TensorDict(
            observation=torch.tensor([[6.0], [-6.0], [0.0]]),
            action=torch.zeros(3, 1),
            next=TensorDict(reward=torch.zeros(3, 1), batch_size=[3]),
            batch_size=[3],
        )
        gail = DiscriminatorReward(disc, clip=(0.01, 0.99))(td.clone())["next", "reward"]
        torch.testing.assert_close(gail, torch.tensor([[-math.log(0.01)], [-math.log(0.99)], [math.log(2.0)]]))
        airl = DiscriminatorReward(disc, kind="airl", clip=(0.01, 0.99))(td.clone())["next", "reward"]
        torch.testing.assert_close(airl, torch.tensor([[math.log(99.0)], [-math.log(99.0)], [0.0]]))

    def test_shift_against_hand_values(self):
        # logit = obs: 6 -> clamped to log 99, -6 -> -log 99, 0 kept; shift log 99 floors the logit at 0
        disc = _linear_disc([1.0, 0.0])
        td = TensorDict(
            observation=torch.tensor([[6.0], [-6.0], [0.0], [-1.0]]),
            action=torch.zeros(4, 1),
            next=TensorDict(reward=torch.full((4, 1), 3.0), batch_size=[4]),
            batch_size=[4],
        )
        floored = DiscriminatorReward(disc, kind="airl", clip=(0.01, 0.99), shift=math.log(99.0))
        expected = torch.tensor([[2 * math.log(99.0)], [0.0], [math.log(99.0)], [math.log(99.0) - 1.0]])
        torch.testing.assert_close(floored(td.clone())["next", "reward"], expected)
        # the shift comes before coef, and mode="add" adds the whole to the reward already there
        scaled = DiscriminatorReward(disc, kind="airl", shift=2.0, coef=0.5, mode="add")(td.clone())
        logit = torch.tensor([[6.0], [-6.0], [0.0], [-1.0]])
        torch.testing.assert_close(scaled["next", "reward"], 3.0 + 0.5 * (logit + 2.0))
        gail = DiscriminatorReward(disc, shift=-1.0)(td.clone())["next", "reward"]
        torch.testing.assert_close(gail, F.softplus(td["observation"]) - 1.0)

    def test_add_mode_in_an_env_adds_to_the_env_reward(self):
        disc = Discriminator(OBS_DIM, ACT_DIM, num_cells=(8,))
        plain = ContinuousActionVecMockEnv()
        plain.set_seed(0)
        dense = plain.rollout(3)["next", "reward"]
        env = TransformedEnv(ContinuousActionVecMockEnv(), DiscriminatorReward(disc, coef=2.0, mode="add"))
        env.set_seed(0)
        rollout = env.rollout(3)
        bonus = 2.0 * F.softplus(disc.net(rollout["observation"], rollout["action"])).detach()
        torch.testing.assert_close(rollout["next", "reward"], dense + bonus)

    @pytest.mark.parametrize(
        "kwargs, message",
        [
            ({"kind": "wgan"}, "kind must be"),
            ({"mode": "mix"}, "mode must be"),
            ({"clip": (0.0, 0.99)}, "clip must be"),
            ({"clip": (0.9, 0.1)}, "clip must be"),
            ({"shift": math.inf}, "shift must be finite"),
        ],
    )
    def test_bad_kind_or_mode(self, kwargs, message):
        with pytest.raises(ValueError, match=message):
            DiscriminatorReward(Discriminator(3, 1, num_cells=(4,)), **kwargs)

    def test_no_gradients(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = _transitions(5)
        td["observation"].requires_grad_(True)
        out = DiscriminatorReward(disc, keep_logit=True)(td)
        assert not out["next", "reward"].requires_grad
        assert not out["d_logit"].requires_grad
        assert all(p.grad is None for p in disc.parameters())

    def test_keys(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = _transitions(5)
        env_reward = td["next", "reward"].clone()
        obs = td["observation"].clone()
        out = DiscriminatorReward(disc, out_key="imitation_reward")(td)
        assert "d_logit" not in out.keys()
        torch.testing.assert_close(out["next", "reward"], env_reward)
        torch.testing.assert_close(out["observation"], obs)
        expected = _softplus_logit(disc, out)
        torch.testing.assert_close(out["next", "imitation_reward"], expected)
        nested = DiscriminatorReward(disc, out_key=("sail", "r"))(td)
        torch.testing.assert_close(nested["next", "sail", "r"], expected)

    def test_time_batch(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = TensorDict(
            observation=torch.randn(2, 6, 3),
            action=torch.rand(2, 6, 1),
            batch_size=[2, 6],
        )
        out = DiscriminatorReward(disc)(td)
        assert out["next", "reward"].shape == (2, 6, 1)
        torch.testing.assert_close(out["next", "reward"], _softplus_logit(disc, td))
        # every (batch, time) entry is a separate transition: row by row gives the same
        row = F.softplus(disc.net(td["observation"][1, 4], td["action"][1, 4])).detach()
        torch.testing.assert_close(out["next", "reward"][1, 4], row)

    def test_chunked_equals_whole(self):
        # a block larger than chunk_size is evaluated in chunks: the same rewards, any shape
        disc = Discriminator(3, 1, num_cells=(8,))
        disc.net.obs_norm.update(torch.randn(50, 3))
        td = TensorDict(observation=torch.randn(4, 5, 3), action=torch.rand(4, 5, 1), batch_size=[4, 5])
        chunked = DiscriminatorReward(disc, chunk_size=3)(td.clone())["next", "reward"]
        whole = DiscriminatorReward(disc)(td.clone())["next", "reward"]
        assert chunked.shape == (4, 5, 1)
        torch.testing.assert_close(chunked, whole)
        torch.testing.assert_close(whole, _softplus_logit(disc, td))
        with pytest.raises(ValueError, match="chunk_size must be >= 1"):
            DiscriminatorReward(disc, chunk_size=0)

    def test_row_ids_evaluate_each_distinct_row_once(self):
        # 4 stored rows drawn 12 times: D sees 4 rows, every draw gets its row's reward
        disc = Discriminator(3, 1, num_cells=(8,))
        disc.net.obs_norm.update(torch.randn(50, 3))
        stored = _transitions(4)
        ids = torch.tensor([[2, 0, 2], [3, 3, 0], [1, 2, 2], [0, 0, 3]])
        block = stored[ids]  # [4, 3]
        block["row_id"] = ids
        seen = []
        hook = disc.net.register_forward_hook(lambda m, args, out: seen.append(args[0].shape[0]))
        logit_key = disc.out_keys[0]
        out = DiscriminatorReward(disc, row_id_key="row_id", keep_logit=True, chunk_size=3)(block.clone())
        hook.remove()
        assert sum(seen) == 4
        expected = _softplus_logit(disc, stored)[ids]
        torch.testing.assert_close(out["next", "reward"], expected)
        torch.testing.assert_close(F.softplus(out[logit_key]), expected)
        # the same rewards as evaluating every row
        torch.testing.assert_close(out["next", "reward"], DiscriminatorReward(disc)(block.clone())["next", "reward"])

    def test_row_id_key_absent_or_all_distinct_evaluates_every_row(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = _transitions(5)
        seen = []
        hook = disc.net.register_forward_hook(lambda m, args, out: seen.append(args[0].shape[0]))
        t = DiscriminatorReward(disc, row_id_key="row_id")
        no_ids = t(td.clone())["next", "reward"]
        td["row_id"] = torch.arange(5)
        distinct = t(td.clone())["next", "reward"]
        hook.remove()
        assert seen == [5, 5]
        torch.testing.assert_close(no_ids, _softplus_logit(disc, td))
        torch.testing.assert_close(distinct, no_ids)

    def test_reward_keeps_discriminator_dtype_under_autocast(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        td = _transitions(6)
        with torch.autocast("cpu", dtype=torch.bfloat16):
            reward = DiscriminatorReward(disc)(td.clone())["next", "reward"]
        assert reward.dtype == torch.float32
        torch.testing.assert_close(reward, _softplus_logit(disc, td), rtol=0.02, atol=0.02)

    def test_mode_of_discriminator_untouched(self):
        disc = Discriminator(3, 1, num_cells=(8,))
        disc.eval()
        t = DiscriminatorReward(disc)
        t.train()
        assert t.training and not disc.training
        t.eval()
        disc.train()
        Compose(t).eval()
        assert disc.training
        env = TransformedEnv(ContinuousActionVecMockEnv(), DiscriminatorReward(disc))
        env.eval()
        assert disc.training

    def test_shared_with_loss(self):
        # the loss trains the very module the transform reads
        disc = Discriminator(3, 1, num_cells=(8,))
        loss_fn = DiscriminatorLoss(disc)
        t = DiscriminatorReward(disc)
        td = _transitions(8)
        td["is_teacher"] = torch.arange(8) < 4
        r0 = t(td.clone())["next", "reward"]
        optim = torch.optim.Adam(disc.parameters(), lr=1e-2)
        out = loss_fn(td)
        (out["loss_discriminator"] + out["loss_entropy"] + out["loss_gradient_penalty"]).backward()
        optim.step()
        r1 = t(td.clone())["next", "reward"]
        assert not torch.allclose(r0, r1)
        assert t.clone().discriminator is disc

    def test_reward_spec_dtype_follows_discriminator(self):
        env = TransformedEnv(
            ContinuousActionVecMockEnv(dtype=torch.float64),
            DiscriminatorReward(
                Discriminator(OBS_DIM, ACT_DIM, num_cells=(8,)).double(),
                out_key="imitation_reward",
            ),
        )
        assert env.full_reward_spec["imitation_reward"].dtype == torch.float64
        check_env_specs(env)
        assert env.rollout(2)["next", "imitation_reward"].dtype == torch.float64
        assert _mock_env().full_reward_spec["imitation_reward"].dtype == torch.float32


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
