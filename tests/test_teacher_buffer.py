"""Tests for TopKTeacherReplayBuffer (SAIL teacher buffer R_T)."""
from __future__ import annotations

import io
import math
from collections import Counter

import pytest
import torch
from hypothesis import given, settings, strategies as st
from tensordict import TensorDict

from torchrl_sail import TopKTeacherReplayBuffer

STORED = {
    "observation",
    "action",
    ("next", "observation"),
    ("next", "reward"),
    ("next", "done"),
    ("next", "terminated"),
    ("next", "truncated"),
}


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
            "episode_return": torch.full((length, 1), 10.0 * r_e),
            ("collector", "traj_ids"): torch.full((length,), code),
        },
        batch_size=[length],
    )


def codes_of(td: TensorDict) -> list[tuple[int, int]]:
    obs = td["observation"][:, 0].long()
    return [(int(o) // 1000, int(o) % 1000) for o in obs]


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


episode = st.tuples(st.integers(-3, 6), st.integers(1, 20))


def run_scenario(rb, ref, demos, offers):
    """Feeds the same demos/offers to the buffer and the reference, checking each step."""
    for i, (r, length) in enumerate(demos):
        rb.add_demonstrations(make_traj(float(r), length, code=i))
        ref.demo(r, i, length)
        assert rb.window == ref.window()
    decisions, thresholds = [], []
    for j, (r, length) in enumerate(offers):
        code = len(demos) + j
        decisions.append(rb.offer(make_traj(float(r), length, code=code)))
        thresholds.append(rb.threshold)
        assert decisions[-1] == ref.offer(r, code, length)
        assert rb.threshold == ref.threshold
        assert rb.window == ref.window()
    assert rb.num_offered == len(offers)
    assert rb.num_promoted == sum(decisions)
    assert rb.num_demonstrations == len(demos)
    return decisions, thresholds


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 4),
    demos=st.lists(episode, max_size=3),
    offers=st.lists(episode, max_size=15),
)
def test_topk_matches_reference(k, demos, offers):
    rb = TopKTeacherReplayBuffer(k=k, max_trajectory_length=20)
    ref = RefTopK(k)
    run_scenario(rb, ref, demos, offers)
    # exactly the K best, as a multiset of returns, and exactly their transitions
    assert rb.returns == ref.window() == rb.window
    assert rb.num_trajectories == len(ref.stored) == min(k, len(ref.stored))
    assert len(rb) == rb.num_transitions == sum(length for _, _, length in ref.stored)
    if ref.stored:
        assert sorted(codes_of(rb.transitions())) == ref.codes()

    # extend() on the concatenated offers goes through the same promotion rule
    rb2 = TopKTeacherReplayBuffer(k=k, max_trajectory_length=20)
    if demos:
        n = rb2.add_demonstrations(
            torch.cat([make_traj(float(r), n, i) for i, (r, n) in enumerate(demos)])
        )
        assert n == len(demos)
    if offers:
        stream = torch.cat(
            [make_traj(float(r), n, len(demos) + j) for j, (r, n) in enumerate(offers)]
        )
        ref2 = RefTopK(k)
        for i, (r, n) in enumerate(demos):
            ref2.demo(r, i, n)
        expected = [ref2.offer(r, len(demos) + j, n) for j, (r, n) in enumerate(offers)]
        assert rb2.offer_many(stream).tolist() == expected
    assert rb2.window == rb.window
    assert rb2.num_promoted == rb.num_promoted
    if ref.stored:
        assert sorted(codes_of(rb2.transitions())) == ref.codes()


