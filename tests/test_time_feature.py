"""Tests for :class:`torchrl_sail.envs.time_feature.TimeFeature`."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.data import (
    Bounded,
    Categorical,
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
    SerialEnv,
    StepCounter,
    TransformedEnv,
)
from torchrl.envs.utils import check_env_specs

from torchrl_sail import TimeFeature

# The paper's tasks are the -v4 MuJoCo envs (obs layout of the teachers' -v2 envs).
pytestmark = pytest.mark.filterwarnings("ignore:.*Hopper-v4 is out of date:DeprecationWarning")


def f32(x: float) -> float:
    """The float32 value closest to ``x`` (how 1 - t/T is stored in the teacher data)."""
    return torch.tensor(x, dtype=torch.float32).item()


def zero_policy(td):
    return td.set("action", torch.zeros(*td.batch_size, 3))


class BoundedObsEnv(EnvBase):
    """Two-dim observation in [-2, 3] x [0, 5]; steps add 1 to the first column."""

    def __init__(self):
        super().__init__(batch_size=torch.Size([]))
        self.observation_spec = Composite(
            observation=Bounded(low=torch.tensor([-2.0, 0.0]), high=torch.tensor([3.0, 5.0]), shape=(2,))
        )
        self.action_spec = Bounded(-1.0, 1.0, shape=(1,))
        self.reward_spec = Unbounded(shape=(1,))
        self.obs = torch.zeros(2)

    def _reset(self, tensordict):
        self.obs = torch.tensor([-2.0, 1.0])
        return TensorDict(
            observation=self.obs.clone(),
            done=torch.zeros(1, dtype=torch.bool),
            terminated=torch.zeros(1, dtype=torch.bool),
        )

    def _step(self, tensordict):
        self.obs = self.obs + torch.tensor([1.0, 0.0])
        terminated = torch.tensor([bool(self.obs[0] >= 3.0)])
        return TensorDict(
            observation=self.obs.clone(),
            reward=torch.zeros(1),
            done=terminated.clone(),
            terminated=terminated,
        )

    def _set_seed(self, seed):
        return seed


def make_env():
    return TransformedEnv(BoundedObsEnv(), Compose(StepCounter(), TimeFeature(max_steps=4)))


def transitions():
    """Three transitions at steps 0, 7 and 999 of a T = 1000 episode."""
    return TensorDict(
        observation=torch.tensor([[0.5, 1.0], [2.0, 3.0], [4.0, 5.0]]),
        step_count=torch.tensor([[0], [7], [999]]),
        next=TensorDict(
            observation=torch.tensor([[6.0, 7.0], [8.0, 9.0], [1.0, 2.0]]),
            step_count=torch.tensor([[1], [8], [1000]]),
            batch_size=[3],
        ),
        batch_size=[3],
    )


def check_transitions(td):
    assert td["observation"].tolist() == [
        [0.5, 1.0, 1.0],
        [2.0, 3.0, f32(0.993)],
        [4.0, 5.0, f32(0.001)],
    ]
    assert td["next", "observation"].tolist() == [
        [6.0, 7.0, f32(0.999)],
        [8.0, 9.0, f32(0.992)],
        [1.0, 2.0, 0.0],
    ]


@pytest.fixture(scope="module")
def hopper():
    env = TransformedEnv(
        GymEnv("Hopper-v4"),
        Compose(DoubleToFloat(), StepCounter(), TimeFeature(max_steps=1000)),
    )
    yield env
    env.close()


class TestTimeFeature:
    def test_single_trans_env_check(self):
        check_env_specs(make_env())

    def test_serial_trans_env_check(self):
        check_env_specs(SerialEnv(2, make_env))

    def test_parallel_trans_env_check(self):
        env = ParallelEnv(2, make_env, mp_start_method="fork")
        try:
            check_env_specs(env)
        finally:
            env.close()

    def test_trans_serial_env_check(self):
        env = TransformedEnv(SerialEnv(2, BoundedObsEnv), Compose(StepCounter(), TimeFeature(max_steps=4)))
        check_env_specs(env)
        assert env.observation_spec["observation"].shape == (2, 3)

    def test_transform_no_env(self):
        td = transitions()
        assert TimeFeature(max_steps=1000)(td) is td
        check_transitions(td)
        # out_keys leave the raw observation in place; float64 stays float64
        td64 = TensorDict(
            obs=torch.ones(2, 1, dtype=torch.float64),
            step_count=torch.tensor([[3], [4]]),
            batch_size=[2],
        )
        TimeFeature(max_steps=8, in_keys=["obs"], out_keys=["obs_t"])(td64)
        assert td64["obs"].shape == (2, 1)
        assert td64["obs_t"].dtype == torch.float64
        assert td64["obs_t"].tolist() == [[1.0, 0.625], [1.0, 0.5]]
        # an Unbounded spec stays Unbounded and keeps its dtype
        spec = Composite(
            observation=Unbounded(shape=(4, 2), dtype=torch.float64),
            step_count=Bounded(0, 10, shape=(4, 1), dtype=torch.int64),
            shape=(4,),
        )
        out = TimeFeature(max_steps=10).transform_observation_spec(spec.clone())
        assert isinstance(out["observation"], Unbounded)
        assert out["observation"].shape == (4, 3)
        assert out["observation"].dtype == torch.float64

    def test_transform_compose(self):
        td = Compose(TimeFeature(max_steps=1000))(transitions())
        check_transitions(td)

    def test_transform_env(self):
        env = make_env()
        spec = env.observation_spec["observation"]
        assert isinstance(spec, Bounded)
        assert spec.shape == (3,)
        assert spec.space.low.tolist() == [-2.0, 0.0, 0.0]
        assert spec.space.high.tolist() == [3.0, 5.0, 1.0]
        td = env.rollout(10)  # terminates after 5 steps
        assert td["observation"].tolist() == [
            [-2.0, 1.0, 1.0],
            [-1.0, 1.0, 0.75],
            [0.0, 1.0, 0.5],
            [1.0, 1.0, 0.25],
            [2.0, 1.0, 0.0],
        ]
        assert td["next", "observation"][-1].tolist() == [3.0, 1.0, -0.25]

    @pytest.mark.parametrize("rbclass", [ReplayBuffer, TensorDictReplayBuffer])
    def test_transform_rb(self, rbclass):
        rb = rbclass(
            storage=LazyTensorStorage(3),
            sampler=SamplerWithoutReplacement(shuffle=False),
            batch_size=3,
        )
        rb.append_transform(TimeFeature(max_steps=1000))
        rb.extend(transitions())
        check_transitions(rb.sample())

    def test_transform_inverse(self):
        # no inverse: data written into a buffer keep their raw observations
        rb = ReplayBuffer(storage=LazyTensorStorage(3))
        rb.append_transform(TimeFeature(max_steps=1000))
        rb.extend(transitions())
        stored = rb.storage[:]
        assert torch.equal(stored["observation"], transitions()["observation"])
        assert torch.equal(stored["next", "observation"], transitions()["next", "observation"])

    def test_hopper_reset_and_steps(self, hopper):
        check_env_specs(hopper)
        assert hopper.observation_spec["observation"].shape == (12,)
        assert hopper.observation_spec["observation"].dtype == torch.float32
        hopper.set_seed(0)
        td = hopper.reset()
        assert td["observation"].shape == (12,)
        assert td["observation"][-1].item() == 1.0
        rollout = hopper.rollout(25, zero_policy, auto_reset=False, tensordict=td)
        assert not rollout["next", "done"].any()  # standing still does not fall in 25 steps
        feature = rollout["next", "observation"][:, -1]
        for t in (1, 2, 5, 10, 25):
            assert feature[t - 1].item() == f32(1 - t / 1000)
        assert feature[0].item() == f32(0.999)
        assert feature[24].item() == f32(0.975)
        # root observations are shifted by one: 1.0, 0.999, ...
        assert rollout["observation"][:3, -1].tolist() == [1.0, f32(0.999), f32(0.998)]
        # the first 11 columns are the unchanged gymnasium observation
        assert torch.equal(rollout["next", "observation"][:-1], rollout["observation"][1:])

    def test_hopper_after_reset_restarts_at_one(self, hopper):
        hopper.set_seed(1)
        rollout = hopper.rollout(60, break_when_any_done=False)
        step_count = rollout["next", "step_count"][:, 0]
        # the feature follows the step count, including after the partial reset(s)
        torch.testing.assert_close(
            rollout["next", "observation"][:, -1],
            (1 - step_count.double() / 1000).float(),
            rtol=0,
            atol=0,
        )
        done = rollout["next", "done"][:, 0]
        assert done.any()  # random actions make the hopper fall within 60 steps
        first_after_reset = done.nonzero()[0, 0] + 1
        assert rollout["observation"][first_after_reset, -1].item() == 1.0

    def test_matches_teacher_data(self, teacher_dir):
        data = np.load(
            teacher_dir / "expert_data_no_img_Hopper_scores_1500_episodes_1.npz",
            allow_pickle=True,
        )
        obs = torch.as_tensor(data["obs"])
        assert obs.shape == (425, 12)
        td = TensorDict(
            observation=obs[:, :11].clone(),
            step_count=torch.arange(425).unsqueeze(-1),
            batch_size=[425],
        )
        TimeFeature(max_steps=1000)(td)
        assert td["observation"].shape == (425, 12)
        assert td["observation"][-1, -1].item() == f32(1 - 424 / 1000)
        torch.testing.assert_close(td["observation"], obs, rtol=0, atol=1e-7)

    def test_bad_arguments(self):
        with pytest.raises(ValueError, match="max_steps"):
            TimeFeature(max_steps=0)
        with pytest.raises(TypeError):
            TimeFeature(1000)  # keyword-only
        with pytest.raises(ValueError, match="out_keys"):
            TimeFeature(max_steps=5, in_keys=["a", "b"], out_keys=["c"])
        with pytest.raises(TypeError, match="Categorical"):
            TimeFeature(max_steps=10).transform_observation_spec(
                Composite(observation=Categorical(3, shape=(1,)), step_count=Unbounded(shape=(1,)))
            )


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
