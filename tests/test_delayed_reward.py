"""Tests for :class:`torchrl_sail.envs.delayed_reward.DelayedRewardTransform`."""

from __future__ import annotations

import argparse
import math
from functools import partial

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import (
    Bounded,
    Composite,
    LazyTensorStorage,
    ReplayBuffer,
    TensorDictReplayBuffer,
    Unbounded,
)
from torchrl.data.replay_buffers.samplers import SamplerWithoutReplacement
from torchrl.envs import (
    Compose,
    DoubleToFloat,
    EnvBase,
    GymEnv,
    ParallelEnv,
    RewardSum,
    SerialEnv,
    StepCounter,
    TransformedEnv,
)
from torchrl.envs.utils import check_env_specs

from torchrl_sail import DelayedRewardTransform, TimeFeature

# The paper's tasks are the -v4 MuJoCo envs (same observation layout as the teachers' -v2).
pytestmark = pytest.mark.filterwarnings("ignore:.*Hopper-v4 is out of date:DeprecationWarning")


class ListRewardEnv(EnvBase):
    """Deterministic env whose k-th step of every episode (k = 1..L) pays ``rewards[k-1]``.

    The episode terminates after ``L = len(rewards)`` steps; the observation is the
    in-episode step index, so dense returns can be computed by hand.
    """

    def __init__(self, rewards):
        super().__init__(batch_size=torch.Size([]))
        self.rewards = torch.tensor(rewards, dtype=torch.float32)
        self.observation_spec = Composite(observation=Unbounded(shape=(1,), dtype=torch.float32))
        self.action_spec = Bounded(-1.0, 1.0, shape=(1,))
        self.reward_spec = Unbounded(shape=(1,), dtype=torch.float32)
        self.count = 0

    def _reset(self, tensordict):
        self.count = 0
        return TensorDict(
            observation=torch.zeros(1),
            done=torch.zeros(1, dtype=torch.bool),
            terminated=torch.zeros(1, dtype=torch.bool),
        )

    def _step(self, tensordict):
        self.count += 1
        terminated = torch.tensor([self.count == len(self.rewards)])
        return TensorDict(
            observation=torch.full((1,), float(self.count)),
            reward=self.rewards[self.count - 1].reshape(1).clone(),
            done=terminated.clone(),
            terminated=terminated,
        )

    def _set_seed(self, seed):
        return seed


def offset_rewards(length: int, offset: float) -> list[float]:
    """reward_t = t + offset for t = 1..length."""
    return [t + offset for t in range(1, length + 1)]


# Three sub-envs with different episode lengths (3, 5, 4) so that resets are partial.
#   env 0: 3, 4, 5                 -> R = 12    -> floor(1.2)  = 1
#   env 1: 2.5, 3.5, 4.5, 5.5, 6.5 -> R = 22.5  -> floor(2.25) = 2
#   env 2: -9.5, -8.5, -7.5, -6.5  -> R = -32   -> floor(-3.2) = -4
EPISODES = [offset_rewards(3, 2.0), offset_rewards(5, 1.5), offset_rewards(4, -10.5)]
RUNNING = [[3.0, 7.0, 12.0], [2.5, 6.0, 10.5, 16.0, 22.5], [-9.5, -18.0, -25.5, -32.0]]
STEPS = 14


def make_serial(episodes=EPISODES):
    return SerialEnv(len(episodes), [partial(ListRewardEnv, r) for r in episodes])


def make_transformed_list_env(rewards):
    return TransformedEnv(ListRewardEnv(rewards), DelayedRewardTransform())


# one worker per episode length: 3 (R = 12 -> 1) and 4 (R = -32 -> -4)
WORKERS = [
    partial(make_transformed_list_env, EPISODES[0]),
    partial(make_transformed_list_env, EPISODES[2]),
]


def tile(values, n):
    return [values[i % len(values)] for i in range(n)]


def expected(running, steps, value_at_done):
    """Per-step delayed rewards and running returns of a periodic episode."""
    ret = tile(running, steps)
    rew = [value_at_done(running[-1]) if (i + 1) % len(running) == 0 else 0.0 for i in range(steps)]
    return torch.tensor(rew), torch.tensor(ret, dtype=torch.float64)


def zero_policy(td):
    return td.set("action", torch.zeros(*td.batch_size, 1))


def check_worker_rollout(env):
    """check_env_specs plus the hand-computed rewards of the two WORKERS."""
    check_env_specs(env)
    td = env.rollout(8, zero_policy, break_when_any_done=False)
    assert td["next", "reward"][..., 0].tolist() == [
        [0, 0, 1, 0, 0, 1, 0, 0],
        [0, 0, 0, -4, 0, 0, 0, -4],
    ]
    assert td["next", "episode_return"][0, :, 0].tolist() == tile(RUNNING[0], 8)