@settings(max_examples=60, deadline=None)
@given(
    k=st.integers(1, 4),
    capacity=st.integers(20, 60),
    demos=st.lists(episode, max_size=3),
    offers=st.lists(episode, max_size=15),
)
def test_fifo_matches_reference(k, capacity, demos, offers):
    rb = TopKTeacherReplayBuffer(k=k, eviction="fifo", capacity=capacity)
    ref = RefFifo(k, capacity)
    decisions, _ = run_scenario(rb, ref, demos, offers)
    assert len(rb) == len(ref.codes())
    if ref.codes():
        # same rows in the same ring positions, partial trajectories included
        assert codes_of(rb.transitions()) == ref.codes()
    assert rb.returns == ref.live_returns()
    assert rb.num_trajectories == len({c[0] for c in ref.codes()})

    rb2 = TopKTeacherReplayBuffer(k=k, eviction="fifo", capacity=capacity)
    for i, (r, n) in enumerate(demos):
        rb2.add_demonstrations(make_traj(float(r), n, i))
    rows = torch.zeros(0, dtype=torch.long)
    if offers:
        stream = torch.cat(
            [make_traj(float(r), n, len(demos) + j) for j, (r, n) in enumerate(offers)]
        )
        rows = rb2.extend(stream)
    assert rows.numel() == sum(n for (_, n), ok in zip(offers, decisions) if ok)
    assert rb2.window == rb.window and rb2.num_promoted == rb.num_promoted
    if ref.codes():
        assert codes_of(rb2.transitions()) == ref.codes()


# --------------------------------------------------------------------------
# hand-computed cases
# --------------------------------------------------------------------------
@pytest.mark.parametrize("eviction", ["topk", "fifo"])
def test_hand_computed_threshold(eviction):
    kwargs = {"capacity": 1000} if eviction == "fifo" else {}
    rb = TopKTeacherReplayBuffer(k=3, eviction=eviction, max_trajectory_length=10, **kwargs)
    assert rb.threshold == -math.inf and rb.window == []
    assert rb.add_demonstrations(make_traj(148.0, 4, code=0)) == 1
    assert rb.threshold == 148.0
    steps = [
        (100.0, False, 148.0, [148.0]),
        (149.0, True, 148.0, [148.0, 149.0]),
        (150.0, True, 148.0, [148.0, 149.0, 150.0]),
        (151.0, True, 149.0, [149.0, 150.0, 151.0]),  # window full: 148 dropped
        (149.0, False, 149.0, [149.0, 150.0, 151.0]),  # strict >
        (150.0, True, 150.0, [150.0, 150.0, 151.0]),
        (150.0, False, 150.0, [150.0, 150.0, 151.0]),
        (-5.0, False, 150.0, [150.0, 150.0, 151.0]),
    ]
    for code, (r_e, accepted, threshold, window) in enumerate(steps, start=1):
        assert rb.offer(make_traj(r_e, 2, code=code)) is accepted
        assert rb.threshold == threshold
        assert rb.window == window
    assert rb.num_offered == 8 and rb.num_promoted == 4 and rb.num_demonstrations == 1
    stored_codes = {c for c, _ in codes_of(rb.transitions())}
    if eviction == "topk":
        # the demo and the 149 trajectory were evicted; 3 trajectories of 2 steps remain
        assert stored_codes == {3, 4, 6}
        assert len(rb) == 6 and rb.returns == [150.0, 150.0, 151.0]
    else:
        # nothing wrapped: the demo and every promoted trajectory are still there
        assert stored_codes == {0, 2, 3, 4, 6}
        assert len(rb) == 4 + 4 * 2
        assert rb.returns == [148.0, 149.0, 150.0, 150.0, 151.0]


def test_empty_window_accepts_anything_and_ties_with_demo_rejected():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=5)
    assert rb.offer(make_traj(-100.0, 3, code=1))  # C = -inf
    assert rb.threshold == -100.0
    rb2 = TopKTeacherReplayBuffer(k=2, max_trajectory_length=5)
    rb2.add_demonstrations(make_traj(7.0, 3, code=0))
    assert not rb2.offer(make_traj(7.0, 3, code=1))


def test_topk_keeps_k_best_demonstrations():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=5)
    demos = torch.cat([make_traj(r, 2, code=i) for i, r in enumerate([5.0, 1.0, 9.0, 3.0])])
    assert rb.add_demonstrations(demos) == 4
    assert rb.window == [5.0, 9.0] and rb.num_trajectories == 2
    assert {c for c, _ in codes_of(rb.transitions())} == {0, 2}


