"""Tests for PrioritizedMixedReplayBuffer (torchrl_sail/data/prioritized_mixed_buffer.py): DDPGfD's
prioritized replay over a fixed demonstration buffer and the agent's replay together."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.data import LazyTensorStorage, ListStorage, ReplayBuffer, TensorDictReplayBuffer

from torchrl_sail import PrioritizedMixedReplayBuffer, TopKTeacherReplayBuffer
from torchrl_sail.data.prioritized_mixed_buffer import _PriorityTree

TEACHER_MARK, AGENT_MARK = 100.0, 0.0


def rows(n, mark):
    """``n`` rows whose observation is ``mark + row index``."""
    return TensorDict({"observation": mark + torch.arange(n, dtype=torch.float32).unsqueeze(-1)}, [n])


def make(n_teacher=2, n_agent=3, capacity=8, **kwargs):
    teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(n_teacher + 4))
    if n_teacher:
        teacher.extend(rows(n_teacher, TEACHER_MARK))
    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(capacity))
    kwargs.setdefault("keys", ["observation"])
    rb = PrioritizedMixedReplayBuffer(teacher, agent, **kwargs)
    if n_agent:
        agent.extend(rows(n_agent, AGENT_MARK))
    return rb, teacher, agent


@pytest.mark.parametrize("size", [1, 2, 5, 8, 13])
def test_tree_sums_mins_and_finds_like_prefix_sums(size):
    rng = np.random.default_rng(size)
    tree = _PriorityTree(size)
    values = rng.uniform(0.1, 2.0, size)
    values[rng.uniform(size=size) < 0.3] = 0.0  # rows without mass are never found
    tree.set(np.arange(size), values)
    assert tree.total == pytest.approx(values.sum())
    assert tree.minimum == pytest.approx(values.min())
    prefix = np.cumsum(values)
    for i in np.flatnonzero(values):
        start = prefix[i] - values[i]
        # the interval [S_{i-1}, S_i) (its ends up to the rounding of the tree's partial sums)
        masses = np.array([start + 1e-9, start + values[i] / 2, prefix[i] - 1e-9])
        assert tree.find(masses, size).tolist() == [i, i, i]
    # a mass within rounding of the total ends on the last set leaf, never on an unset one past it
    partial = _PriorityTree(size + 3)
    partial.set(np.arange(size), np.full(size, 0.1))
    assert partial.find(np.array([partial.total, np.nextafter(partial.total, 0)]), size).tolist() == [size - 1] * 2
    # a partial update changes the roots as recomputing them would
    values[size // 2] = 7.0
    tree.set(np.array([size // 2]), np.array([7.0]))
    assert (tree.total, tree.minimum) == (pytest.approx(values.sum()), pytest.approx(values.min()))


def test_probabilities_weights_and_tags_follow_the_priorities():
    rb, _, _ = make(alpha=0.5, beta=0.7, eps=1e-3, teacher_eps=0.5)
    # positions 0-1: the teacher's 2 rows; 2-4: the agent's storage rows 0-2
    p = torch.tensor([1.0, 4.0, 0.0, 9.0, 2.0])
    rb.update_priority(torch.arange(5), p)
    v = (p.double() + 1e-3 + torch.tensor([0.5, 0.5, 0, 0, 0])) ** 0.5
    assert torch.allclose(rb.probabilities(), v / v.sum())

    torch.manual_seed(0)
    batch = rb.sample(50_000)
    position = batch["index"]
    frequencies = torch.bincount(position, minlength=5).double() / 50_000
    assert torch.allclose(frequencies, v / v.sum(), atol=4 * (0.25 / 50_000) ** 0.5)
    # teacher rows first, tagged, and holding the teacher's data
    n_teacher = int((position < 2).sum())
    assert batch["is_teacher"][:n_teacher].all() and not batch["is_teacher"][n_teacher:].any()
    assert (batch["observation"][:n_teacher, 0] == TEACHER_MARK + position[:n_teacher]).all()
    assert (batch["observation"][n_teacher:, 0] == AGENT_MARK + position[n_teacher:] - 2).all()
    # w_i = (N P_i)^-beta / max_k (N P_k)^-beta = (v_i / v_min)^-beta
    expected = ((v / v.min()) ** -0.7).float()
    assert torch.allclose(batch["priority_weight"], expected[position])


def test_a_batch_draws_one_row_per_equal_range_of_the_total_priority():
    # the teacher's 2 rows hold half the total: stratified draws put exactly half of every batch
    # there, where independent draws would vary (4 rows: 2 teacher rows in only 6 of 16 orderings)
    rb, _, _ = make(alpha=1.0, beta=1.0, eps=1e-9)
    rb.update_priority(torch.arange(5), torch.tensor([3.0, 3.0, 2.0, 2.0, 2.0]))
    torch.manual_seed(0)
    for batch_size in (2, 4, 8):
        for _ in range(50):
            batch = rb.sample(batch_size)
            assert int(batch["is_teacher"].sum()) == batch_size // 2
            assert batch["index"].tolist() == sorted(batch["index"].tolist())
    # the i-th draw falls in [i, i + 1) * total / batch_size: with 5 equal priorities and a batch
    # of 5, each row exactly once
    rb.update_priority(torch.arange(5), torch.ones(5))
    assert rb.sample(5)["index"].tolist() == [0, 1, 2, 3, 4]


def test_rows_enter_at_the_largest_priority_so_far_and_ring_overwrites_reenter():
    rb, _, agent = make(n_teacher=1, n_agent=2, capacity=4, alpha=1.0, eps=1e-6)
    leaves = rb.state_dict()["leaves"]
    assert torch.allclose(leaves, torch.full((3,), 1.0 + 1e-6, dtype=torch.float64))  # 1 before any priority
    rb.update_priority(torch.tensor([1, 2]), torch.tensor([5.0, 0.5]))
    agent.extend(rows(3, AGENT_MARK))  # storage rows 2, 3, then 0 again (the ring)
    leaves = rb.state_dict()["leaves"]
    assert torch.allclose(leaves, torch.tensor([1.0, 5.0, 0.5, 5.0, 5.0], dtype=torch.float64) + 1e-6)
    # position 1 (agent row 0) was overwritten: it re-entered at the max, 5


def test_teacher_bonus_repeated_positions_and_scalar_priorities():
    rb, _, _ = make(alpha=1.0, eps=1e-6, teacher_eps=2.0)
    rb.update_priority(torch.tensor([0, 3, 0]), torch.tensor([7.0, 1.0, 3.0]))  # position 0 twice: last kept
    rb.update_priority(torch.tensor([1, 4]), 0.25)
    leaves = rb.state_dict()["leaves"]
    assert torch.allclose(leaves, torch.tensor([3 + 2.0, 0.25 + 2.0, 1.0, 1.0, 0.25], dtype=torch.float64) + 1e-6)
    assert rb.max_priority == 7.0  # the largest given, even if overwritten


def test_update_tensordict_priority_reads_the_index_and_priority_keys():
    rb, _, _ = make(alpha=1.0, eps=1e-6)
    batch = rb.sample(4)
    batch["td_error"] = torch.full((4,), 3.0)
    rb.update_tensordict_priority(batch)
    leaves = rb.state_dict()["leaves"]
    assert torch.allclose(leaves[batch["index"]], torch.full((4,), 3.0 + 1e-6, dtype=torch.float64))


def test_state_dict_round_trip_and_size_check():
    rb, teacher, agent = make(alpha=0.6)
    rb.update_priority(torch.arange(5), torch.tensor([0.1, 0.2, 0.3, 0.4, 0.5]))
    state = rb.state_dict()
    fresh = PrioritizedMixedReplayBuffer(teacher, agent, alpha=0.6, keys=["observation"])
    assert not torch.equal(fresh.state_dict()["leaves"], state["leaves"])
    fresh.load_state_dict(state)
    assert torch.equal(fresh.state_dict()["leaves"], state["leaves"]) and fresh.max_priority == rb.max_priority
    agent.extend(rows(1, AGENT_MARK))
    with pytest.raises(ValueError, match="cover 2 teacher and 3 agent rows, the buffers hold 2 and 4"):
        fresh.load_state_dict(state)
    # the same count split otherwise between teacher and agent rows, or other priority settings: refused
    other, _, _ = make(n_teacher=3, n_agent=2, alpha=0.6)
    with pytest.raises(ValueError, match="cover 2 teacher and 3 agent rows, the buffers hold 3 and 2"):
        other.load_state_dict(state)
    other, _, _ = make(alpha=0.3, teacher_eps=1.0)
    with pytest.raises(ValueError, match=r"set with alpha=0.6 \(here 0.3\), teacher_eps=0.0 \(here 1.0\)"):
        other.load_state_dict(state)
    # a state saved before the priority settings were saved with it: refused with the reason
    old_state = {
        key: value for key, value in state.items() if key not in ("num_teacher", "alpha", "eps", "teacher_eps")
    }
    with pytest.raises(ValueError, match=r"no \['num_teacher', 'alpha', 'eps', 'teacher_eps'\].*restart the run"):
        fresh.load_state_dict(old_state)


def test_a_load_or_an_emptied_agent_buffer_leaves_no_stale_priority():
    """Rows set before a load of fewer rows, or before ``agent.empty()``, are out of the draws, the
    probabilities and the weights; a loaded buffer draws what the saved one draws."""
    rb, teacher, agent = make(n_agent=2, alpha=1.0, beta=1.0, eps=1e-9)
    rb.update_priority(torch.tensor([0, 1, 2, 3]), torch.tensor([1.0, 2.0, 3.0, 4.0]))
    state = rb.state_dict()  # 2 teacher + 2 agent rows
    big, big_teacher, big_agent = make(n_agent=6, alpha=1.0, beta=1.0, eps=1e-9)
    big.update_priority(torch.tensor([3, 7]), torch.tensor([100.0, 0.01]))  # 0.01: the min of the tree
    big_agent.storage.load_state_dict(agent.storage.state_dict())  # the saved 2 agent rows
    big.load_state_dict(state)
    assert len(big) == 4
    probabilities = big.probabilities()
    assert torch.allclose(probabilities, torch.tensor([1.0, 2.0, 3.0, 4.0], dtype=torch.float64) / 10)
    torch.manual_seed(0)
    drawn = rb.sample(32)
    torch.manual_seed(0)
    loaded = big.sample(32)
    assert torch.equal(drawn["index"], loaded["index"])
    assert torch.equal(drawn["priority_weight"], loaded["priority_weight"])
    # min v = 1 (position 0): the weights are (v / 1) ** -1, not those of the stale 0.01
    assert torch.allclose(loaded["priority_weight"], 1.0 / (loaded["index"] + 1.0))
    big_agent.empty()  # the agent rows go, their priorities with them
    assert len(big) == 2 and torch.allclose(big.probabilities(), torch.tensor([1 / 3, 2 / 3], dtype=torch.float64))
    assert not big.sample(64)["is_teacher"].logical_not().any()
    big_agent.extend(rows(1, AGENT_MARK))  # a new row enters at the largest priority so far (4)
    assert torch.allclose(big.probabilities(), torch.tensor([1.0, 2.0, 4.0], dtype=torch.float64) / 7)


def test_a_teacher_buffer_reads_its_stored_rows():
    """Two episodes in a top-K buffer fill two slots (rows 0-3 and 10-12): positions 0-6 map to them."""
    teacher = TopKTeacherReplayBuffer(k=2, max_trajectory_length=10, keys=["observation"])
    for length, mark in ((4, TEACHER_MARK), (3, 2 * TEACHER_MARK)):
        episode = rows(length, mark)
        done = torch.zeros(length, 1, dtype=torch.bool)
        done[-1] = True
        episode.set(("next", "done"), done)
        episode.set(("next", "reward"), torch.zeros(length, 1))
        teacher.add_demonstrations(episode)
    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(8))
    rb = PrioritizedMixedReplayBuffer(teacher, agent, keys=["observation"])
    assert len(rb) == 7
    rb.update_priority(torch.arange(7), torch.tensor([0.0, 0, 0, 0, 0, 1e6, 0]))  # position 5: row 11
    batch = rb.sample(16)
    assert set(batch["index"].tolist()) <= set(range(7))
    expected = torch.tensor([100.0, 101, 102, 103, 200, 201, 202])
    assert torch.equal(batch["observation"][:, 0], expected[batch["index"]])
    assert (batch["index"] == 5).sum() >= 12  # P(5) = 1e6 ** 0.6 / (that + 6 eps ** 0.6 + ...) ~ 1


def test_draws_read_the_storages_rows_and_a_reloaded_agent_storage():
    """The batch holds what ``storage[index]`` holds at the drawn rows, the selected keys only; after the
    agent storage loads other rows (a resumed run), draws read those."""
    teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(4))
    teacher.extend(rows(3, TEACHER_MARK).set("other", torch.zeros(3)))
    agent = TensorDictReplayBuffer(storage=LazyTensorStorage(8))
    rb = PrioritizedMixedReplayBuffer(teacher, agent, keys=["observation"])
    agent.extend(rows(5, AGENT_MARK).set("other", torch.zeros(5)))
    batch = rb.sample(64)
    assert set(batch.keys()) == {"observation", "is_teacher", "index", "priority_weight"}
    n_teacher = int(batch["is_teacher"].sum())
    position = batch["index"]
    expected = torch.cat([teacher.storage[position[:n_teacher]], agent.storage[position[n_teacher:] - 3]])
    assert torch.equal(batch["observation"], expected["observation"])
    saved = TensorDictReplayBuffer(storage=LazyTensorStorage(8))
    saved.extend(rows(5, 50.0).set("other", torch.zeros(5)))
    agent.storage.load_state_dict(saved.storage.state_dict())
    batch = rb.sample(64)
    agent_rows = ~batch["is_teacher"]
    assert torch.equal(batch["observation"][agent_rows, 0], 50.0 + batch["index"][agent_rows] - 3)


def test_bad_input_is_refused_with_the_reason():
    with pytest.raises(ValueError, match="eps must be a finite number > 0"):
        make(eps=0.0)
    with pytest.raises(ValueError, match="alpha must be a finite number >= 0, got -1"):
        make(alpha=-1)
    with pytest.raises(ValueError, match="the teacher buffer is empty"):
        make(n_teacher=0)
    teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(2))
    teacher.extend(rows(2, TEACHER_MARK))
    with pytest.raises(TypeError, match="the agent buffer needs a TensorStorage .*, got a ListStorage"):
        PrioritizedMixedReplayBuffer(teacher, TensorDictReplayBuffer(storage=ListStorage(8)))
    tensors = ReplayBuffer(storage=LazyTensorStorage(8))  # a TensorStorage of plain tensors
    tensors.extend(torch.zeros(4, 1))
    with pytest.raises(TypeError, match="the agent storage must hold TensorDicts, it holds a Tensor"):
        PrioritizedMixedReplayBuffer(teacher, tensors, keys=["observation"]).sample(64)
    rb, teacher, _ = make()
    teacher.extend(rows(1, TEACHER_MARK))
    with pytest.raises(RuntimeError, match="teacher buffer changed size \\(2 rows at construction, 3 now\\)"):
        rb.sample(4)
    rb, _, _ = make()  # 2 teacher + 3 agent rows: positions 0-4
    with pytest.raises(ValueError, match="batch_size must be an int >= 1, got 0"):
        rb.sample(0)
    before = rb.state_dict()["leaves"]
    for position in (-1, 5):  # an internal tree node, an agent row not written yet
        with pytest.raises(IndexError, match=f"positions must lie in \\[0, 5\\).*got \\[{position}\\]"):
            rb.update_priority(torch.tensor([0, position]), 1.0)
    for priority in (float("nan"), float("inf"), -0.5):
        with pytest.raises(ValueError, match="priorities must be finite and >= 0"):
            rb.update_priority(torch.tensor([0, 1]), torch.tensor([1.0, priority]))
    assert torch.equal(rb.state_dict()["leaves"], before) and rb.max_priority == 1.0  # nothing written
