"""SAIL's teacher replay buffer R_T: whole trajectories admitted by a top-K threshold rule.

SAIL (Algorithm 1 of the paper) seeds a teacher buffer R_T with the demonstrations and, at
the end of every agent episode, *promotes* the episode into R_T when its trajectory-wise
reward ``r_e`` beats a threshold ``C``: the minimum of a window ``W_k`` of the ``K`` best
rewards admitted so far, so ``C`` only rises and the teacher data keeps improving.

As in TorchRL's :class:`~torchrl.data.TensorDictMaxValueWriter`, the ranking rule lives in a
:class:`~torchrl.data.replay_buffers.writers.Writer`: :class:`TrajectoryWriter` splits what
it is given into trajectories and applies the promotion test, and three writers decide where
an admitted trajectory goes: :class:`TopKTrajectoryWriter` (keep the K best trajectories, the
default), :class:`UnionTrajectoryWriter` (the paper's literal ``R_T <- R_T U tau``: keep every
admitted trajectory) and :class:`FIFOTrajectoryWriter` (the authors' code: a ring of transitions).
:class:`TeacherReplayBuffer` is a :class:`~torchrl.data.TensorDictReplayBuffer` built around
one of them, and :class:`TopKTeacherReplayBuffer` the default buffer in one call (as TorchRL's
``TensorDictPrioritizedReplayBuffer`` builds its sampler). (``TensorDictMaxValueWriter`` ranks
one storage slot at a time: it cannot hold variable-length trajectories in a transition storage
nor express the window rule.)
"""

from __future__ import annotations

import bisect
import math
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase, pad
from tensordict.utils import NestedKey, unravel_key
from torchrl.data.replay_buffers import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import RandomSampler
from torchrl.data.replay_buffers.writers import Writer

from torchrl_sail.data.keys import TRANSITION_KEYS

__all__ = [
    "FIFOTrajectoryWriter",
    "TeacherReplayBuffer",
    "TopKTeacherReplayBuffer",
    "TopKTrajectoryWriter",
    "TrajectoryWriter",
    "UnionTrajectoryWriter",
]

_MASK_KEY = ("collector", "mask")


