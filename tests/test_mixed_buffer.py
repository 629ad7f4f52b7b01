"""Tests for MixedReplayBuffer (torchrl_sail/data/mixed_buffer.py)."""

from __future__ import annotations

import argparse

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ReplayBuffer, TensorDictReplayBuffer

from torchrl_sail import TRANSITION_KEYS, MixedReplayBuffer

OBS = 3
TEACHER_MARK, AGENT_MARK = 100.0, 0.0


def transitions(n, mark):
    """``n`` transitions whose observation rows are ``mark + row index``."""
    obs = mark + torch.arange(n, dtype=torch.float32).unsqueeze(-1).expand(n, OBS)
    done = torch.zeros(n, 1, dtype=torch.bool)
    return TensorDict(
        {
            "observation": obs.clone(),
            "action": torch.zeros(n, 1),
            ("next", "observation"): obs + 1,
            ("next", "reward"): torch.zeros(n, 1),
            ("next", "done"): done,
            ("next", "terminated"): done.clone(),
            ("next", "truncated"): done.clone(),
            ("collector", "mask"): torch.zeros(n, dtype=torch.bool),  # would mask every row
            "step_count": torch.zeros(n, 1, dtype=torch.long),
        },
        [n],
    )


def make_rb(data=None, cls=TensorDictReplayBuffer, size=64):
    rb = cls(storage=LazyTensorStorage(size))
    if data is not None:
        rb.extend(data)
    return rb


def from_teacher(batch):
    return batch["observation"][:, 0] >= TEACHER_MARK


_TEACHER = make_rb(transitions(10, TEACHER_MARK))
_AGENT = make_rb(transitions(20, AGENT_MARK))