# --------------------------------------------------------------------------
# sampling
# --------------------------------------------------------------------------
def test_topk_sampling_uniform_over_valid_rows_after_eviction():
    rb = TopKTeacherReplayBuffer(k=3, max_trajectory_length=6, batch_size=20_000)
    rb.add_demonstrations(make_traj(10.0, 4, code=0))
    assert rb.offer(make_traj(11.0, 2, code=1))
    assert rb.offer(make_traj(12.0, 5, code=2))
    # evicts the demo; reuses its slot with 3 rows: its 4th row must never be sampled
    assert rb.offer(make_traj(13.0, 3, code=3))
    expected = {(1, t) for t in range(2)} | {(2, t) for t in range(5)} | {(3, t) for t in range(3)}
    assert len(rb) == 10
    batch = rb.sample()
    assert set(batch.keys(True, True)) == STORED | {"index"}
    counts = Counter(codes_of(batch))
    assert set(counts) == expected  # only valid rows, and every stored transition reached
    for n in counts.values():
        assert abs(n - 2000) < 200  # uniform over transitions (std ~42)
    # rows are intact: next observation belongs to the same transition
    torch.testing.assert_close(batch["next", "observation"], batch["observation"] + 0.5)
    assert batch["index"].max() < rb.capacity


def test_fifo_sampling_partial_overwrite():
    rb = TopKTeacherReplayBuffer(k=10, eviction="fifo", capacity=8, batch_size=8000)
    rb.add_demonstrations(make_traj(1.0, 5, code=0))
    assert rb.offer(make_traj(2.0, 5, code=1))  # rows 5,6,7,0,1: demo steps 0,1 overwritten
    assert len(rb) == 8 and rb.num_trajectories == 2
    # ring rows 0..7 after the wrap
    assert codes_of(rb.transitions()) == [
        (1, 3), (1, 4), (0, 2), (0, 3), (0, 4), (1, 0), (1, 1), (1, 2)
    ]
    counts = Counter(codes_of(rb.sample()))
    assert set(counts) == {(0, 2), (0, 3), (0, 4)} | {(1, t) for t in range(5)}
    assert rb.offer(make_traj(3.0, 3, code=2))  # rows 2,3,4: the demo is gone
    assert rb.num_trajectories == 2 and rb.returns == [2.0, 3.0]
    assert {c for c, _ in codes_of(rb.sample())} == {1, 2}
    assert rb.window == [1.0, 2.0, 3.0]  # the demo's score stays in W_k


def test_sampling_empty_buffer_raises():
    rb = TopKTeacherReplayBuffer(k=1, max_trajectory_length=5, batch_size=2)
    assert len(rb) == 0 and not rb.can_sample()
    with pytest.raises(RuntimeError, match="add_demonstrations"):
        rb.sample()


# --------------------------------------------------------------------------
# input formats, keys and errors
# --------------------------------------------------------------------------
def test_demonstration_formats():
    rb = TopKTeacherReplayBuffer(k=5, max_trajectory_length=8)
    padded = torch.stack([make_traj(3.0, 6, code=0), make_traj(4.0, 6, code=1)])
    mask = torch.zeros(2, 6, dtype=torch.bool)
    mask[0, :6] = True
    mask[1, :2] = True
    padded["next", "done"][1, 1] = True  # second demo has 2 valid steps
    padded["next", "reward"][1, 1] = 4.0
    padded["next", "reward"][1, 5] = 0.0
    padded["collector", "mask"] = mask
    assert rb.add_demonstrations(padded) == 2
    assert rb.window == [3.0, 4.0] and len(rb) == 8
    assert sorted(codes_of(rb.transitions())) == [(0, t) for t in range(6)] + [(1, 0), (1, 1)]
    with pytest.raises(ValueError, match="whole episodes"):
        rb.add_demonstrations(make_traj(1.0, 3, code=5, finished=False))
    assert rb.num_demonstrations == 2