class TrajectoryWriter(Writer):
    """Writes whole trajectories into a transition storage through SAIL's promotion rule.

    :meth:`extend` takes transitions with time as the last batch dim, ``[T]`` (one stream) or
    ``[B, T]`` (``B`` streams, e.g. a collector batch), and splits every stream after each
    ``done_key``. A stream's unfinished tail is kept and prepended to the same stream at the
    next call, so an episode that spans collector batches is offered whole when it ends (keep
    the number of streams constant). Steps whose ``("collector", "mask")`` is ``False`` are
    ignored. Finished trajectories are offered in the order they end (time, then stream).

    An agent trajectory with reward ``r_e`` (the sum of ``rank_key`` over its steps) is
    promoted iff ``r_e > C`` (strict), ``C = min(W_k)`` (``-inf`` while ``W_k`` is empty).
    Demonstrations (:meth:`add_demonstrations`) skip the test. Only ``keys`` are stored.

    Subclasses decide where an admitted trajectory goes and how ``W_k`` evolves (:meth:`_place`).
    The rule's state is public: :attr:`threshold`, :attr:`window`, :attr:`returns`,
    ``num_trajectories``, ``num_transitions``, ``num_offered``, ``num_promoted``, ``num_demonstrations``.

    Keyword Args:
        k (int): size ``K`` of the window ``W_k``. Defaults to ``10`` (the authors' value).
        capacity (int): number of transition rows of the storage.
        keys (sequence of NestedKey, optional): the entries stored per transition. Defaults
            to :data:`~torchrl_sail.TRANSITION_KEYS`.
        rank_key (NestedKey): the per-step entry summed into ``r_e``. Defaults to
            ``("next", "reward")`` (the delayed reward after ``DelayedRewardTransform``).
        done_key (NestedKey): the end-of-episode flag. Defaults to ``("next", "done")``.
    """

    _placement_state: tuple[str, ...] = ()  # subclass attributes saved with the state

    def __init__(
        self,
        *,
        k: int = 10,
        capacity: int,
        keys: list[NestedKey] | None = None,
        rank_key: NestedKey = ("next", "reward"),
        done_key: NestedKey = ("next", "done"),
    ) -> None:
        if k < 1 or capacity < 1:
            raise ValueError(f"k and capacity must be >= 1, got k={k}, capacity={capacity}.")
        super().__init__()
        self.k = k
        self.capacity = capacity
        self.keys = [unravel_key(key) for key in (TRANSITION_KEYS if keys is None else keys)]
        self.rank_key = unravel_key(rank_key)
        self.done_key = unravel_key(done_key)
        self._read_keys = list(dict.fromkeys([*self.keys, self.rank_key, self.done_key]))
        self._empty()

    def _empty(self, empty_write_count: bool = True) -> None:
        self._row_trajectory = torch.full((self.capacity,), -1)  # trajectory id per row
        self._returns: dict[int, float] = {}  # r_e of the trajectories with stored rows
        self._window: list[float] = []  # W_k, sorted ascending
        self._next_id = 0
        self.num_offered = self.num_promoted = self.num_demonstrations = 0
        # stream -> chunks of its unfinished episode, concatenated once when it ends so
        # that per-step writes stay O(1)
        self._pending: dict[int, list[TensorDictBase]] = {}
        self._stored_rows: torch.Tensor | None = None
        if empty_write_count:
            self._write_count = 0

    @property
    def threshold(self) -> float:
        """The promotion threshold ``C = min(W_k)``, ``-inf`` while ``W_k`` is empty."""
        return self._window[0] if self._window else -math.inf

    @property
    def window(self) -> list[float]:
        """The rewards ``r_e`` in ``W_k``, sorted ascending."""
        return list(self._window)

    @property
    def returns(self) -> list[float]:
        """``r_e`` of the trajectories with at least one stored transition, sorted."""
        return sorted(self._returns.values())

    num_trajectories = property(lambda self: len(self._returns))
    num_transitions = property(lambda self: int(self.stored_rows().numel()))

    def stored_rows(self) -> torch.Tensor:
        """Sorted indices of the storage rows that hold a transition."""
        if self._stored_rows is None:
            self._stored_rows = self._row_trajectory.ge(0).nonzero().squeeze(-1)
        return self._stored_rows

    def add(self, data: TensorDictBase) -> torch.Tensor:
        """Appends one time step (``[]``, or ``[B]`` for ``B`` streams); see :meth:`extend`."""
        return self.extend(data.unsqueeze(-1)).squeeze(-1)

    def extend(self, data: TensorDictBase) -> torch.Tensor:
        """Offers every trajectory that ends in ``data``.

        Returns:
            the storage row of every step of ``data`` (shape ``data.shape``), ``-1`` where
            nothing was written (rejected, unfinished or masked steps).
        """
        index = torch.full(data.shape, -1, dtype=torch.long)
        if not data.batch_size.numel():
            return index
        streams, positions = self._streams(data)
        finished = []  # (end within this call, stream, trajectory, positions in data)
        for b, (stream, pos) in enumerate(zip(streams, positions, strict=True)):
            chunks = self._pending.pop(b, [])
            start = 0
            for end in self._ends(stream):
                finished.append((end, b, torch.cat([*chunks, stream[start:end]]), pos[start:end]))
                chunks, start = [], end
            if start < stream.shape[0]:
                # clone: a collector may overwrite the batch it yielded
                self._pending[b] = [*chunks, stream[start:].clone()]
            elif chunks:
                self._pending[b] = chunks
        written = []  # (positions in data, their rows, trajectory id)
        for _, _, trajectory, pos in sorted(finished, key=lambda item: item[:2]):
            rows = self._offer(trajectory, demonstration=False)
            if rows is not None and len(pos):
                written.append((pos, rows[-len(pos) :], self._next_id - 1))
        flat_index = index.view(-1)
        for pos, rows, tid in written:  # a later trajectory of this call may have evicted it
            flat_index[pos] = torch.where(self._row_trajectory[rows] == tid, rows, -1)
        return index

    def add_demonstrations(self, demonstrations: TensorDictBase) -> int:
        """Admits whole demonstration episodes without the promotion test.

        ``demonstrations`` is one or several episodes concatenated (``[N]``), or padded
        ``[n, T]`` with a ``("collector", "mask")``; every episode ends with ``done_key``.

        Returns:
            the number of demonstrations read (a top-K writer keeps only the K best).
        """
        count = 0
        for stream in self._streams(demonstrations)[0]:
            start = 0
            for end in self._ends(stream):
                self._offer(stream[start:end], demonstration=True)
                count, start = count + 1, end
            if start < stream.shape[0]:
                raise ValueError(
                    f"A demonstration ends with {stream.shape[0] - start} steps after its last "
                    f"{self.done_key}=True: demonstrations must be whole episodes."
                )
        return count

    def clear_unfinished(self) -> None:
        """Forgets the unfinished episode tails (e.g. when the env restarts on a new episode)."""
        self._pending = {}

    def _streams(self, data: TensorDictBase) -> tuple[list[TensorDictBase], list[torch.Tensor]]:
        """Per stream: the steps to read and their positions in ``data.view(-1)``."""
        length = data.shape[-1]
        mask = data.get(_MASK_KEY, None)
        data = data.select(*self._read_keys).reshape(-1, length)
        position = torch.arange(data.batch_size.numel()).view(-1, length)
        if mask is None:
            return list(data.unbind(0)), list(position.unbind(0))
        mask = mask.reshape(-1, length)
        return [d[m] for d, m in zip(data.unbind(0), mask, strict=True)], [
            p[m] for p, m in zip(position, mask, strict=True)
        ]

    def _ends(self, stream: TensorDictBase) -> list[int]:
        return (stream.get(self.done_key).reshape(-1).nonzero().squeeze(-1) + 1).tolist()

    def _offer(self, trajectory: TensorDictBase, demonstration: bool) -> torch.Tensor | None:
        r_e = float(trajectory.get(self.rank_key).to(torch.float64).sum())
        if demonstration:
            self.num_demonstrations += 1
        else:
            self.num_offered += 1
            if not r_e > self.threshold:  # Algorithm 1: ties with C are rejected
                return None
            self.num_promoted += 1
        return self._place(trajectory.select(*self.keys), r_e)

    def _place(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor | None:
        """Writes an admitted trajectory; returns its storage rows (``None`` if dropped)."""
        raise NotImplementedError

    def _write(self, rows: torch.Tensor, data: TensorDictBase) -> None:
        # set_cursor (default): the storage length grows as with TorchRL's RoundRobinWriter
        self._storage.set(rows.to(self._storage.device), data)
        self._write_count += rows.numel()
        self._stored_rows = None

    def _enter_window(self, r_e: float) -> None:
        """Keeps ``W_k`` the ``K`` best admitted rewards (the window of the ring and union rules)."""
        bisect.insort(self._window, r_e)
        if len(self._window) > self.k:
            self._window.pop(0)

    def _new_trajectory(self, r_e: float) -> int:
        tid = self._next_id
        self._next_id += 1
        self._returns[tid] = r_e
        return tid

    def state_dict(self) -> dict[str, Any]:
        return {
            "k": self.k,
            "capacity": self.capacity,
            "row_trajectory": self._row_trajectory.clone(),
            "returns": dict(self._returns),
            "window": list(self._window),
            "next_id": self._next_id,
            "counts": (self.num_offered, self.num_promoted, self.num_demonstrations),
            "write_count": self._write_count,
            "pending": {
                b: (sum(c.shape[0] for c in chunks), torch.cat(chunks).to_dict()) for b, chunks in self._pending.items()
            },
            **{name: getattr(self, name) for name in self._placement_state},
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        if (state_dict["k"], state_dict["capacity"]) != (self.k, self.capacity):
            raise ValueError(
                f"Cannot load a writer state with k={state_dict['k']}, capacity="
                f"{state_dict['capacity']} into one with k={self.k}, capacity={self.capacity}."
            )
        self._row_trajectory = state_dict["row_trajectory"].clone()
        self._returns = dict(state_dict["returns"])
        self._window = list(state_dict["window"])
        self._next_id = state_dict["next_id"]
        self.num_offered, self.num_promoted, self.num_demonstrations = state_dict["counts"]
        self._write_count = state_dict["write_count"]
        self._pending = {b: [TensorDict(data, batch_size=[n])] for b, (n, data) in state_dict["pending"].items()}
        for name in self._placement_state:
            setattr(self, name, state_dict[name])
        self._stored_rows = None

    def dumps(self, path) -> None:
        path = Path(path)
        path.mkdir(parents=True, exist_ok=True)
        torch.save(self.state_dict(), path / "writer_state.pt")

    def loads(self, path) -> None:
        self.load_state_dict(torch.load(Path(path) / "writer_state.pt", weights_only=True))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(k={self.k}, capacity={self.capacity}, threshold={self.threshold})"


class TopKTrajectoryWriter(TrajectoryWriter):
    """The teacher buffer as the paper's top-K window: the ``K`` best trajectories seen, demonstrations included.

    ``W_k`` is the set of rewards of the stored trajectories. Each trajectory gets a slot of
    ``max_trajectory_length`` rows; when all ``K`` slots are taken, an admitted trajectory
    replaces the worst stored one (the oldest among ties). With more than ``K``
    demonstrations only the ``K`` best are kept.

    Keyword Args:
        k (int): number of trajectories kept (the window size). Defaults to ``10``.
        max_trajectory_length (int): the longest trajectory accepted. Defaults to ``1000``
            (the MuJoCo time limit).
        **kwargs: ``keys``, ``rank_key``, ``done_key`` of :class:`TrajectoryWriter`.
    """

    _placement_state = ("_slots",)

    def __init__(self, *, k: int = 10, max_trajectory_length: int = 1000, **kwargs) -> None:
        self.max_trajectory_length = max_trajectory_length
        super().__init__(k=k, capacity=k * max_trajectory_length, **kwargs)

    def _empty(self, empty_write_count: bool = True) -> None:
        super()._empty(empty_write_count)
        self._slots: dict[int, int] = {}  # trajectory id -> slot

    def _place(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor | None:
        length, slot_length = trajectory.shape[0], self.max_trajectory_length
        if length > slot_length:
            raise ValueError(f"A trajectory of {length} steps exceeds max_trajectory_length={slot_length}.")
        if len(self._slots) < self.k:
            slot = min(set(range(self.k)) - set(self._slots.values()))
        else:
            victim = min(self._slots, key=lambda i: (self._returns[i], i))
            if r_e < self._returns[victim]:  # only a demonstration below the K stored ones
                return None
            slot = self._slots.pop(victim)
            self._window.remove(self._returns.pop(victim))
        slot_rows = torch.arange(slot * slot_length, (slot + 1) * slot_length)
        # The whole slot is written (zero padding after the trajectory): the storage length
        # then covers every slot in use, and the padding is never sampled.
        self._write(slot_rows, pad(trajectory, [0, slot_length - length]))
        tid = self._new_trajectory(r_e)
        self._slots[tid] = slot
        self._row_trajectory[slot_rows] = -1
        self._row_trajectory[slot_rows[:length]] = tid
        bisect.insort(self._window, r_e)
        return slot_rows[:length]


class _AppendingWriter(TrajectoryWriter):
    """A writer that appends admitted trajectories at a cursor (the ring and the union rules)."""

    _placement_state = ("_cursor",)

    def __init__(self, *, capacity: int, k: int = 10, **kwargs) -> None:
        super().__init__(k=k, capacity=capacity, **kwargs)

    def _empty(self, empty_write_count: bool = True) -> None:
        super()._empty(empty_write_count)
        self._cursor = 0


class FIFOTrajectoryWriter(_AppendingWriter):
    """The authors' teacher buffer: a FIFO ring of transitions with a score window of size K.

    Admitted trajectories are appended whole and overwrite the oldest transitions when the
    ring wraps, so partial trajectories can remain and a demonstration leaves only by
    wrapping. ``W_k`` is a separate list of the ``K`` best admitted rewards. Departure:
    the authors' first threshold is the first demonstration's score, not ``min(W_k)`` (the
    same with one demonstration), and they keep every demonstration score in the list.

    Keyword Args:
        capacity (int): number of transitions of the ring (authors: 1e4, Hopper 1e5).
        k (int): size of the score window. Defaults to ``10``.
        **kwargs: ``keys``, ``rank_key``, ``done_key`` of :class:`TrajectoryWriter`.
    """

    def _place(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor:
        length = trajectory.shape[0]
        if length > self.capacity:
            raise ValueError(f"A trajectory of {length} steps exceeds capacity={self.capacity}.")
        rows = (torch.arange(length) + self._cursor) % self.capacity
        overwritten = self._row_trajectory[rows].unique()
        self._write(rows, trajectory)
        self._row_trajectory[rows] = self._new_trajectory(r_e)
        alive = set(self._row_trajectory[self._row_trajectory.ge(0)].unique().tolist())
        for tid in overwritten.tolist():
            if tid >= 0 and tid not in alive:
                del self._returns[tid]
        self._cursor = (self._cursor + length) % self.capacity
        self._enter_window(r_e)
        return rows


class UnionTrajectoryWriter(_AppendingWriter):
    """The paper's literal rule: ``R_T <- R_T U tau``, every admitted trajectory is kept.

    Admitted trajectories are appended and never evicted, so sampling is uniform over the
    demonstrations and every promoted trajectory; ``W_k`` is a separate list of the ``K`` best
    admitted rewards (demonstrations included) and only sets the threshold ``C``. Size
    ``capacity`` for the demonstrations plus every frame the run can promote (its total frames):
    a trajectory that does not fit raises before anything is written.

    Keyword Args:
        capacity (int): number of transition rows (demonstration rows + the run's frames).
        k (int): size of the score window. Defaults to ``10``.
        **kwargs: ``keys``, ``rank_key``, ``done_key`` of :class:`TrajectoryWriter`.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import TeacherReplayBuffer, UnionTrajectoryWriter
        >>> def episode(r_e, T=5):
        ...     reward, done = torch.zeros(T, 1), torch.zeros(T, 1, dtype=torch.bool)
        ...     reward[-1], done[-1] = r_e, True
        ...     return TensorDict({"observation": torch.randn(T, 3), "action": torch.zeros(T, 2),
        ...         ("next", "observation"): torch.randn(T, 3), ("next", "reward"): reward,
        ...         ("next", "done"): done, ("next", "terminated"): done.clone(),
        ...         ("next", "truncated"): torch.zeros_like(done)}, batch_size=[T])
        >>> rb = TeacherReplayBuffer(UnionTrajectoryWriter(k=2, capacity=100), batch_size=4)
        >>> rb.add_demonstrations(episode(148.0))
        1
        >>> for r_e in (150.0, 147.0, 152.0, 149.0):  # 147 < C = 148, 149 < C = 150: rejected
        ...     _ = rb.extend(episode(r_e))
        >>> rb.writer.window, rb.writer.threshold  # the demonstration left W_k ...
        ([150.0, 152.0], 150.0)
        >>> rb.writer.returns, len(rb)  # ... but not R_T
        ([148.0, 150.0, 152.0], 15)
    """

    def _place(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor:
        length = trajectory.shape[0]
        if self._cursor + length > self.capacity:
            raise RuntimeError(
                f"The teacher buffer is full: {self._cursor} of its capacity={self.capacity} rows hold "
                f"trajectories and one of {length} steps was admitted. Size capacity for the "
                f"demonstrations plus every frame of the run."
            )
        rows = torch.arange(self._cursor, self._cursor + length)
        self._write(rows, trajectory)
        self._row_trajectory[rows] = self._new_trajectory(r_e)
        self._cursor += length
        self._enter_window(r_e)
        return rows


class _StoredRowSampler(RandomSampler):
    """Uniform sampling, with replacement, over the rows a :class:`TrajectoryWriter` filled."""

    def __init__(self, writer: TrajectoryWriter) -> None:
        self._writer = writer

    def sample(self, storage, batch_size: int) -> tuple[torch.Tensor, dict]:
        rows = self._writer.stored_rows()
        if not rows.numel():
            raise RuntimeError("The teacher buffer is empty: add the demonstrations first.")
        index = rows[torch.randint(rows.numel(), (batch_size,), generator=self._rng)]
        return index.to(storage.device), {}

    def _sampleable_count(self, storage, batch_size: int) -> int:
        return self._writer.num_transitions


class TeacherReplayBuffer(TensorDictReplayBuffer):
    """SAIL's teacher buffer R_T: demonstrations plus promoted agent trajectories.

    A :class:`~torchrl.data.TensorDictReplayBuffer` whose writer is a :class:`TrajectoryWriter`
    and whose sampler draws stored transitions uniformly, with replacement. Two write paths:
    :meth:`add_demonstrations` (always admitted) and ``extend`` (hence a collector given this
    buffer), which offers every finished trajectory to the promotion rule. The rule's state is
    read from ``rb.writer``; ``len(rb)`` is the number of stored transitions.

    Args:
        writer (TrajectoryWriter, optional): :class:`TopKTrajectoryWriter` (the K best
            trajectories, default ``TopKTrajectoryWriter(k=10)``), :class:`UnionTrajectoryWriter`
            (the paper's literal union) or :class:`FIFOTrajectoryWriter` (the authors' code).

    Keyword Args:
        device (torch.device or str): device of the storage. Defaults to ``"cpu"``.
        **kwargs: other :class:`~torchrl.data.TensorDictReplayBuffer` arguments
            (``batch_size``, ``transform``, ``generator``...).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import TeacherReplayBuffer, TopKTrajectoryWriter
        >>> def episode(r_e, T=5):
        ...     reward, done = torch.zeros(T, 1), torch.zeros(T, 1, dtype=torch.bool)
        ...     reward[-1], done[-1] = r_e, True  # the delayed reward, at the last step
        ...     return TensorDict({
        ...         "observation": torch.randn(T, 3), "action": torch.rand(T, 2) * 2 - 1,
        ...         ("next", "observation"): torch.randn(T, 3),
        ...         ("next", "reward"): reward, ("next", "done"): done,
        ...         ("next", "terminated"): done.clone(),
        ...         ("next", "truncated"): torch.zeros_like(done)}, batch_size=[T])
        >>> rb = TeacherReplayBuffer(TopKTrajectoryWriter(k=3, max_trajectory_length=10),
        ...                          batch_size=4)
        >>> rb.add_demonstrations(episode(148.0))
        1
        >>> for r_e in (100.0, 149.0, 150.0, 151.0, 149.0):
        ...     _ = rb.extend(episode(r_e))
        >>> rb.writer.window, rb.writer.threshold  # the demonstration (148) was evicted
        ([149.0, 150.0, 151.0], 149.0)
        >>> len(rb), rb.writer.num_offered, rb.writer.num_promoted
        (15, 5, 3)
        >>> rb.sample().batch_size
        torch.Size([4])
    """

    def __init__(self, writer: TrajectoryWriter | None = None, *, device="cpu", **kwargs) -> None:
        writer = TopKTrajectoryWriter() if writer is None else writer
        storage = LazyTensorStorage(writer.capacity, device=device)
        super().__init__(storage=storage, writer=writer, sampler=_StoredRowSampler(writer), **kwargs)

    def __len__(self) -> int:
        return self._writer.num_transitions

    def add_demonstrations(self, demonstrations: TensorDictBase) -> int:
        """Seeds the buffer with whole episodes, admitted without the test, after the buffer's
        transform's ``inv`` as :meth:`extend` does; see the writer's."""
        if self._transform is not None and len(self._transform):
            demonstrations = self._transform.inv(demonstrations)
        with self._replay_lock, self._write_lock:
            return self._writer.add_demonstrations(demonstrations)


class TopKTeacherReplayBuffer(TeacherReplayBuffer):
    """SAIL's teacher buffer as the paper describes it: the ``K`` best trajectories, threshold ``C = min W_k``.

    A :class:`TeacherReplayBuffer` over a :class:`TopKTrajectoryWriter`, built from the
    writer's arguments, as TorchRL's ``TensorDictPrioritizedReplayBuffer`` is a
    ``TensorDictReplayBuffer`` over a ``PrioritizedSampler``. Seed it with
    :meth:`~TeacherReplayBuffer.add_demonstrations`, give it every collector batch with
    ``extend`` (a trajectory is promoted when its reward ``r_e`` beats ``C``), sample it like any
    replay buffer, and read the rule's state from ``rb.writer``.

    Keyword Args:
        k (int): number of trajectories kept, the window ``W_k``. Defaults to ``10`` (the authors').
        max_trajectory_length (int): the longest trajectory accepted. Defaults to ``1000``.
        keys (sequence of NestedKey, optional): the entries stored per transition. Defaults
            to :data:`~torchrl_sail.TRANSITION_KEYS`.
        rank_key (NestedKey): the per-step entry summed into ``r_e``. Defaults to ``("next", "reward")``.
        done_key (NestedKey): the end-of-episode flag. Defaults to ``("next", "done")``.
        device (torch.device or str): device of the storage. Defaults to ``"cpu"``.
        **kwargs: other :class:`~torchrl.data.TensorDictReplayBuffer` arguments
            (``batch_size``, ``transform``, ``generator``...).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import TopKTeacherReplayBuffer
        >>> def episode(r_e, T=4):
        ...     reward, done = torch.zeros(T, 1), torch.zeros(T, 1, dtype=torch.bool)
        ...     reward[-1], done[-1] = r_e, True  # the delayed reward, at the last step
        ...     return TensorDict({"observation": torch.randn(T, 3), "action": torch.zeros(T, 2),
        ...         ("next", "observation"): torch.randn(T, 3), ("next", "reward"): reward,
        ...         ("next", "done"): done, ("next", "terminated"): done.clone(),
        ...         ("next", "truncated"): torch.zeros_like(done)}, batch_size=[T])
        >>> rb = TopKTeacherReplayBuffer(k=2, max_trajectory_length=10, batch_size=8)
        >>> rb.add_demonstrations(episode(100.0))
        1
        >>> for r_e in (90.0, 120.0, 130.0):  # 90 < C = 100: rejected; 130 evicts the demonstration
        ...     _ = rb.extend(episode(r_e))
        >>> rb.writer.window, rb.writer.threshold, len(rb)
        ([120.0, 130.0], 120.0, 8)
        >>> rb.sample()["observation"].shape
        torch.Size([8, 3])
    """

    def __init__(
        self,
        *,
        k: int = 10,
        max_trajectory_length: int = 1000,
        keys: list[NestedKey] | None = None,
        rank_key: NestedKey = ("next", "reward"),
        done_key: NestedKey = ("next", "done"),
        device="cpu",
        **kwargs,
    ) -> None:
        writer = TopKTrajectoryWriter(
            k=k, max_trajectory_length=max_trajectory_length, keys=keys, rank_key=rank_key, done_key=done_key
        )
        super().__init__(writer, device=device, **kwargs)
