"""Tests for AbsorbingStateTransform (envs/absorbing.py): DAC's absorbing state."""

from __future__ import annotations

import argparse

import pytest
import torch
from tensordict import TensorDict
from torchrl.data import Bounded
from torchrl.envs.utils import check_env_specs

from torchrl_sail import AbsorbingStateTransform, SAILLoss, make_sail_env


def _transitions(terminated, truncated):
    """Flat transitions with 1-d observations ``t`` -> ``t + 1``, action ``10 + t``, reward ``100 + t``."""
    n = len(terminated)
    terminated = torch.tensor(terminated).unsqueeze(-1)
    truncated = torch.tensor(truncated).unsqueeze(-1)
    t = torch.arange(n, dtype=torch.float32).unsqueeze(-1)
    return TensorDict(
        {
            "observation": t,
            "action": 10 + t,
            "step_count": t.long(),
            "next": {
                "observation": t + 1,
                "reward": 100 + t,
                "terminated": terminated,
                "truncated": truncated,
                "done": terminated | truncated,
            },
        },
        batch_size=[n],
    )


class TestAbsorbingStateTransform:
    def test_rows_against_hand_layout(self):
        # rows 1 and 2 terminate (two short episodes), row 4 is a time-limit truncation
        data = _transitions([False, True, True, False, False], [False, False, False, False, True])
        before = data.clone()
        out = AbsorbingStateTransform()(data)
        torch.testing.assert_close(data, before)  # the input is untouched
        a = [0.0, 1.0]  # s_a
        assert out["observation"].tolist() == [[0, 0], [1, 0], a, [2, 0], a, [3, 0], [4, 0]]
        assert out["next", "observation"].tolist() == [[1, 0], a, a, a, a, [4, 0], [5, 0]]
        assert out["action"].squeeze(-1).tolist() == [10, 11, 0, 12, 0, 13, 14]
        assert out["next", "reward"].squeeze(-1).tolist() == [100, 101, 0, 102, 0, 103, 104]
        assert not out["next", "terminated"].any()  # every target bootstraps (through s_a)
        assert out["next", "done"].squeeze(-1).tolist() == [False, False, True, False, True, False, True]
        assert out["next", "truncated"].squeeze(-1).tolist() == [False] * 6 + [True]
        # other entries are copied from the terminal row
        assert out["step_count"].squeeze(-1).tolist() == [0, 1, 1, 2, 2, 3, 4]

    def test_sail_authors_variant_against_hand_layout(self):
        # bootstrap=False with an action spec: the same rows, nothing bootstrapped, random actions at s_a
        data = _transitions([False, True, True, False, False], [False, False, False, False, True])
        spec = Bounded(-1.0, 1.0, (1,))
        torch.manual_seed(0)
        out = AbsorbingStateTransform(bootstrap=False, action_spec=spec)(data)
        a = [0.0, 1.0]
        assert out["observation"].tolist() == [[0, 0], [1, 0], a, [2, 0], a, [3, 0], [4, 0]]
        assert out["next", "observation"].tolist() == [[1, 0], a, a, a, a, [4, 0], [5, 0]]
        assert out["next", "terminated"].squeeze(-1).tolist() == [False, True, True, True, True, False, False]
        assert out["next", "done"].squeeze(-1).tolist() == [False, True, True, True, True, False, True]
        assert out["next", "truncated"].squeeze(-1).tolist() == [False] * 6 + [True]
        assert out["next", "reward"].squeeze(-1).tolist() == [100, 101, 0, 102, 0, 103, 104]
        actions = out["action"].squeeze(-1)
        assert actions[[0, 1, 3, 5, 6]].tolist() == [10, 11, 12, 13, 14]
        assert (actions[[2, 4]].abs() <= 1).all() and actions[2] != actions[4] and (actions[[2, 4]] != 0).all()
        # without the spec the absorbing action is zero (the SAIL authors' demonstrations)
        zero = AbsorbingStateTransform(bootstrap=False)(data)
        assert zero["action"].squeeze(-1)[[2, 4]].tolist() == [0, 0]

    def test_no_termination_leaves_transitions_alone(self):
        data = _transitions([False, False], [False, True])
        t = AbsorbingStateTransform()
        widened = t(data)
        assert widened.shape == (2,) and widened["observation"][:, -1].eq(0).all()
        assert t.add_absorbing_transitions(widened) is widened

    def test_env_appends_indicator_and_spec(self):
        env = make_sail_env("Hopper-v4", absorbing_state=True)
        check_env_specs(env)
        spec = env.observation_spec["observation"]
        assert spec.shape == (13,)  # Hopper's spec is Unbounded; a Bounded one gets [0, 1] (test_time_feature)
        env.set_seed(0)
        rollout = env.rollout(200)  # a random Hopper falls within 200 steps
        assert rollout["observation"][:, -1].eq(0).all()
        assert rollout["next", "terminated"][-1].item()
        stored = env.transform[-1].add_absorbing_transitions(rollout.reshape(-1))
        assert stored.shape[0] == rollout.shape[0] + 1
        assert stored["next", "observation"][-2:].tolist() == [[0.0] * 12 + [1.0]] * 2

    def test_loss_bootstraps_through_the_absorbing_state_with_the_zero_action(self):
        # TD(0), no smoothing noise, terminated=False at the terminal and absorbing rows, and a masked
        # actor (pi(s_a) = 0): y = r + gamma * min_i Q_i'(s_a, 0), where the critic is trained.
        from tensordict.nn import TensorDictModule, TensorDictSequential
        from torchrl.data import Bounded as B
        from torchrl.modules import MLP, TanhModule, ValueOperator
        from torchrl.objectives import SoftUpdate

        spec = B(-1.0, 1.0, shape=(1,))
        transform = AbsorbingStateTransform()
        actor = TensorDictSequential(
            TensorDictModule(MLP(in_features=2, out_features=1, num_cells=[4]), ["observation"], ["param"]),
            TanhModule(in_keys=["param"], out_keys=["action"], spec=spec),
            transform.action_mask(),
        )
        critic = ValueOperator(MLP(in_features=3, out_features=1, num_cells=[4]), in_keys=["action", "observation"])
        loss = SAILLoss(actor, critic, action_spec=spec, policy_noise=0.0, noise_clip=0.0)
        loss.make_value_estimator(gamma=0.9)
        SoftUpdate(loss, tau=0.1)  # targets as a run has them (and no missing-updater warning)
        out = transform(_transitions([True], [False]))
        _, meta = loss.value_loss(out)
        s_a = TensorDict(observation=torch.tensor([[0.0, 1.0]]), action=torch.zeros(1, 1), batch_size=[1])
        q_next = []
        for i in range(2):
            with torch.no_grad(), loss.target_qvalue_network_params[i].to_module(loss.qvalue_network):
                q_next.append(loss.qvalue_network(s_a.clone())["state_action_value"])
        expected = out["next", "reward"] + 0.9 * torch.minimum(*q_next)
        torch.testing.assert_close(meta["target_value"].reshape(-1, 1), expected.expand(2, 1))

        # The actor gets no gradient from an absorbing row: its action there is the constant 0.
        loss_actor, _ = loss.actor_loss(out[1:])  # the (s_a, 0, s_a) row alone
        loss_actor.backward()
        grads = [p.grad for p in loss.actor_network_params.values(True, True) if p.grad is not None]
        assert grads and all(bool((g == 0).all()) for g in grads)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