def test_offer_accepts_padded_and_rejects_several():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    traj = make_traj(5.0, 4, code=1)
    padded = torch.stack([torch.cat([traj, make_traj(0.0, 2, code=9, finished=False)])])
    padded["collector", "mask"] = torch.tensor([[True] * 4 + [False] * 2])
    assert rb.offer(padded)
    assert codes_of(rb.transitions()) == [(1, t) for t in range(4)]
    with pytest.raises(ValueError, match="exactly one finished trajectory"):
        rb.offer(torch.cat([make_traj(6.0, 2, code=2), make_traj(7.0, 2, code=3)]))
    with pytest.raises(ValueError, match="exactly one finished trajectory"):
        rb.offer(make_traj(6.0, 2, code=2, finished=False))
    assert rb.num_offered == 1


def test_extend_carries_unfinished_episodes_across_batches():
    # stream 0: A (3 steps, r=5) then B (5 steps, r=7); stream 1: C (6, r=6) then D (2, r=7)
    s0 = torch.cat([make_traj(5.0, 3, code=1), make_traj(7.0, 5, code=2)])
    s1 = torch.cat([make_traj(6.0, 6, code=3), make_traj(7.0, 2, code=4)])
    data = torch.stack([s0, s1])  # [2, 8], time last
    rb = TopKTeacherReplayBuffer(k=1, max_trajectory_length=10)
    assert rb.offer_many(data[:, :4]).tolist() == [True]  # A finishes; B, C pending
    assert rb.num_offered == 1
    # finish order in batch 2: C (t=5), then B and D (t=7, stream order)
    assert rb.offer_many(data[:, 4:]).tolist() == [True, True, False]
    assert rb.window == [7.0]
    assert codes_of(rb.transitions()) == [(2, t) for t in range(5)]  # B, stitched whole


def test_empty_extend_keeps_the_episode_in_progress():
    traj = make_traj(3.0, 4, code=1)
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    rb.extend(traj[:2])
    rb.extend(traj[2:2])  # zero steps
    rb.extend(traj[2:])
    assert rb.num_promoted == 1
    assert codes_of(rb.transitions()) == [(1, t) for t in range(4)]


def test_extend_padded_requires_finished_rows():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    padded = torch.stack([make_traj(5.0, 3, code=1), make_traj(0.0, 3, code=2, finished=False)])
    padded["collector", "mask"] = torch.ones(2, 3, dtype=torch.bool)
    with pytest.raises(ValueError, match="Row 1"):
        rb.extend(padded)
    assert rb.num_offered == 0 and len(rb) == 0
    rows = rb.extend(padded[:1])
    assert rows.tolist() == [0, 1, 2]


def test_pending_stream_count_must_match():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    rb.extend(torch.stack([make_traj(0.0, 3, 1, finished=False)] * 2))
    with pytest.raises(ValueError, match="2 streams"):
        rb.extend(torch.stack([make_traj(1.0, 3, 1)] * 3))
    rb.clear_unfinished()
    three = torch.stack([make_traj(1.0, 3, 1), make_traj(2.0, 3, 2), make_traj(1.0, 3, 3)])
    assert rb.offer_many(three).tolist() == [True, True, False]  # 1 > C=1 is false
    assert rb.window == [1.0, 2.0]


def test_add_single_transitions():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    for step in make_traj(4.0, 3, code=1).unbind(0):
        rb.add(step)
    assert rb.num_promoted == 1 and codes_of(rb.transitions()) == [(1, 0), (1, 1), (1, 2)]
    # one step of two environments at a time (a collector with extend_buffer=False)
    a = torch.cat([make_traj(4.0, 2, code=1), make_traj(9.0, 2, code=2)])
    b = make_traj(6.0, 4, code=3)
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    offered = []
    for step in torch.stack([a, b]).unbind(-1):
        rb.add(step)
        offered.append(rb.num_offered)
    assert offered == [0, 1, 1, 3]  # a's first episode ends at t=1; b and a's second at t=3
    assert rb.window == [6.0, 9.0] and rb.num_promoted == 3
    whole = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    assert whole.offer_many(torch.stack([a, b])).tolist() == [True, True, True]
    assert sorted(codes_of(whole.transitions())) == sorted(codes_of(rb.transitions()))


def test_keys_dropped_and_custom_keys():
    keys = ["observation", ("next", "reward"), ("next", "done")]
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8, keys=keys, batch_size=4)
    traj = make_traj(3.0, 4, code=1).exclude("action", ("next", "truncated"))
    rb.add_demonstrations(traj)
    assert set(rb.sample().keys(True, True)) == {
        "observation", ("next", "reward"), ("next", "done"), "index"
    }