def dense_and_online(**kwargs):
    """The same deterministic rollout, dense and through the transform in the env."""
    dense = make_serial().rollout(STEPS, zero_policy, break_when_any_done=False)
    env = TransformedEnv(make_serial(), DelayedRewardTransform(**kwargs))
    online = env.rollout(STEPS, zero_policy, break_when_any_done=False)
    return dense, online


class TestDelayedRewardTransform:
    def test_single_trans_env_check(self):
        check_env_specs(make_transformed_list_env([1.0, 2.0]))

    def test_serial_trans_env_check(self):
        check_worker_rollout(SerialEnv(2, WORKERS))

    def test_parallel_trans_env_check(self):
        # the running return is tensordict state, so it works inside the workers
        env = ParallelEnv(2, WORKERS, mp_start_method="fork")
        try:
            check_worker_rollout(env)
        finally:
            env.close()

    def test_trans_serial_env_check(self):
        env = TransformedEnv(make_serial(), DelayedRewardTransform())
        check_env_specs(env)
        assert env.observation_spec["episode_return"].dtype == torch.float64
        assert env.observation_spec["episode_return"].shape == (3, 1)
        assert "episode_return" in env.full_state_spec.keys()
        assert env.full_reward_spec["reward"].dtype == torch.float32

    def test_transform_no_env(self):
        # 1D trajectory: episode [1.5, -3.7] ends, then -2, -30.5 ends, then 7 without done
        reward = torch.tensor([1.5, -3.7, -2.0, -30.5, 7.0]).unsqueeze(-1)
        done = torch.tensor([False, True, False, True, False]).unsqueeze(-1)
        td = TensorDict(next=TensorDict(reward=reward, done=done, batch_size=[5]), batch_size=[5])
        DelayedRewardTransform()(td)
        r1 = float(torch.tensor(1.5, dtype=torch.float64) + torch.tensor(-3.7).double())
        # floor(0.1 * -2.2) = -1, floor(0.1 * -32.5) = floor(-3.25) = -4, trailing: 0
        assert td["next", "reward"][:, 0].tolist() == [0.0, -1.0, 0.0, -4.0, 0.0]
        assert td["next", "episode_return"][:, 0].tolist() == [1.5, r1, -2.0, -32.5, 7.0]

    def test_transform_compose(self):
        dense, online = dense_and_online()
        out = Compose(DelayedRewardTransform())(dense.clone())
        assert torch.equal(out["next", "reward"], online["next", "reward"])
        assert torch.equal(out["next", "episode_return"], online["next", "episode_return"])

    @pytest.mark.parametrize(
        "kwargs, value_at_done",
        [
            ({}, lambda R: float(math.floor(0.1 * R))),
            ({"scale": 0.5, "rounding": "none"}, lambda R: 0.5 * R),
            ({"scale": 0.25}, lambda R: float(math.floor(0.25 * R))),
        ],
    )
    def test_transform_env(self, kwargs, value_at_done):
        # partial resets: the three sub-envs end their episodes at different steps
        env = TransformedEnv(make_serial(), DelayedRewardTransform(**kwargs))
        td = env.rollout(STEPS, zero_policy, break_when_any_done=False)
        assert td.batch_size == (3, STEPS)
        # 0.5 scale, no rounding: 6.0, 11.25, -16.0; 0.25 floor: 3, 5, -8
        for i, running in enumerate(RUNNING):
            rew, ret = expected(running, STEPS, value_at_done)
            torch.testing.assert_close(td["next", "reward"][i, :, 0], rew, rtol=0, atol=0)
            torch.testing.assert_close(td["next", "episode_return"][i, :, 0], ret, rtol=0, atol=0)
            # the state carried at the root is the return before the step (0 after reset)
            root = torch.tensor(tile([0.0] + running[:-1], STEPS), dtype=torch.float64)
            torch.testing.assert_close(td["episode_return"][i, :, 0], root, rtol=0, atol=0)
        assert td["next", "reward"].dtype == torch.float32
        assert td["next", "episode_return"].dtype == torch.float64

    @pytest.mark.parametrize("rbclass", [ReplayBuffer, TensorDictReplayBuffer])
    def test_transform_rb(self, rbclass):
        # one storage slot per trajectory, so every sampled row is a whole trajectory
        dense, online = dense_and_online()
        rb = rbclass(
            storage=LazyTensorStorage(3),
            sampler=SamplerWithoutReplacement(shuffle=False),
            batch_size=3,
        )
        rb.append_transform(DelayedRewardTransform())
        rb.extend(dense)
        sample = rb.sample()
        assert torch.equal(sample["next", "reward"], online["next", "reward"])
        assert torch.equal(sample["next", "episode_return"], online["next", "episode_return"])

    def test_transform_inverse(self):
        # no inverse: data written into a buffer keep their dense rewards
        dense, _ = dense_and_online()
        rb = ReplayBuffer(storage=LazyTensorStorage(3))
        rb.append_transform(DelayedRewardTransform())
        rb.extend(dense.clone())
        stored = rb.storage[:]
        assert torch.equal(stored["next", "reward"], dense["next", "reward"])
        assert "episode_return" not in stored["next"].keys()

    def test_hand_computed_episode_sums(self):
        for rewards, running in zip(EPISODES, RUNNING, strict=True):
            assert sum(rewards) == running[-1]
        assert [math.floor(0.1 * r[-1]) for r in RUNNING] == [1, 2, -4]

    def test_default_values_by_hand(self):
        env = TransformedEnv(make_serial(), DelayedRewardTransform())
        td = env.rollout(6, zero_policy, break_when_any_done=False)
        rew = td["next", "reward"][..., 0]
        assert rew.tolist() == [
            [0, 0, 1, 0, 0, 1],
            [0, 0, 0, 0, 2, 0],
            [0, 0, 0, -4, 0, 0],
        ]
        assert td["next", "episode_return"][2, :, 0].tolist() == [
            -9.5,
            -18.0,
            -25.5,
            -32.0,
            -9.5,
            -18.0,
        ]

    def test_scale_snaps_binary_error(self):
        # 0.7 * 90 == 62.99999999999999 in float64: a naive floor would pay 62, not 63.
        assert math.floor(0.7 * 90.0) == 62
        env = TransformedEnv(ListRewardEnv([40.0, 50.0]), DelayedRewardTransform(0.7))
        td = env.rollout(2, zero_policy)
        assert td["next", "reward"][:, 0].tolist() == [0, 63]

    def test_truncation_releases_reward(self):
        # episodes of 6 steps cut at 4 by StepCounter: done = truncated, R = 1+2+3+4 = 10
        env = TransformedEnv(
            ListRewardEnv([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            Compose(StepCounter(max_steps=4), DelayedRewardTransform(rounding="none")),
        )
        td = env.rollout(8, zero_policy, break_when_any_done=False)
        assert td["next", "truncated"][:, 0].tolist() == [False, False, False, True] * 2
        assert td["next", "reward"][:, 0].tolist() == [0, 0, 0, 1.0] * 2
        assert td["next", "episode_return"][:, 0].tolist() == [1.0, 3.0, 6.0, 10.0] * 2

    def test_recommended_stack_with_dense_reward_sum(self):
        # the class docstring's stack, verbatim: DoubleToFloat -> StepCounter -> RewardSum
        # (explicit in_keys, torchrl 0.14.1 needs them with out_keys) -> DelayedRewardTransform
        env = TransformedEnv(
            ListRewardEnv([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            Compose(
                DoubleToFloat(),
                StepCounter(max_steps=4),
                RewardSum(in_keys=["reward"], out_keys=["dense_return"]),
                DelayedRewardTransform(rounding="none"),
            ),
        )
        check_env_specs(env)
        td = env.rollout(8, zero_policy, break_when_any_done=False)
        # episodes cut at 4 steps: dense 1, 2, 3, 4 -> R = 10, delayed 0.1 * 10 = 1
        assert td["next", "dense_return"][:, 0].tolist() == [1.0, 3.0, 6.0, 10.0] * 2
        assert td["next", "episode_return"][:, 0].tolist() == [1.0, 3.0, 6.0, 10.0] * 2
        assert td["next", "reward"][:, 0].tolist() == [0, 0, 0, 1.0] * 2

    def test_reset_zeroes_only_flagged_sub_envs(self):
        # called directly: inside an env, TorchRL masks the non-reset rows anyway, which
        # would hide a _reset that zeroes every sub-env
        t = DelayedRewardTransform(reset_keys=["_reset"])
        running = torch.tensor([[3.5], [7.0], [-2.0]], dtype=torch.float64)
        td = TensorDict(
            episode_return=running.clone(),
            _reset=torch.tensor([[True], [False], [True]]),
            batch_size=[3],
        )
        out = t._reset(td, TensorDict(batch_size=[3]))
        assert out["episode_return"][:, 0].tolist() == [0.0, 7.0, 0.0]
        assert out["episode_return"].dtype == torch.float64
        # no "_reset" entry means a full reset
        td = TensorDict(episode_return=running.clone(), batch_size=[3])
        out = t._reset(td, TensorDict(batch_size=[3]))
        assert out["episode_return"][:, 0].tolist() == [0.0, 0.0, 0.0]
        # through a batched env: the partial reset keeps sub-env 1 counting
        env = TransformedEnv(make_serial(), DelayedRewardTransform())
        td = env.rollout(2, zero_policy, break_when_any_done=False)
        state = td[:, -1]["next"].exclude("reward", "done", "terminated")
        state["_reset"] = torch.tensor([[True], [False], [False]])
        out = env.reset(state)
        assert out["episode_return"][:, 0].tolist() == [0.0, 6.0, -18.0]

    @pytest.mark.parametrize("rounding", ["floor", "none"])
    def test_offline_forward_matches_env(self, rounding):
        dense, online = dense_and_online(rounding=rounding)
        assert dense.names[-1] == "time"
        # the dense rewards are still there before the transform
        assert dense["next", "reward"][0, :3, 0].tolist() == [3.0, 4.0, 5.0]
        offline = DelayedRewardTransform(rounding=rounding)(dense.clone())
        assert torch.equal(offline["next", "reward"], online["next", "reward"])
        assert torch.equal(offline["next", "episode_return"], online["next", "episode_return"])
        # time dim not named: the last batch dim is used, [T, N] needs the name
        unnamed = dense.clone()
        unnamed.names = None
        out = DelayedRewardTransform(rounding=rounding)(unnamed)
        assert torch.equal(out["next", "reward"], online["next", "reward"])
        transposed = dense.clone().transpose(0, 1)
        assert transposed.names == ["time", None]
        out = DelayedRewardTransform(rounding=rounding)(transposed)
        assert torch.equal(out["next", "reward"], online["next", "reward"].transpose(0, 1))

    def test_float32_precision(self):
        rewards = [0.1] * 1000
        r32 = torch.tensor(rewards, dtype=torch.float32)
        reference = r32.double().sum().item()  # 100.0000014901...
        assert 100.0 < reference < 100.00001
        # a float32 accumulator lands below 100 and would pay 9 instead of 10
        acc = torch.zeros((), dtype=torch.float32)
        for r in r32:
            acc = acc + r
        assert acc.item() < 100.0
        env = TransformedEnv(ListRewardEnv(rewards), DelayedRewardTransform())
        td = env.rollout(1000, zero_policy)
        assert td["next", "done"][-1].item()
        assert td["next", "reward"][-1].item() == 10.0
        assert (td["next", "reward"][:-1] == 0).all()
        assert td["next", "episode_return"][-1].item() == pytest.approx(reference, abs=1e-9)
        assert math.floor(0.1 * td["next", "episode_return"][-1].item()) == 10
        dense = TensorDict(
            next=TensorDict(reward=r32.unsqueeze(-1), done=td["next", "done"].clone(), batch_size=[1000]),
            batch_size=[1000],
        )
        out = DelayedRewardTransform()(dense)
        assert torch.equal(out["next", "reward"], td["next", "reward"])
        assert torch.equal(out["next", "episode_return"], td["next", "episode_return"])

    def test_hopper_compose_with_time_feature(self):
        # the SAIL env stack: delayed reward after DoubleToFloat and after the done-setting
        # StepCounter; a RewardSum before it keeps the (float32) dense return for comparison
        env = TransformedEnv(
            GymEnv("Hopper-v4"),
            Compose(
                DoubleToFloat(),
                StepCounter(max_steps=20),
                TimeFeature(max_steps=1000),
                RewardSum(in_keys=["reward"], out_keys=["dense_return"]),
                DelayedRewardTransform(),
            ),
        )
        try:
            check_env_specs(env)
            env.set_seed(0)
            td = env.rollout(40, break_when_any_done=False)
        finally:
            env.close()
        assert env.observation_spec["observation"].shape == (12,)
        done = td["next", "done"][:, 0]
        assert done.sum() >= 2
        dense = td["next", "dense_return"][:, 0]
        ret = td["next", "episode_return"][:, 0]
        torch.testing.assert_close(ret.float(), dense, rtol=1e-6, atol=1e-4)
        reward = td["next", "reward"][:, 0]
        assert (reward[~done] == 0).all()
        torch.testing.assert_close(reward[done], torch.floor(0.1 * ret[done]).float())
        assert (reward[done] != 0).any()  # Hopper pays ~1 per step: R > 10 in 20 steps

    def test_custom_keys(self):
        env = TransformedEnv(
            ListRewardEnv([2.0, 3.0]),
            DelayedRewardTransform(scale=1.0, return_key=("logs", "ret")),
        )
        check_env_specs(env)
        td = env.rollout(2, zero_policy)
        assert td["next", "reward"][:, 0].tolist() == [0.0, 5.0]
        assert td["next", "logs", "ret"][:, 0].tolist() == [2.0, 5.0]

    def test_bad_arguments(self):
        with pytest.raises(ValueError, match="rounding"):
            DelayedRewardTransform(rounding="round")
        with pytest.raises(ValueError, match="scale"):
            DelayedRewardTransform(scale=0.0)
        with pytest.raises(ValueError, match="return_key"):
            DelayedRewardTransform(return_key="reward")


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
