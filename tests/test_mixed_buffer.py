"""Tests for MixedReplayBuffer (torchrl_sail/data/mixed_buffer.py)."""
from __future__ import annotations

import argparse

import pytest
import torch
from hypothesis import given, settings, strategies as st
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer, TensorDictReplayBuffer

from torchrl_sail import MixedReplayBuffer

OBS = 3
TEACHER_MARK, AGENT_MARK = 100.0, 0.0


def transitions(n, mark, **extra):
    """``n`` transitions whose observation rows are ``mark + row index``."""
    obs = mark + torch.arange(n, dtype=torch.float32).unsqueeze(-1).expand(n, OBS)
    td = TensorDict(
        {
            "observation": obs.clone(),
            "action": torch.zeros(n, 1),
            ("next", "observation"): obs + 1,
            ("next", "reward"): torch.zeros(n, 1),
            ("next", "done"): torch.zeros(n, 1, dtype=torch.bool),
            ("next", "terminated"): torch.zeros(n, 1, dtype=torch.bool),
        },
        [n],
    )
    for key, value in extra.items():
        td.set(key, value)
    return td


def make_rb(data=None, cls=TensorDictReplayBuffer, size=64):
    rb = cls(storage=LazyTensorStorage(size))
    if data is not None:
        rb.extend(data)
    return rb


def from_teacher(batch):
    return batch["observation"][:, 0] >= TEACHER_MARK


_TEACHER = make_rb(transitions(10, TEACHER_MARK))
_AGENT = make_rb(transitions(20, AGENT_MARK))


@settings(max_examples=25, deadline=None)
@given(num_teacher=st.integers(0, 9), num_agent=st.integers(0, 9))
def test_exact_counts_teacher_first_and_tag(num_teacher, num_agent):
    rb = MixedReplayBuffer(_TEACHER, _AGENT)
    if num_teacher + num_agent == 0:
        with pytest.raises(ValueError, match="must be positive"):
            rb.sample(num_teacher, num_agent)
        return
    batch = rb.sample(num_teacher, num_agent)
    assert batch.batch_size == (num_teacher + num_agent,)
    tag = batch["is_teacher"]
    assert tag.dtype == torch.bool and tag.shape == (num_teacher + num_agent,)
    expected = torch.tensor([True] * num_teacher + [False] * num_agent)
    assert torch.equal(tag, expected)
    # the tag tells the truth: teacher rows really come from the teacher buffer
    assert torch.equal(from_teacher(batch), expected)


def test_keys_intersection_and_bookkeeping_removed():
    teacher = make_rb(
        transitions(
            8,
            TEACHER_MARK,
            teacher_only=torch.ones(8),
            priority_weight=torch.ones(8),
            **{"is_teacher": torch.zeros(8, dtype=torch.bool)},  # stale tag gets rewritten
        )
    )
    teacher_data = teacher.storage[:]
    agent_data = transitions(8, AGENT_MARK, priority_weight=torch.ones(8))
    agent_data["collector", "traj_ids"] = torch.zeros(8, dtype=torch.long)
    agent_data["collector", "mask"] = torch.ones(8, dtype=torch.bool)
    teacher_data["collector", "mask"] = torch.ones(8, dtype=torch.bool)
    teacher = make_rb(teacher_data)
    agent = make_rb(agent_data)
    batch = MixedReplayBuffer(teacher, agent).sample(3, 4)
    keys = set(batch.keys(include_nested=True, leaves_only=True))
    assert keys == {
        "observation",
        "action",
        ("next", "observation"),
        ("next", "reward"),
        ("next", "done"),
        ("next", "terminated"),
        "is_teacher",
    }
    assert batch["is_teacher"].tolist() == [True] * 3 + [False] * 4
    # each sample did carry "index" (TensorDictReplayBuffer writes it): it was dropped
    assert "index" in teacher.sample(2).keys()


def test_single_buffer_batches_drop_bookkeeping_too():
    agent_data = transitions(8, AGENT_MARK)
    agent_data["collector", "mask"] = torch.ones(8, dtype=torch.bool)
    agent_data["collector", "traj_ids"] = torch.zeros(8, dtype=torch.long)
    batch = MixedReplayBuffer(make_rb(), make_rb(agent_data)).sample(0, 5)
    assert ("collector", "mask") not in batch.keys(True)
    assert "index" not in batch.keys()
    assert ("collector", "traj_ids") in batch.keys(True)