def test_missing_key_raises_keyerror():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    traj = make_traj(3.0, 4, code=1).exclude(("next", "truncated"))
    with pytest.raises(KeyError, match="truncated"):
        rb.add_demonstrations(traj)
    with pytest.raises(KeyError, match="truncated"):
        rb.offer(traj)
    rb2 = TopKTeacherReplayBuffer(
        k=2, max_trajectory_length=8, keys=["observation"], rank_key="dense_reward"
    )
    with pytest.raises(KeyError, match="dense_reward"):
        rb2.offer(make_traj(3.0, 4, code=1))


@pytest.mark.parametrize("k", [0, -2, 1.5, True])
def test_invalid_k(k):
    with pytest.raises(ValueError, match="k "):
        TopKTeacherReplayBuffer(k=k)


def test_invalid_construction():
    with pytest.raises(ValueError, match="eviction"):
        TopKTeacherReplayBuffer(eviction="lifo")
    with pytest.raises(ValueError, match="capacity"):
        TopKTeacherReplayBuffer(eviction="fifo")
    with pytest.raises(ValueError, match="capacity"):
        TopKTeacherReplayBuffer(capacity=100)
    with pytest.raises(TypeError, match="sampler"):
        TopKTeacherReplayBuffer(sampler=None)


def test_too_long_trajectory_raises():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=5)
    with pytest.raises(ValueError, match="6 steps"):
        rb.offer(make_traj(1.0, 6, code=1))
    with pytest.raises(ValueError, match="6 steps"):
        rb.add_demonstrations(make_traj(1.0, 6, code=1))
    fifo = TopKTeacherReplayBuffer(k=2, eviction="fifo", capacity=5)
    with pytest.raises(ValueError, match="6 steps"):
        fifo.offer(make_traj(1.0, 6, code=1))
    # a batch is validated before anything is written
    with pytest.raises(ValueError, match="6 steps"):
        fifo.extend(torch.cat([make_traj(1.0, 2, 1), make_traj(1.0, 6, 2)]))
    assert fifo.num_offered == 0 and len(fifo) == 0 and rb.num_offered == 0


def test_transforms_apply_on_sample():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8, batch_size=5)
    rb.add_demonstrations(make_traj(3.0, 4, code=1))

    def double_obs(td):
        td["obs2"] = td["observation"] * 2
        return td

    rb.append_transform(double_obs)
    batch = rb.sample()
    torch.testing.assert_close(batch["obs2"], batch["observation"] * 2)
    assert "obs2" not in rb.transitions().keys()


def test_empty_resets_everything():
    rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=8)
    rb.add_demonstrations(make_traj(3.0, 4, code=1))
    rb.offer(make_traj(5.0, 2, code=2))
    rb.empty()
    assert len(rb) == 0 and rb.threshold == -math.inf and rb.num_promoted == 0
    assert rb.offer(make_traj(-1.0, 3, code=3))
    assert codes_of(rb.transitions()) == [(3, t) for t in range(3)]


# --------------------------------------------------------------------------
# state dict
# --------------------------------------------------------------------------
def _build(eviction):
    if eviction == "fifo":
        return TopKTeacherReplayBuffer(k=3, eviction="fifo", capacity=25, batch_size=16)
    return TopKTeacherReplayBuffer(k=3, max_trajectory_length=12, batch_size=16)


def _history():
    g = torch.Generator().manual_seed(1)
    returns = torch.randint(0, 8, (24,), generator=g).tolist()
    lengths = torch.randint(1, 11, (24,), generator=g).tolist()
    return [make_traj(float(r), n, code=i + 1) for i, (r, n) in enumerate(zip(returns, lengths))]


def _state(rb):
    return (rb.window, rb.threshold, rb.returns, rb.num_offered, rb.num_promoted,
            rb.num_demonstrations, rb.num_trajectories, len(rb), codes_of(rb.transitions()))