class TestMixedReplayBuffer:
    @settings(max_examples=25, deadline=None)
    @given(batch_size=st.integers(1, 17), fraction=st.floats(0.0, 1.0))
    def test_exact_counts_teacher_first_and_tag(self, batch_size, fraction):
        batch = MixedReplayBuffer(_TEACHER, _AGENT).sample(batch_size, teacher_fraction=fraction)
        num_teacher = round(fraction * batch_size)  # OfflineToOnlineReplayBuffer's rule
        assert batch.batch_size == (batch_size,)
        assert batch["is_teacher"].tolist() == [True] * num_teacher + [False] * (batch_size - num_teacher)
        assert torch.equal(from_teacher(batch), batch["is_teacher"])

    def test_keys_are_the_transition_keys(self):
        # bookkeeping ("index", a stray ("collector", "mask") the loss would read) is left out
        batch = MixedReplayBuffer(_TEACHER, _AGENT).sample(4, teacher_fraction=0.5)
        assert set(batch.keys(True, True)) == set(TRANSITION_KEYS) | {"is_teacher"}
        torch.testing.assert_close(batch["next", "observation"], batch["observation"] + 1)

    def test_a_share_of_zero_does_not_touch_the_teacher_buffer(self):
        empty_teacher = make_rb()
        batch = MixedReplayBuffer(empty_teacher, _AGENT).sample(6, teacher_fraction=0.0)
        assert not batch["is_teacher"].any() and not from_teacher(batch).any()
        batch = MixedReplayBuffer(_TEACHER, make_rb()).sample(5, teacher_fraction=1.0)
        assert batch["is_teacher"].all() and from_teacher(batch).all()

    def test_transform_is_applied_after_concatenation(self):
        seen = []

        def transform(td):
            seen.append(td.batch_size)
            # a reward that needs the tag and both halves, like DiscriminatorReward
            td.set(("next", "reward"), td["is_teacher"].float().unsqueeze(-1) * 2.0)
            return td

        batch = MixedReplayBuffer(_TEACHER, _AGENT, transform=transform).sample(5, teacher_fraction=0.4)
        assert seen == [torch.Size([5])]
        assert batch["next", "reward"].squeeze(-1).tolist() == [2.0, 2.0, 0.0, 0.0, 0.0]
        assert (_TEACHER.storage[:]["next", "reward"] == 0).all()  # the stored data is untouched

    def test_custom_keys_nested_tag_and_plain_replay_buffer(self):
        teacher = make_rb(transitions(6, TEACHER_MARK), cls=ReplayBuffer)
        agent = make_rb(transitions(6, AGENT_MARK), cls=ReplayBuffer)
        rb = MixedReplayBuffer(teacher, agent, keys=["observation"], tag_key=("meta", "src"))
        batch = rb.sample(4, teacher_fraction=0.5)
        assert set(batch.keys(True, True)) == {"observation", ("meta", "src")}
        assert batch["meta", "src"].tolist() == [True, True, False, False]

    def test_draws_in_the_same_order_as_two_direct_samples(self):
        # teacher first, then agent: the same random draws as sampling each buffer by hand
        torch.manual_seed(3)
        batch = MixedReplayBuffer(_TEACHER, _AGENT).sample(8, teacher_fraction=0.25)
        torch.manual_seed(3)
        teacher, agent = _TEACHER.sample(2), _AGENT.sample(6)
        torch.testing.assert_close(batch["observation"], torch.cat([teacher["observation"], agent["observation"]]))

    @pytest.mark.parametrize("fraction", [0.0, 0.4, 1.0])
    def test_num_batches_exact_split_in_every_batch(self, fraction):
        seen = []
        rb = MixedReplayBuffer(_TEACHER, _AGENT, transform=lambda td: seen.append(td.batch_size) or td)
        block = rb.sample(5, teacher_fraction=fraction, num_batches=7)
        num_teacher = round(fraction * 5)
        assert block.batch_size == (7, 5) and seen == [torch.Size([7, 5])]  # one transform call
        assert block["is_teacher"].tolist() == [[True] * num_teacher + [False] * (5 - num_teacher)] * 7
        assert torch.equal(from_teacher(block.reshape(-1)), block["is_teacher"].reshape(-1))

    def test_num_batches_draws_like_one_sample_per_buffer(self):
        # batch i holds draws [i * n, (i + 1) * n) of one teacher and one agent sample
        torch.manual_seed(3)
        block = MixedReplayBuffer(_TEACHER, _AGENT).sample(4, teacher_fraction=0.5, num_batches=3)
        torch.manual_seed(3)
        teacher, agent = _TEACHER.sample(6), _AGENT.sample(6)
        expected = torch.cat([teacher["observation"].reshape(3, 2, OBS), agent["observation"].reshape(3, 2, OBS)], 1)
        torch.testing.assert_close(block["observation"], expected)

    def test_row_ids_name_the_stored_row(self):
        rb = MixedReplayBuffer(_TEACHER, _AGENT, row_id_key=("meta", "row"))
        block = rb.sample(6, teacher_fraction=0.5, num_batches=40).reshape(-1)
        ids, teacher = block["meta", "row"], block["is_teacher"]
        assert ids.dtype == torch.int64 and "row" not in block.keys()
        # teacher rows 2 * index, agent rows 2 * index + 1, and the id's row is the drawn row
        assert torch.equal(ids % 2 == 0, teacher)
        for source, buffer in ((0, _TEACHER), (1, _AGENT)):
            rows = ids % 2 == source
            torch.testing.assert_close(buffer.storage[ids[rows] // 2]["observation"], block["observation"][rows])
        assert ids.unique().numel() <= 30 < ids.numel()  # 30 stored rows, 240 draws
        assert "meta" not in MixedReplayBuffer(_TEACHER, _AGENT).sample(4, teacher_fraction=0.5).keys()

    def test_row_ids_need_flat_storages(self):
        teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(16, ndim=2))
        teacher.extend(transitions(8, TEACHER_MARK).reshape(2, 4))
        with pytest.raises(ValueError, match="needs flat storages.*teacher buffer"):
            MixedReplayBuffer(teacher, _AGENT, row_id_key="row_id").sample(4, teacher_fraction=0.5)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