def test_explicit_keys():
    teacher = make_rb(transitions(8, TEACHER_MARK, extra=torch.ones(8)))
    rb = MixedReplayBuffer(
        teacher, _AGENT, keys=["observation", ("next", "reward"), "is_teacher"]
    )
    batch = rb.sample(2, 3)
    assert set(batch.keys(include_nested=True, leaves_only=True)) == {
        "observation",
        ("next", "reward"),
        "is_teacher",
    }
    assert batch["is_teacher"].tolist() == [True, True, False, False, False]
    with pytest.raises(KeyError, match="'extra'.*agent buffer"):
        MixedReplayBuffer(teacher, _AGENT, keys=["observation", "extra"]).sample(2, 2)
    with pytest.raises(KeyError, match="'missing'.*teacher buffer"):
        MixedReplayBuffer(teacher, _AGENT, keys=["missing"]).sample(2, 2)
    # explicit keys may name a sub-tensordict
    batch = MixedReplayBuffer(teacher, _AGENT, keys=["next"]).sample(1, 1)
    assert ("next", "observation") in batch.keys(True)


def test_num_teacher_zero_does_not_touch_teacher_buffer():
    class Untouchable:
        def sample(self, batch_size):
            raise AssertionError("the teacher buffer must not be sampled")

        def __len__(self):
            return 0

    batch = MixedReplayBuffer(Untouchable(), _AGENT).sample(0, 6)
    assert batch.batch_size == (6,)
    assert not batch["is_teacher"].any()
    assert not from_teacher(batch).any()
    # with a real, empty teacher buffer too
    batch = MixedReplayBuffer(make_rb(), _AGENT).sample(0, 4)
    assert batch["is_teacher"].tolist() == [False] * 4


def test_num_agent_zero_gives_teacher_only_batch():
    batch = MixedReplayBuffer(_TEACHER, make_rb()).sample(5, 0)
    assert batch["is_teacher"].all() and from_teacher(batch).all()


def test_transform_is_applied_after_concatenation():
    seen = []

    def transform(td):
        seen.append(td.batch_size)
        # a reward that needs the tag and both halves, like DiscriminatorReward
        td.set(("next", "reward"), td["is_teacher"].float().unsqueeze(-1) * 2.0)
        return td

    rb = MixedReplayBuffer(_TEACHER, _AGENT, transform=transform)
    batch = rb.sample(2, 3)
    assert seen == [torch.Size([5])]
    assert batch["next", "reward"].squeeze(-1).tolist() == [2.0, 2.0, 0.0, 0.0, 0.0]
    # the stored data is untouched
    assert (_TEACHER.storage[:]["next", "reward"] == 0).all()


def test_nested_tag_key_and_plain_replay_buffer():
    teacher = make_rb(transitions(6, TEACHER_MARK), cls=ReplayBuffer)
    agent = make_rb(transitions(6, AGENT_MARK), cls=ReplayBuffer)
    rb = MixedReplayBuffer(teacher, agent, tag_key=("meta", "src"))
    batch = rb.sample(2, 2)
    assert batch["meta", "src"].tolist() == [True, True, False, False]
    assert torch.equal(from_teacher(batch), batch["meta", "src"])


def test_mixed_batch_feeds_sail_loss():
    from torchrl.data import Bounded
    from torchrl.modules import MLP, Actor, ValueOperator
    from torchrl.objectives import SoftUpdate

    from torchrl_sail import SAILLoss

    spec = Bounded(-torch.ones(1), torch.ones(1), (1,))
    actor = Actor(torch.nn.Linear(OBS, 1), spec=spec)
    critic = ValueOperator(
        MLP(in_features=OBS + 1, out_features=1, num_cells=[4]),
        in_keys=["observation", "action"],
    )
    loss = SAILLoss(actor, critic, action_spec=spec, alpha=0.5)
    loss.make_value_estimator(gamma=0.99)
    SoftUpdate(loss, tau=0.01)
    agent_data = transitions(8, AGENT_MARK)
    agent_data["collector", "mask"] = torch.zeros(8, dtype=torch.bool)  # would mask all
    batch = MixedReplayBuffer(_TEACHER, make_rb(agent_data)).sample(4, 4)
    out = loss(batch)
    assert torch.isfinite(out["loss_qvalue"]) and torch.isfinite(out["loss_actor"])
    assert torch.isfinite(out["pred_value_teacher"]) and torch.isfinite(out["pred_value_self"])