@pytest.mark.parametrize("eviction", ["topk", "fifo"])
def test_state_dict_round_trip(eviction):
    trajs = _history()
    rb = _build(eviction)
    rb.add_demonstrations(make_traj(3.0, 7, code=0))
    for traj in trajs[:12]:
        rb.offer(traj)
    # an episode in progress (2 streams) is part of the state too
    unfinished = torch.stack([trajs[12][:1], trajs[13][:1]])
    rb.extend(unfinished)

    buffer = io.BytesIO()
    torch.save(rb.state_dict(), buffer)
    buffer.seek(0)
    state = torch.load(buffer, weights_only=True)
    fresh = _build(eviction)
    fresh.load_state_dict(state)
    assert _state(fresh) == _state(rb)

    torch.manual_seed(7)
    a = rb.sample()
    torch.manual_seed(7)
    b = fresh.sample()
    assert (a == b).all()

    # same decisions afterwards, including the pending episodes being completed
    rest = torch.stack([trajs[12][1:2], trajs[13][1:2]])
    assert (rb.offer_many(rest) == fresh.offer_many(rest)).all()
    for traj in trajs[14:]:
        assert rb.offer(traj) == fresh.offer(traj)
        assert _state(fresh) == _state(rb)
    torch.manual_seed(8)
    a = rb.sample()
    torch.manual_seed(8)
    assert (a == fresh.sample()).all()


@pytest.mark.parametrize("eviction", ["topk", "fifo"])
def test_state_dict_mid_episode_completes_like_uninterrupted(eviction):
    # stream 0: A (7 steps, r=6); stream 1: B (4 steps, r=2) then C (3 steps, r=9)
    s0 = make_traj(6.0, 7, code=1)
    s1 = torch.cat([make_traj(2.0, 4, code=2), make_traj(9.0, 3, code=3)])
    data = torch.stack([s0, s1])  # [2, 7], time last

    def first_part(rb):
        rb.add_demonstrations(make_traj(1.0, 5, code=0))
        rb.extend(data[:, :2])  # A and B unfinished
        rb.extend(data[:, 2:3])  # still unfinished: two pending chunks per stream
        rb.add(data[:, 3])  # B ends; A now has 4 steps pending in 3 chunks
        rb.add(data[:, 4])  # A: 5 steps pending, C: 1

    def second_part(rb):
        rb.add(data[:, 5])
        rb.extend(data[:, 6:])  # A and C end at the same step (stream order: A, C)

    reference = _build(eviction)
    first_part(reference)
    second_part(reference)

    rb = _build(eviction)
    first_part(rb)
    assert rb.num_offered == 1  # only B finished before the checkpoint
    buffer = io.BytesIO()
    torch.save(rb.state_dict(), buffer)
    buffer.seek(0)
    fresh = _build(eviction)
    fresh.load_state_dict(torch.load(buffer, weights_only=True))
    assert _state(fresh) == _state(rb)
    second_part(fresh)
    assert _state(fresh) == _state(reference)

    # by hand: B (2 > C=1), A (6 > 1) and C (9 > 1) are all promoted, A and C whole
    assert fresh.window == [2.0, 6.0, 9.0] and fresh.num_promoted == 3
    codes = codes_of(fresh.transitions())
    expected = [(2, t) for t in range(4)] + [(1, t) for t in range(7)]
    expected += [(3, t) for t in range(3)]
    if eviction == "fifo":  # the ring keeps the demonstration; top-3 evicted it
        expected = [(0, t) for t in range(5)] + expected
    assert sorted(codes) == sorted(expected)


def test_load_state_dict_config_mismatch():
    rb = _build("topk")
    rb.add_demonstrations(make_traj(3.0, 4, code=0))
    with pytest.raises(ValueError, match="same k"):
        TopKTeacherReplayBuffer(k=4, max_trajectory_length=12).load_state_dict(rb.state_dict())


def test_dumps_loads(tmp_path):
    rb = _build("fifo")
    rb.add_demonstrations(make_traj(3.0, 7, code=0))
    for traj in _history()[:10]:
        rb.offer(traj)
    rb.dumps(tmp_path)
    fresh = _build("fifo")
    fresh.loads(tmp_path)
    assert _state(fresh) == _state(rb)
