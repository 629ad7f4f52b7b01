"""Tests for the teacher buffer: TrajectoryWriter, its TopK, Union and FIFO writers, TeacherReplayBuffer."""

from __future__ import annotations

import argparse
import io
import math
from collections import Counter

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from tensordict import TensorDict

from torchrl_sail import (
    TRANSITION_KEYS,
    FIFOTrajectoryWriter,
    TeacherReplayBuffer,
    TopKTeacherReplayBuffer,
    TopKTrajectoryWriter,
    UnionTrajectoryWriter,
)


def make_traj(r_e: float, length: int, code: int, *, finished: bool = True) -> TensorDict:
    """A trajectory whose observation encodes (code, step) as ``code * 1000 + step``.

    The delayed reward ``r_e`` sits on the last step; extra keys mimic a collector output.
    """
    steps = torch.arange(length, dtype=torch.float32)
    obs = (code * 1000 + steps).unsqueeze(-1).expand(length, 3).clone()
    reward = torch.zeros(length, 1)
    done = torch.zeros(length, 1, dtype=torch.bool)
    if finished:
        reward[-1] = r_e
        done[-1] = True
    return TensorDict(
        {
            "observation": obs,
            "action": torch.full((length, 2), 0.5),
            ("next", "observation"): obs + 0.5,
            ("next", "reward"): reward,
            ("next", "done"): done,
            ("next", "terminated"): done.clone(),
            ("next", "truncated"): torch.zeros_like(done),
            "step_count": torch.arange(length).unsqueeze(-1),
            ("collector", "traj_ids"): torch.full((length,), code),
        },
        batch_size=[length],
    )