def test_split():
    assert MixedReplayBuffer.split(256, 0.5) == (128, 128)
    assert MixedReplayBuffer.split(256, 0.0) == (0, 256)
    assert MixedReplayBuffer.split(256, 1.0) == (256, 0)
    assert MixedReplayBuffer.split(10, 0.33) == (3, 7)
    assert MixedReplayBuffer.split(4, torch.tensor(0.25)) == (1, 3)
    with pytest.raises(ValueError, match="alpha"):
        MixedReplayBuffer.split(10, 1.1)
    with pytest.raises(ValueError, match="batch_size"):
        MixedReplayBuffer.split(0, 0.5)
    with pytest.raises(TypeError, match="batch_size"):
        MixedReplayBuffer.split(10.0, 0.5)


def test_empty_buffer_errors():
    with pytest.raises(ValueError, match="teacher buffer is empty.*num_teacher=0"):
        MixedReplayBuffer(make_rb(), _AGENT).sample(2, 2)
    with pytest.raises(ValueError, match="agent buffer is empty.*num_agent=0"):
        MixedReplayBuffer(_TEACHER, make_rb()).sample(2, 2)


@pytest.mark.parametrize(
    "args,err,match",
    [
        ((-1, 2), ValueError, "num_teacher must be >= 0"),
        ((2, -1), ValueError, "num_agent must be >= 0"),
        ((0, 0), ValueError, "must be positive"),
        ((1.0, 2), TypeError, "num_teacher must be an int"),
        ((True, 2), TypeError, "num_teacher must be an int"),
    ],
)
def test_sample_argument_errors(args, err, match):
    with pytest.raises(err, match=match):
        MixedReplayBuffer(_TEACHER, _AGENT).sample(*args)


def test_constructor_errors():
    with pytest.raises(TypeError, match="teacher buffer must be a replay buffer"):
        MixedReplayBuffer(transitions(3, 0.0).to_dict(), _AGENT)
    with pytest.raises(TypeError, match="agent buffer"):
        MixedReplayBuffer(_TEACHER, [1, 2])
    with pytest.raises(TypeError, match="transform"):
        MixedReplayBuffer(_TEACHER, _AGENT, transform=3)
    with pytest.raises(TypeError, match="list of keys"):
        MixedReplayBuffer(_TEACHER, _AGENT, keys="observation")
    with pytest.raises(TypeError, match="tag_key"):
        MixedReplayBuffer(_TEACHER, _AGENT, tag_key=3)
    with pytest.raises(ValueError, match="at least one entry"):
        MixedReplayBuffer(_TEACHER, _AGENT, keys=["is_teacher"])


def test_incompatible_halves_raise():
    demo = transitions(6, TEACHER_MARK)
    demo["observation"] = demo["observation"].double()
    with pytest.raises(ValueError, match="'observation'.*float64.*float32"):
        MixedReplayBuffer(make_rb(demo), _AGENT).sample(2, 2)
    all_double = transitions(6, TEACHER_MARK).apply(
        lambda x: x.double() if x.is_floating_point() else x
    )
    teacher = make_rb(all_double)
    with pytest.raises(ValueError, match="differs between the teacher \\(dtype torch.float64"):
        MixedReplayBuffer(teacher, _AGENT).sample(2, 2)
    wide = transitions(6, TEACHER_MARK)
    wide["observation"] = torch.zeros(6, OBS + 1)
    with pytest.raises(ValueError, match="'observation'.*\\(4,\\).*\\(3,\\)"):
        MixedReplayBuffer(make_rb(wide), _AGENT).sample(2, 2)


def test_non_flat_sample_raises():
    class TrajectoryBuffer:
        def sample(self, batch_size):
            return transitions(batch_size * 2, 0.0).reshape(batch_size, 2)

        def __len__(self):
            return 10

    match = "teacher buffer returned a batch of shape \\(2, 2\\)"
    with pytest.raises(ValueError, match=match):
        MixedReplayBuffer(TrajectoryBuffer(), _AGENT).sample(2, 2)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