def codes_of(td: TensorDict) -> list[tuple[int, int]]:
    obs = td["observation"][:, 0].long()
    return [(int(o) // 1000, int(o) % 1000) for o in obs]


def stored(rb: TeacherReplayBuffer) -> TensorDict:
    """All stored transitions, in storage-row order."""
    return rb.storage.get(rb.writer.stored_rows())


def topk(k, length=20, **kwargs):
    return TeacherReplayBuffer(TopKTrajectoryWriter(k=k, max_trajectory_length=length), **kwargs)


def fifo(k, capacity, **kwargs):
    return TeacherReplayBuffer(FIFOTrajectoryWriter(k=k, capacity=capacity), **kwargs)


def union(k, capacity=400, **kwargs):
    return TeacherReplayBuffer(UnionTrajectoryWriter(k=k, capacity=capacity), **kwargs)


def offer(rb, traj) -> bool:
    """Offers one finished trajectory; True if it was promoted."""
    before = rb.writer.num_promoted
    rb.extend(traj)
    return rb.writer.num_promoted > before


# --------------------------------------------------------------------------
# plain-Python references of Algorithm 1
# --------------------------------------------------------------------------
class RefTopK:
    """Keeps the K best (return, id); ties evict the oldest; C = min of the K kept."""

    def __init__(self, k):
        self.k = k
        self.stored = []  # (r_e, id, length)

    @property
    def threshold(self):
        return min(r for r, _, _ in self.stored) if self.stored else -math.inf

    def _insert(self, r, tid, length):
        self.stored.append((r, tid, length))
        if len(self.stored) > self.k:
            self.stored.remove(min(self.stored, key=lambda x: (x[0], x[1])))

    def demo(self, r, tid, length):
        self._insert(r, tid, length)

    def offer(self, r, tid, length):
        accepted = r > self.threshold
        if accepted:
            self._insert(r, tid, length)
        return accepted

    def codes(self):
        return sorted((tid, t) for _, tid, length in self.stored for t in range(length))

    def window(self):
        return sorted(float(r) for r, _, _ in self.stored)


class RefFifo:
    """The authors' buffer: transition ring + sorted score list capped at K."""

    def __init__(self, k, capacity):
        self.k = k
        self.ring = [None] * capacity
        self.cursor = 0
        self.scores = []
        self.returns = {}

    @property
    def threshold(self):
        return self.scores[0] if self.scores else -math.inf

    def _insert(self, r, tid, length):
        for t in range(length):
            self.ring[self.cursor] = (tid, t)
            self.cursor = (self.cursor + 1) % len(self.ring)
        self.returns[tid] = float(r)
        self.scores.append(float(r))
        self.scores.sort()
        if len(self.scores) > self.k:
            self.scores.pop(0)

    def demo(self, r, tid, length):
        self._insert(r, tid, length)

    def offer(self, r, tid, length):
        accepted = r > self.threshold
        if accepted:
            self._insert(r, tid, length)
        return accepted

    def codes(self):
        return [c for c in self.ring if c is not None]

    def window(self):
        return list(self.scores)

    def live_returns(self):
        return sorted(self.returns[tid] for tid in {c[0] for c in self.codes()})


class RefUnion:
    """The paper's literal rule: every admitted trajectory kept; C = min of the K best scores."""

    def __init__(self, k):
        self.k = k
        self.kept = []  # (r_e, id, length) in admission order
        self.scores = []

    @property
    def threshold(self):
        return self.scores[0] if self.scores else -math.inf

    def demo(self, r, tid, length):
        self.kept.append((float(r), tid, length))
        self.scores = sorted([*self.scores, float(r)])[-self.k :]

    def offer(self, r, tid, length):
        accepted = r > self.threshold
        if accepted:
            self.demo(r, tid, length)
        return accepted

    def codes(self):
        return [(tid, t) for _, tid, length in self.kept for t in range(length)]

    def window(self):
        return list(self.scores)


episode = st.tuples(st.integers(-3, 6), st.integers(1, 20))


def run_scenario(rb, ref, demos, offers):
    """Feeds the same demos/offers to the buffer and the reference, checking each step."""
    w = rb.writer
    for i, (r, length) in enumerate(demos):
        rb.add_demonstrations(make_traj(float(r), length, code=i))
        ref.demo(r, i, length)
        assert w.window == ref.window()
    decisions = []
    for j, (r, length) in enumerate(offers):
        code = len(demos) + j
        decisions.append(offer(rb, make_traj(float(r), length, code=code)))
        assert decisions[-1] == ref.offer(r, code, length)
        assert w.threshold == ref.threshold
        assert w.window == ref.window()
    assert w.num_offered == len(offers)
    assert w.num_promoted == sum(decisions)
    assert w.num_demonstrations == len(demos)
    return decisions


class TestTopKTrajectoryWriter:
    @settings(max_examples=60, deadline=None)
    @given(k=st.integers(1, 4), demos=st.lists(episode, max_size=3), offers=st.lists(episode, max_size=15))
    def test_matches_reference(self, k, demos, offers):
        rb = topk(k)
        ref = RefTopK(k)
        run_scenario(rb, ref, demos, offers)
        # exactly the K best, as a multiset of returns, and exactly their transitions
        assert rb.writer.returns == ref.window() == rb.writer.window
        assert rb.writer.num_trajectories == len(ref.stored)
        assert len(rb) == sum(length for _, _, length in ref.stored)
        if ref.stored:
            assert sorted(codes_of(stored(rb))) == ref.codes()

        # one extend() of the concatenated offers goes through the same promotion rule
        rb2 = topk(k)
        if demos:
            stream = torch.cat([make_traj(float(r), n, i) for i, (r, n) in enumerate(demos)])
            assert rb2.add_demonstrations(stream) == len(demos)
        if offers:
            rb2.extend(torch.cat([make_traj(float(r), n, len(demos) + j) for j, (r, n) in enumerate(offers)]))
        assert rb2.writer.window == rb.writer.window
        assert rb2.writer.num_promoted == rb.writer.num_promoted
        if ref.stored:
            assert sorted(codes_of(stored(rb2))) == ref.codes()

    def test_hand_computed_threshold(self):
        rb = topk(3, length=10)
        assert rb.writer.threshold == -math.inf and rb.writer.window == []
        assert rb.add_demonstrations(make_traj(148.0, 4, code=0)) == 1
        steps = [
            (100.0, False, 148.0, [148.0]),
            (149.0, True, 148.0, [148.0, 149.0]),
            (150.0, True, 148.0, [148.0, 149.0, 150.0]),
            (151.0, True, 149.0, [149.0, 150.0, 151.0]),  # full: the demo (148) is evicted
            (149.0, False, 149.0, [149.0, 150.0, 151.0]),  # strict >
            (150.0, True, 150.0, [150.0, 150.0, 151.0]),
            (150.0, False, 150.0, [150.0, 150.0, 151.0]),
        ]
        for code, (r_e, accepted, threshold, window) in enumerate(steps, start=1):
            assert offer(rb, make_traj(r_e, 2, code=code)) is accepted
            assert (rb.writer.threshold, rb.writer.window) == (threshold, window)
        assert {c for c, _ in codes_of(stored(rb))} == {3, 4, 6}
        assert len(rb) == 6 and rb.writer.returns == [150.0, 150.0, 151.0]

    def test_keeps_k_best_demonstrations(self):
        rb = topk(2, length=5)
        demos = torch.cat([make_traj(r, 2, code=i) for i, r in enumerate([5.0, 1.0, 9.0, 3.0])])
        assert rb.add_demonstrations(demos) == 4
        assert rb.writer.window == [5.0, 9.0] and rb.writer.num_trajectories == 2
        assert {c for c, _ in codes_of(stored(rb))} == {0, 2}

    def test_sampling_uniform_over_stored_rows_after_eviction(self):
        rb = topk(3, length=6, batch_size=20_000)
        rb.add_demonstrations(make_traj(10.0, 4, code=0))
        assert offer(rb, make_traj(11.0, 2, code=1))
        assert offer(rb, make_traj(12.0, 5, code=2))
        # evicts the demo and reuses its slot with 3 rows: its 4th row must never be sampled
        assert offer(rb, make_traj(13.0, 3, code=3))
        expected = {(1, t) for t in range(2)} | {(2, t) for t in range(5)} | {(3, t) for t in range(3)}
        assert len(rb) == 10
        batch = rb.sample()
        assert set(batch.keys(True, True)) == set(TRANSITION_KEYS) | {"index"}
        counts = Counter(codes_of(batch))
        assert set(counts) == expected  # only stored rows, and every one of them reached
        assert all(abs(n - 2000) < 200 for n in counts.values())  # uniform (std ~42)
        torch.testing.assert_close(batch["next", "observation"], batch["observation"] + 0.5)

    def test_too_long_trajectory_raises(self):
        with pytest.raises(ValueError, match="6 steps exceeds max_trajectory_length=5"):
            topk(2, length=5).extend(make_traj(1.0, 6, code=1))


class TestFIFOTrajectoryWriter:
    @settings(max_examples=60, deadline=None)
    @given(
        k=st.integers(1, 4),
        capacity=st.integers(20, 60),
        demos=st.lists(episode, max_size=3),
        offers=st.lists(episode, max_size=15),
    )
    def test_matches_reference(self, k, capacity, demos, offers):
        rb = fifo(k, capacity)
        ref = RefFifo(k, capacity)
        decisions = run_scenario(rb, ref, demos, offers)
        assert len(rb) == len(ref.codes())
        if ref.codes():  # same rows in the same ring positions, partial trajectories included
            assert codes_of(stored(rb)) == ref.codes()
        assert rb.writer.returns == ref.live_returns()

        rb2 = fifo(k, capacity)
        for i, (r, n) in enumerate(demos):
            rb2.add_demonstrations(make_traj(float(r), n, i))
        if offers:
            stream = torch.cat([make_traj(float(r), n, len(demos) + j) for j, (r, n) in enumerate(offers)])
            index = rb2.extend(stream)
            # the returned index points every written step to the row that now holds it
            written = index.ge(0)
            assert bool(written.any()) == any(decisions)
            assert codes_of(rb2.storage.get(index[written])) == codes_of(stream[written])
        assert rb2.writer.window == rb.writer.window
        if ref.codes():
            assert codes_of(stored(rb2)) == ref.codes()

    def test_partial_overwrite(self):
        rb = fifo(10, 8, batch_size=8000)
        rb.add_demonstrations(make_traj(1.0, 5, code=0))
        assert offer(rb, make_traj(2.0, 5, code=1))  # rows 5,6,7,0,1: demo steps 0,1 overwritten
        assert len(rb) == 8 and rb.writer.num_trajectories == 2
        assert codes_of(stored(rb)) == [(1, 3), (1, 4), (0, 2), (0, 3), (0, 4), (1, 0), (1, 1), (1, 2)]
        assert set(Counter(codes_of(rb.sample()))) == {(0, 2), (0, 3), (0, 4)} | {(1, t) for t in range(5)}
        assert offer(rb, make_traj(3.0, 3, code=2))  # rows 2,3,4: the demo is gone
        assert rb.writer.num_trajectories == 2 and rb.writer.returns == [2.0, 3.0]
        assert {c for c, _ in codes_of(rb.sample())} == {1, 2}
        assert rb.writer.window == [1.0, 2.0, 3.0]  # the demo's score stays in W_k


class TestTopKTeacherReplayBuffer:
    def test_is_the_composed_buffer(self):
        rb = TopKTeacherReplayBuffer(
            k=3, max_trajectory_length=12, batch_size=16, keys=["observation"], rank_key=("next", "reward")
        )
        reference = topk(3, length=12, batch_size=16)
        assert isinstance(rb, TeacherReplayBuffer) and isinstance(rb.writer, TopKTrajectoryWriter)
        assert (rb.writer.k, rb.writer.max_trajectory_length, rb.writer.capacity) == (3, 12, 36)
        assert rb.writer.keys == ["observation"] and rb._batch_size == 16
        for buffer in (rb, reference):
            buffer.add_demonstrations(make_traj(3.0, 7, code=0))
            for traj in _history():
                buffer.extend(traj)
        assert _state(rb)[:7] == _state(reference)[:7]  # same decisions, window and counts
        assert codes_of(stored(rb)) == codes_of(stored(reference))
        assert set(rb.sample().keys()) == {"observation", "index"}

    def test_state_dict_round_trip(self):
        rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=12)
        rb.add_demonstrations(make_traj(3.0, 7, code=0))
        for traj in _history()[:8]:
            rb.extend(traj)
        fresh = TopKTeacherReplayBuffer(k=2, max_trajectory_length=12)
        fresh.load_state_dict(_roundtrip(rb.state_dict()))
        assert _state(fresh) == _state(rb)


class TestUnionTrajectoryWriter:
    @settings(max_examples=60, deadline=None)
    @given(k=st.integers(1, 4), demos=st.lists(episode, max_size=3), offers=st.lists(episode, max_size=15))
    def test_matches_reference(self, k, demos, offers):
        rb = union(k)
        ref = RefUnion(k)
        run_scenario(rb, ref, demos, offers)
        # every admitted trajectory, in admission order, whole
        assert len(rb) == len(ref.codes())
        if ref.kept:
            assert codes_of(stored(rb)) == ref.codes()
        assert rb.writer.returns == sorted(r for r, _, _ in ref.kept)

    def test_hand_computed_threshold(self):
        rb = union(2, batch_size=20_000)
        for code, r_e in enumerate([5.0, 1.0, 9.0]):  # three demonstrations: all kept, W_k = [5, 9]
            rb.add_demonstrations(make_traj(r_e, 2, code=code))
        assert (rb.writer.threshold, rb.writer.window) == (5.0, [5.0, 9.0])
        steps = [
            (5.0, False, 5.0, [5.0, 9.0]),  # strict >
            (6.0, True, 6.0, [6.0, 9.0]),
            (7.0, True, 7.0, [7.0, 9.0]),
            (6.5, False, 7.0, [7.0, 9.0]),
            (10.0, True, 9.0, [9.0, 10.0]),
        ]
        for code, (r_e, accepted, threshold, window) in enumerate(steps, start=3):
            assert offer(rb, make_traj(r_e, 3, code=code)) is accepted
            assert (rb.writer.threshold, rb.writer.window) == (threshold, window)
        # nothing was evicted: 3 demonstrations of 2 steps, 3 promoted trajectories of 3
        assert rb.writer.returns == [1.0, 5.0, 6.0, 7.0, 9.0, 10.0] and len(rb) == 15
        counts = Counter(codes_of(rb.sample()))
        assert {c for c, _ in counts} == {0, 1, 2, 4, 5, 7}
        assert all(abs(n - 20_000 / 15) < 150 for n in counts.values())  # uniform over rows (std ~36)

    def test_full_buffer_raises_before_writing(self):
        rb = union(2, capacity=8)
        rb.add_demonstrations(make_traj(1.0, 5, code=0))
        with pytest.raises(RuntimeError, match="5 of its capacity=8 rows hold trajectories and one of 4 steps"):
            rb.extend(make_traj(2.0, 4, code=1))
        assert len(rb) == 5 and codes_of(stored(rb)) == [(0, t) for t in range(5)]


class TestTrajectoryWriter:
    def test_extend_carries_unfinished_episodes_across_batches(self):
        # stream 0: A (3 steps, r=5) then B (5, r=7); stream 1: C (6, r=6) then D (2, r=7)
        s0 = torch.cat([make_traj(5.0, 3, code=1), make_traj(7.0, 5, code=2)])
        s1 = torch.cat([make_traj(6.0, 6, code=3), make_traj(7.0, 2, code=4)])
        data = torch.stack([s0, s1])  # [2, 8], time last
        rb = topk(1, length=10)
        index = rb.extend(data[:, :4].clone())
        assert rb.writer.num_offered == 1 and rb.writer.num_promoted == 1  # A
        assert index.tolist() == [[0, 1, 2, -1], [-1, -1, -1, -1]]
        # finish order in batch 2: C (t=5), then B and D (t=7, stream order)
        second = data[:, 4:].clone()
        index = rb.extend(second)
        assert rb.writer.window == [7.0] and rb.writer.num_promoted == 3
        assert codes_of(stored(rb)) == [(2, t) for t in range(5)]  # B, stitched whole
        # B's last 4 steps are in this batch: rows 1..4 of its slot; C was written, then evicted
        assert index.tolist() == [[1, 2, 3, 4], [-1, -1, -1, -1]]

    def test_zero_length_extend_keeps_the_episode_in_progress(self):
        traj = make_traj(3.0, 4, code=1)
        rb = topk(2, length=8)
        for part in (traj[:2], traj[2:2], traj[2:]):
            rb.extend(part)
        assert rb.writer.num_promoted == 1
        assert codes_of(stored(rb)) == [(1, t) for t in range(4)]

    def test_add_one_step_at_a_time(self):
        # one step of two environments at a time (a collector with extend_buffer=False)
        a = torch.cat([make_traj(4.0, 2, code=1), make_traj(9.0, 2, code=2)])
        b = make_traj(6.0, 4, code=3)
        rb = topk(2, length=8)
        offered = []
        for step in torch.stack([a, b]).unbind(-1):
            rb.add(step)
            offered.append(rb.writer.num_offered)
        assert offered == [0, 1, 1, 3]  # a's first episode ends at t=1; b and a's second at t=3
        assert rb.writer.window == [6.0, 9.0] and rb.writer.num_promoted == 3
        whole = topk(2, length=8)
        whole.extend(torch.stack([a, b]))
        assert sorted(codes_of(stored(whole))) == sorted(codes_of(stored(rb)))

    def test_padded_demonstrations_with_mask(self):
        rb = topk(5, length=8)
        padded = torch.stack([make_traj(3.0, 6, code=0), make_traj(4.0, 6, code=1)])
        padded["next", "done"][1, 1] = True  # the second demonstration has 2 valid steps
        padded["next", "reward"][1, 1] = 4.0
        padded["collector", "mask"] = torch.tensor([[True] * 6, [True] * 2 + [False] * 4])
        assert rb.add_demonstrations(padded) == 2
        assert rb.writer.window == [3.0, 4.0] and len(rb) == 8
        assert sorted(codes_of(stored(rb))) == [(0, t) for t in range(6)] + [(1, 0), (1, 1)]
        with pytest.raises(ValueError, match="whole episodes"):
            rb.add_demonstrations(make_traj(1.0, 3, code=5, finished=False))

    def test_custom_keys_and_rank_key(self):
        keys = ["observation", ("next", "reward"), ("next", "done")]
        rb = TeacherReplayBuffer(
            TopKTrajectoryWriter(k=2, max_trajectory_length=8, keys=keys, rank_key="step_count"), batch_size=4
        )
        rb.add_demonstrations(make_traj(3.0, 4, code=1))
        assert rb.writer.window == [6.0]  # 0 + 1 + 2 + 3
        assert set(rb.sample().keys(True, True)) == set(keys) | {"index"}

    def test_empty(self):
        rb = topk(2, length=8)
        rb.add_demonstrations(make_traj(3.0, 4, code=1))
        offer(rb, make_traj(5.0, 2, code=2))
        rb.empty()
        assert len(rb) == 0 and rb.writer.threshold == -math.inf and rb.writer.num_promoted == 0
        assert offer(rb, make_traj(-1.0, 3, code=3))
        assert codes_of(stored(rb)) == [(3, t) for t in range(3)]

    def test_sampling_an_empty_buffer_raises(self):
        rb = topk(1, length=5, batch_size=2)
        assert len(rb) == 0 and not rb.can_sample()
        with pytest.raises(RuntimeError, match="demonstrations"):
            rb.sample()

    def test_transforms_apply_on_sample(self):
        rb = topk(2, length=8, batch_size=5)
        rb.add_demonstrations(make_traj(3.0, 4, code=1))
        rb.append_transform(lambda td: td.set("obs2", td["observation"] * 2))
        batch = rb.sample()
        torch.testing.assert_close(batch["obs2"], batch["observation"] * 2)
        assert "obs2" not in stored(rb).keys()


def _history():
    g = torch.Generator().manual_seed(1)
    returns = torch.randint(0, 8, (24,), generator=g).tolist()
    lengths = torch.randint(1, 11, (24,), generator=g).tolist()
    return [make_traj(float(r), n, code=i + 1) for i, (r, n) in enumerate(zip(returns, lengths, strict=True))]


def _build(kind):
    return {
        "fifo": lambda: fifo(3, 25, batch_size=16),
        "union": lambda: union(3, 300, batch_size=16),
        "topk": lambda: topk(3, length=12, batch_size=16),
    }[kind]()


def _state(rb):
    w = rb.writer
    return (
        w.window,
        w.threshold,
        w.returns,
        w.num_offered,
        w.num_promoted,
        w.num_demonstrations,
        w.num_trajectories,
        len(rb),
        codes_of(stored(rb)),
    )


def _roundtrip(state):
    buffer = io.BytesIO()
    torch.save(state, buffer)
    buffer.seek(0)
    return torch.load(buffer, weights_only=True)


class TestTeacherReplayBufferCheckpoint:
    @pytest.mark.parametrize("kind", ["topk", "union", "fifo"])
    def test_state_dict_round_trip(self, kind):
        trajs = _history()
        rb = _build(kind)
        rb.add_demonstrations(make_traj(3.0, 7, code=0))
        for traj in trajs[:12]:
            rb.extend(traj)
        rb.extend(torch.stack([trajs[12][:1], trajs[13][:1]]))  # two episodes in progress
        fresh = _build(kind)
        fresh.load_state_dict(_roundtrip(rb.state_dict()))
        assert _state(fresh) == _state(rb)
        torch.manual_seed(7)
        a = rb.sample()
        torch.manual_seed(7)
        assert (a == fresh.sample()).all()
        # same decisions afterwards, the pending episodes included
        rest = torch.stack([trajs[12][1:2], trajs[13][1:2]])
        assert torch.equal(rb.extend(rest.clone()), fresh.extend(rest.clone()))
        for traj in trajs[14:]:
            rb.extend(traj)
            fresh.extend(traj)
            assert _state(fresh) == _state(rb)

    @pytest.mark.parametrize("kind", ["topk", "union", "fifo"])
    def test_mid_episode_checkpoint_completes_like_uninterrupted(self, kind):
        # stream 0: A (7 steps, r=6); stream 1: B (4 steps, r=2) then C (3 steps, r=9)
        data = torch.stack(
            [make_traj(6.0, 7, code=1), torch.cat([make_traj(2.0, 4, code=2), make_traj(9.0, 3, code=3)])]
        )

        def first_part(rb):
            rb.add_demonstrations(make_traj(1.0, 5, code=0))
            rb.extend(data[:, :2])
            rb.extend(data[:, 2:3])  # two pending chunks per stream
            rb.add(data[:, 3])  # B ends
            rb.add(data[:, 4])

        def second_part(rb):
            rb.add(data[:, 5])
            rb.extend(data[:, 6:])  # A and C end at the same step (stream order: A, C)

        reference = _build(kind)
        first_part(reference)
        second_part(reference)
        rb = _build(kind)
        first_part(rb)
        assert rb.writer.num_offered == 1
        fresh = _build(kind)
        fresh.load_state_dict(_roundtrip(rb.state_dict()))
        second_part(fresh)
        assert _state(fresh) == _state(reference)
        # by hand: B (2 > C=1), A (6 > 1) and C (9 > 1) are promoted, A and C whole
        assert fresh.writer.window == [2.0, 6.0, 9.0] and fresh.writer.num_promoted == 3
        expected = [(2, t) for t in range(4)] + [(1, t) for t in range(7)] + [(3, t) for t in range(3)]
        if kind != "topk":  # the ring and the union keep the demonstration; the top-3 evicted it
            expected += [(0, t) for t in range(5)]
        assert sorted(codes_of(stored(fresh))) == sorted(expected)

    def test_config_mismatch_raises(self):
        rb = _build("topk")
        rb.add_demonstrations(make_traj(3.0, 4, code=0))
        with pytest.raises(ValueError, match="k=3"):
            topk(4, length=12).load_state_dict(rb.state_dict())

    def test_dumps_loads(self, tmp_path):
        rb = _build("fifo")
        rb.add_demonstrations(make_traj(3.0, 7, code=0))
        for traj in _history()[:10]:
            rb.extend(traj)
        rb.dumps(tmp_path)
        fresh = _build("fifo")
        fresh.loads(tmp_path)
        assert _state(fresh) == _state(rb)


if __name__ == "__main__":
    args, unknown = argparse.ArgumentParser().parse_known_args()
    pytest.main([__file__, "--capture", "no", "--exitfirst"] + unknown)
