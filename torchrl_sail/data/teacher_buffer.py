"""SAIL's teacher replay buffer R_T: whole trajectories kept by a top-K threshold rule.

SAIL (Algorithm 1 of the paper) seeds a teacher buffer R_T with the demonstrations and,
at the end of every agent episode, *promotes* the episode into R_T when its
trajectory-wise (delayed) reward ``r_e`` beats a threshold ``C``. ``C`` is the minimum of
a window ``W_k`` that tracks the ``K`` best trajectory rewards admitted so far, so it can
only rise and the teacher data keeps improving.

:class:`TopKTeacherReplayBuffer` is that buffer as a regular TorchRL
:class:`~torchrl.data.TensorDictReplayBuffer`: a flat
:class:`~torchrl.data.LazyTensorStorage` of transitions, a trajectory-aware
:class:`~torchrl.data.replay_buffers.writers.Writer` that applies the promotion rule,
evicts and keeps the row -> trajectory bookkeeping, and a
:class:`~torchrl.data.replay_buffers.samplers.Sampler` drawing transitions uniformly
among the rows that currently hold data. ``sample()``, ``batch_size``, transforms,
``len()``, ``state_dict()`` behave as for any TorchRL buffer.

Why not :class:`~torchrl.data.TensorDictMaxValueWriter`: it ranks one storage *slot*
at a time, so trajectories must be padded to a common length (ragged inputs crash it);
it has no FIFO mode (the authors' code); its ``state_dict`` raises
``NotImplementedError``; and it cannot express SAIL's rule (the threshold is the minimum
of a window of size K, and it rejects ties at the window boundary even when the buffer is
not full).
"""
from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.utils import NestedKey, unravel_key
from torchrl._utils import logger as torchrl_logger
from torchrl.data.replay_buffers import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.data.replay_buffers.samplers import Sampler
from torchrl.data.replay_buffers.storages import Storage
from torchrl.data.replay_buffers.writers import Writer

from torchrl_sail.data._keys import TRANSITION_KEYS

__all__ = ["TopKTeacherReplayBuffer"]

_MASK_KEY = ("collector", "mask")
_DEFAULT_KEYS = TRANSITION_KEYS
_EVICTIONS = ("topk", "fifo")
_WRITER_FILE = "teacher_writer.pt"


def _key_str(key: NestedKey) -> str:
    return repr(key if isinstance(key, str) else tuple(key))


class _TeacherWriter(Writer):
    """Trajectory-aware writer of :class:`TopKTeacherReplayBuffer` (private).

    It owns everything that is not transition data: the promotion rule, eviction, the
    row -> trajectory id map (``-1`` = free row), the returns of the stored trajectories,
    the score window ``W_k``, the counters, the FIFO cursor and the unfinished episode
    tails carried between two ``extend`` calls. The storage only ever holds transitions.

    Keyword Args:
        k (int): size of the window ``W_k`` (and number of trajectories kept in
            ``"topk"`` mode).
        eviction (str): ``"topk"`` or ``"fifo"``.
        max_trajectory_length (int): rows reserved per trajectory slot in ``"topk"`` mode.
        capacity (int): number of transition rows of the storage.

    Examples:
        >>> from torchrl_sail.data.teacher_buffer import _TeacherWriter
        >>> writer = _TeacherWriter(k=2, eviction="fifo", max_trajectory_length=5, capacity=8)
        >>> writer.threshold, writer.num_transitions
        (-inf, 0)
    """

    def __init__(
        self,
        *,
        k: int,
        eviction: Literal["topk", "fifo"],
        max_trajectory_length: int,
        capacity: int,
    ) -> None:
        super().__init__()
        self.k = k
        self.eviction = eviction
        self.max_trajectory_length = max_trajectory_length
        self.capacity = capacity
        self._empty()

    # ------------------------------------------------------------------ state
    def _empty(self, empty_write_count: bool = True) -> None:
        self._row_traj = torch.full((self.capacity,), -1, dtype=torch.long)
        # id -> r_e / number of stored rows / slot ("topk") for trajectories with >= 1 row
        self._traj_return: dict[int, float] = {}
        self._traj_rows: dict[int, int] = {}
        self._traj_slot: dict[int, int] = {}
        self._window: list[float] = []  # sorted ascending, at most k entries
        self._next_id = 0
        self._cursor = 0
        self._high_water = 0
        self.num_offered = 0
        self.num_promoted = 0
        self.num_demonstrations = 0
        # stream -> chunks of its unfinished episode (and their total length): chunks are
        # concatenated only when the episode ends, so per-step add() stays O(1) per step.
        self._pending: dict[int, list[TensorDictBase]] = {}
        self._pending_len: dict[int, int] = {}
        self._pending_streams = 0
        self._valid_cache: torch.Tensor | None = None
        if empty_write_count or not hasattr(self, "_write_count"):
            self._write_count = 0
        if self._storage is not None:
            self._storage._len = 0

    def _config(self) -> dict[str, Any]:
        return {
            "k": self.k,
            "eviction": self.eviction,
            "max_trajectory_length": self.max_trajectory_length,
            "capacity": self.capacity,
        }

    def state_dict(self) -> dict[str, Any]:
        ids = sorted(self._traj_return)
        return {
            "config": self._config(),
            "row_traj": self._row_traj.clone(),
            "traj_ids": ids,
            "traj_returns": [self._traj_return[i] for i in ids],
            "traj_rows": [self._traj_rows[i] for i in ids],
            "traj_slots": [self._traj_slot.get(i, -1) for i in ids],
            "window": list(self._window),
            "next_id": self._next_id,
            "cursor": self._cursor,
            "high_water": self._high_water,
            "num_offered": self.num_offered,
            "num_promoted": self.num_promoted,
            "num_demonstrations": self.num_demonstrations,
            "write_count": self._write_count,
            "pending_streams": self._pending_streams,
            "pending": [
                (stream, self._pending_len[stream], self.pending_episode(stream).to_dict())
                for stream in sorted(self._pending)
            ],
        }

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        config = dict(state_dict["config"])
        if config != self._config():
            raise ValueError(
                f"Cannot load a teacher buffer state saved with {config} into a buffer "
                f"built with {self._config()}: build the buffer with the same k, eviction, "
                "max_trajectory_length and capacity."
            )
        self._row_traj = state_dict["row_traj"].to(torch.long).clone()
        ids = [int(i) for i in state_dict["traj_ids"]]
        self._traj_return = {
            i: float(r) for i, r in zip(ids, state_dict["traj_returns"])
        }
        self._traj_rows = {i: int(n) for i, n in zip(ids, state_dict["traj_rows"])}
        self._traj_slot = {
            i: int(s) for i, s in zip(ids, state_dict["traj_slots"]) if int(s) >= 0
        }
        self._window = [float(r) for r in state_dict["window"]]
        self._next_id = int(state_dict["next_id"])
        self._cursor = int(state_dict["cursor"])
        self._high_water = int(state_dict["high_water"])
        self.num_offered = int(state_dict["num_offered"])
        self.num_promoted = int(state_dict["num_promoted"])
        self.num_demonstrations = int(state_dict["num_demonstrations"])
        self._write_count = int(state_dict["write_count"])
        self._pending_streams = int(state_dict["pending_streams"])
        self._pending = {
            int(stream): [TensorDict(data, batch_size=[int(length)])]
            for stream, length, data in state_dict["pending"]
        }
        self._pending_len = {
            int(stream): int(length) for stream, length, _ in state_dict["pending"]
        }
        self._valid_cache = None

    def dumps(self, path) -> None:
        path = Path(path)
        path.mkdir(parents=True, exist_ok=True)
        torch.save(self.state_dict(), path / _WRITER_FILE)

    def loads(self, path) -> None:
        self.load_state_dict(torch.load(Path(path) / _WRITER_FILE, weights_only=True))

    # -------------------------------------------------------------- queries
    def pending_episode(self, stream: int) -> TensorDictBase:
        """The unfinished episode of ``stream`` as one ``[T]`` tensordict."""
        chunks = self._pending[stream]
        return chunks[0] if len(chunks) == 1 else torch.cat(chunks, 0)

    def clear_pending(self) -> None:
        """Forgets every unfinished episode."""
        self._pending = {}
        self._pending_len = {}
        self._pending_streams = 0

    @property
    def threshold(self) -> float:
        return self._window[0] if self._window else -math.inf

    @property
    def num_transitions(self) -> int:
        return int(self.valid_rows().numel())

    @property
    def num_trajectories(self) -> int:
        return len(self._traj_return)

    def valid_rows(self) -> torch.Tensor:
        """Sorted indices of the storage rows that hold a transition."""
        if self._valid_cache is None:
            self._valid_cache = self._row_traj.ge(0).nonzero().squeeze(-1)
        return self._valid_cache

    def check_length(self, length: int, what: str) -> None:
        if self.eviction == "topk" and length > self.max_trajectory_length:
            raise ValueError(
                f"{what} has {length} steps, more than max_trajectory_length="
                f"{self.max_trajectory_length}: build the buffer with a larger "
                "max_trajectory_length."
            )
        if self.eviction == "fifo" and length > self.capacity:
            raise ValueError(
                f"{what} has {length} steps, more than the FIFO capacity={self.capacity} "
                "transitions: build the buffer with a larger capacity."
            )

    # --------------------------------------------------------------- writes
    def add(self, data: Any) -> int:
        raise RuntimeError(
            "_TeacherWriter writes whole trajectories: use TopKTeacherReplayBuffer.offer/"
            "extend/add_demonstrations."
        )

    def extend(self, data: Sequence) -> torch.Tensor:
        raise RuntimeError(
            "_TeacherWriter writes whole trajectories: use TopKTeacherReplayBuffer.offer/"
            "extend/add_demonstrations."
        )

    def admit(
        self, trajectory: TensorDictBase, r_e: float, *, demonstration: bool
    ) -> torch.Tensor | None:
        """Applies the promotion rule to one whole trajectory.

        Demonstrations are always admitted; agent trajectories only if ``r_e > C``.
        Returns the storage rows written, or ``None`` when nothing was written.
        """
        if demonstration:
            self.num_demonstrations += 1
        else:
            self.num_offered += 1
            # Algorithm 1: strict comparison, ties with C are rejected.
            if not r_e > self.threshold:
                return None
            self.num_promoted += 1
        if self.eviction == "topk":
            return self._write_topk(trajectory, r_e)
        return self._write_fifo(trajectory, r_e)

    def _write_rows(self, rows: torch.Tensor, trajectory: TensorDictBase, tid: int):
        self._row_traj[rows] = tid
        device = self._storage.device
        index = rows if not isinstance(device, torch.device) else rows.to(device)
        # set_cursor=False: the storage must not grow its length by len(rows) (rows are
        # reused); the last cursor is still recorded for TorchRL's checkpointers.
        self._storage.set(index, trajectory, set_cursor=False)
        self._storage._set_last_cursor(index)
        # The storage's length is a high-water mark (it slices [:len] on reads); which
        # rows are live is tracked by ``_row_traj`` and exposed through ``__len__``.
        self._high_water = max(self._high_water, int(rows.max()) + 1)
        self._storage._len = self._high_water
        self._write_count += rows.numel()
        self._valid_cache = None

    def _write_topk(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor | None:
        tid = self._next_id
        self._next_id += 1
        if len(self._traj_slot) < self.k:
            used = set(self._traj_slot.values())
            slot = next(s for s in range(self.k) if s not in used)
        else:
            # Evict the worst trajectory, the oldest one among ties.
            victim = min(self._traj_slot, key=lambda i: (self._traj_return[i], i))
            if r_e < self._traj_return[victim]:
                # Only reachable for a demonstration below the K stored ones.
                return None
            slot = self._traj_slot.pop(victim)
            self._window.remove(self._traj_return.pop(victim))
            del self._traj_rows[victim]
            start = slot * self.max_trajectory_length
            self._row_traj[start : start + self.max_trajectory_length] = -1
        length = trajectory.shape[0]
        rows = torch.arange(length) + slot * self.max_trajectory_length
        self._write_rows(rows, trajectory, tid)
        self._traj_slot[tid] = slot
        self._traj_return[tid] = r_e
        self._traj_rows[tid] = length
        bisect.insort(self._window, r_e)
        return rows

    def _write_fifo(self, trajectory: TensorDictBase, r_e: float) -> torch.Tensor:
        tid = self._next_id
        self._next_id += 1
        length = trajectory.shape[0]
        rows = (torch.arange(length) + self._cursor) % self.capacity
        overwritten = self._row_traj[rows]
        overwritten = overwritten[overwritten >= 0]
        if overwritten.numel():
            old_ids, counts = torch.unique(overwritten, return_counts=True)
            for old, count in zip(old_ids.tolist(), counts.tolist()):
                self._traj_rows[old] -= count
                if self._traj_rows[old] == 0:
                    del self._traj_rows[old]
                    del self._traj_return[old]
        self._write_rows(rows, trajectory, tid)
        self._cursor = (self._cursor + length) % self.capacity
        self._traj_return[tid] = r_e
        self._traj_rows[tid] = length
        # Authors' window: once full, drop the lowest score and insert the new one.
        bisect.insort(self._window, r_e)
        if len(self._window) > self.k:
            self._window.pop(0)
        return rows

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(k={self.k}, eviction={self.eviction!r}, "
            f"threshold={self.threshold}, trajectories={self.num_trajectories})"
        )


class _ValidRowSampler(Sampler):
    """Uniform sampler, with replacement, over the rows that hold a transition (private).

    Freed rows (evicted trajectories in ``"topk"`` mode, never-written rows) are never
    returned. The set of valid rows belongs to the writer, so this sampler keeps no state.

    Args:
        writer (_TeacherWriter): the writer whose row bookkeeping defines the valid rows.

    Examples:
        >>> from torchrl_sail.data.teacher_buffer import _TeacherWriter, _ValidRowSampler
        >>> sampler = _ValidRowSampler(
        ...     _TeacherWriter(k=1, eviction="topk", max_trajectory_length=3, capacity=3))
        >>> sampler.state_dict()
        {}
    """

    def __init__(self, writer: _TeacherWriter) -> None:
        self._writer = writer

    def sample(self, storage: Storage, batch_size: int) -> tuple[torch.Tensor, dict]:
        valid = self._writer.valid_rows()
        if valid.numel() == 0:
            raise RuntimeError(
                "Cannot sample from an empty TopKTeacherReplayBuffer: call "
                "add_demonstrations(...) first."
            )
        pick = torch.randint(valid.numel(), (batch_size,), generator=self._rng)
        index = valid[pick]
        device = getattr(storage, "device", None)
        if isinstance(device, torch.device):
            index = index.to(device)
        return index, {}

    def _sampleable_count(self, storage: Storage, batch_size: int) -> int:
        return self._writer.num_transitions

    def _empty(self) -> None:
        return

    def state_dict(self) -> dict[str, Any]:
        return {}

    def load_state_dict(self, state_dict: dict[str, Any]) -> None:
        return

    def dumps(self, path) -> None:
        return

    def loads(self, path) -> None:
        return


class TopKTeacherReplayBuffer(TensorDictReplayBuffer):
    """SAIL's teacher replay buffer R_T: demonstrations plus promoted agent trajectories.

    The buffer stores *whole* trajectories (a trajectory is a ``[T]`` tensordict of
    transitions whose last step has ``done_key`` set) in a flat storage of transitions and
    samples transitions uniformly, with replacement, among the stored ones.

    It is seeded with the demonstrations (:meth:`add_demonstrations`), which are always
    admitted. An agent trajectory with trajectory-wise reward ``r_e`` is promoted
    (:meth:`offer`) iff ``r_e > C`` (strict), where ``C = min(W_k)`` and ``W_k`` is a window
    of the ``K`` best ``r_e`` admitted so far (``C = -inf`` while ``W_k`` is empty). ``r_e``
    is the sum of ``rank_key`` over the trajectory; with the default ``("next", "reward")``
    after :class:`~torchrl_sail.DelayedRewardTransform` that is the delayed reward
    ``floor(0.1 * R)``. Demonstrations are ranked the same way from their recorded
    rewards: pass them with delayed rewards. Dense returns are never looked at.

    Two eviction policies:

    - ``"topk"`` (default, the paper's top-K): the buffer holds exactly the ``K`` best
      trajectories seen, demonstrations included. When full, a promoted trajectory evicts
      the current worst one (the oldest among ties), and ``W_k`` is the set of returns of
      the stored trajectories. Each trajectory gets a slot of ``max_trajectory_length``
      rows, so the storage holds ``K * max_trajectory_length`` transitions. With more
      demonstrations than ``K``, only the ``K`` best are kept.
    - ``"fifo"`` (the authors' code, ``illidanlab/SAIL``): a transition-level FIFO ring of
      ``capacity`` transitions (authors: 1e4, Hopper 1e5). Promoted trajectories are
      appended whole and overwrite the oldest transitions when the ring wraps, so partial
      trajectories can remain and the demonstration leaves only by wrapping. ``W_k`` is a
      separate score window of size ``K`` (authors: K=10): on admission the score is
      inserted and, beyond ``K`` entries, the lowest is dropped. Departure: the authors'
      initial threshold is the *first* demonstration's score (their list is only sorted
      after the first promotion), not the minimum; we use ``min(W_k)`` from the start,
      which only differs with several demonstrations. They also keep every demonstration
      score in the list even beyond K; we keep the K best.

    Writes go through the promotion rule whatever the entry point: :meth:`extend` (hence a
    collector given this buffer) splits its input into trajectories and offers each one,
    so nothing can bypass the threshold. Only the ``keys`` are stored; any other entry
    (collector ids, ``"episode_return"``, ``"step_count"``...) is dropped, so
    demonstrations and agent trajectories are stored alike. Samples hold the stored keys
    plus the ``"index"`` of the sampled rows.

    Keyword Args:
        k (int): size ``K`` of the window ``W_k``. Defaults to ``10`` (the authors' value).
        eviction (str): ``"topk"`` (default) or ``"fifo"``, see above.
        max_trajectory_length (int): the longest trajectory accepted in ``"topk"`` mode
            (rows reserved per trajectory). Defaults to ``1000`` (MuJoCo time limit).
            Unused in ``"fifo"`` mode.
        capacity (int): number of transitions of the FIFO ring; required in ``"fifo"``
            mode, must be left ``None`` (it is ``k * max_trajectory_length``) in ``"topk"``
            mode.
        batch_size (int, optional): default number of transitions returned by
            :meth:`sample`.
        rank_key (NestedKey): the per-step entry summed into ``r_e``. Defaults to
            ``("next", "reward")``.
        done_key (NestedKey): the per-step end-of-episode flag used to split
            trajectories. Defaults to ``("next", "done")``.
        keys (sequence of NestedKey, optional): the entries stored for each transition.
            Defaults to ``"observation"``, ``"action"``, ``("next", "observation")``,
            ``("next", "reward")``, ``("next", "done")``, ``("next", "terminated")``,
            ``("next", "truncated")``. A trajectory missing one of them raises a
            ``KeyError``.
        transform (Transform, optional): applied to sampled batches (and inverted on
            writes), as for any TorchRL buffer.
        device (torch.device or str): device of the storage. Defaults to ``"cpu"``.
        **kwargs: other :class:`~torchrl.data.TensorDictReplayBuffer` keyword arguments
            (``generator``, ``pin_memory``, ``prefetch``...). ``storage``, ``sampler`` and
            ``writer`` are built by this class and cannot be passed.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import TopKTeacherReplayBuffer
        >>> def episode(r_e, T=5):
        ...     reward = torch.zeros(T, 1)
        ...     reward[-1] = r_e  # delayed reward: r_e at the last step only
        ...     done = torch.zeros(T, 1, dtype=torch.bool)
        ...     done[-1] = True
        ...     return TensorDict({
        ...         "observation": torch.randn(T, 3), "action": torch.rand(T, 2) * 2 - 1,
        ...         ("next", "observation"): torch.randn(T, 3),
        ...         ("next", "reward"): reward, ("next", "done"): done,
        ...         ("next", "terminated"): done.clone(),
        ...         ("next", "truncated"): torch.zeros_like(done),
        ...         "step_count": torch.arange(T).unsqueeze(-1)}, batch_size=[T])
        >>> rb = TopKTeacherReplayBuffer(k=3, max_trajectory_length=10, batch_size=4)
        >>> rb.add_demonstrations(episode(148.0))
        1
        >>> rb.threshold
        148.0
        >>> [rb.offer(episode(r)) for r in (100.0, 149.0, 150.0, 151.0, 149.0)]
        [False, True, True, True, False]
        >>> rb.window, rb.threshold  # the demonstration (148) was evicted
        ([149.0, 150.0, 151.0], 149.0)
        >>> len(rb), rb.num_trajectories, rb.num_offered, rb.num_promoted
        (15, 3, 5, 3)
        >>> batch = rb.sample()
        >>> batch.batch_size, "step_count" in batch.keys()
        (torch.Size([4]), False)
    """

    def __init__(
        self,
        *,
        k: int = 10,
        eviction: Literal["topk", "fifo"] = "topk",
        max_trajectory_length: int = 1000,
        capacity: int | None = None,
        batch_size: int | None = None,
        rank_key: NestedKey = ("next", "reward"),
        done_key: NestedKey = ("next", "done"),
        keys: Sequence[NestedKey] | None = None,
        transform=None,
        device: torch.device | str = "cpu",
        **kwargs,
    ) -> None:
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise ValueError(f"k (size of the top-K window) must be an int >= 1, got {k!r}.")
        if eviction not in _EVICTIONS:
            raise ValueError(f"eviction must be one of {_EVICTIONS}, got {eviction!r}.")
        if (
            isinstance(max_trajectory_length, bool)
            or not isinstance(max_trajectory_length, int)
            or max_trajectory_length < 1
        ):
            raise ValueError(
                f"max_trajectory_length must be an int >= 1, got {max_trajectory_length!r}."
            )
        if eviction == "fifo":
            if capacity is None:
                raise ValueError(
                    "eviction='fifo' needs capacity= (number of transitions of the ring; "
                    "the authors use 10_000, 100_000 for Hopper)."
                )
            if isinstance(capacity, bool) or int(capacity) != capacity or capacity < 1:
                raise ValueError(f"capacity must be an int >= 1, got {capacity!r}.")
            capacity = int(capacity)
        else:
            if capacity is not None:
                raise ValueError(
                    "capacity is only used with eviction='fifo'; in 'topk' mode the buffer "
                    f"holds k * max_trajectory_length = {k * max_trajectory_length} "
                    f"transitions. Got capacity={capacity!r}: leave it None."
                )
            capacity = k * max_trajectory_length
        for name in ("storage", "sampler", "writer"):
            if name in kwargs:
                raise TypeError(
                    f"TopKTeacherReplayBuffer builds its own {name}; do not pass {name}=."
                )
        self._rank_key = unravel_key(rank_key)
        self._done_key = unravel_key(done_key)
        stored = _DEFAULT_KEYS if keys is None else keys
        self._stored_keys = list(dict.fromkeys(unravel_key(key) for key in stored))
        if not self._stored_keys:
            raise ValueError("keys must name at least one entry to store.")
        self._needed_keys = list(
            dict.fromkeys([*self._stored_keys, self._rank_key, self._done_key])
        )
        self._teacher_writer = _TeacherWriter(
            k=k,
            eviction=eviction,
            max_trajectory_length=max_trajectory_length,
            capacity=capacity,
        )
        super().__init__(
            storage=LazyTensorStorage(capacity, device=device),
            sampler=_ValidRowSampler(self._teacher_writer),
            writer=self._teacher_writer,
            batch_size=batch_size,
            transform=transform,
            **kwargs,
        )

    # ------------------------------------------------------------- logging
    @property
    def k(self) -> int:
        """Size K of the window W_k."""
        return self._teacher_writer.k

    @property
    def eviction(self) -> str:
        """``"topk"`` or ``"fifo"``."""
        return self._teacher_writer.eviction

    @property
    def capacity(self) -> int:
        """Number of transition rows of the storage."""
        return self._teacher_writer.capacity

    @property
    def threshold(self) -> float:
        """The promotion threshold C = min(W_k), ``-inf`` while W_k is empty."""
        return self._teacher_writer.threshold

    @property
    def window(self) -> list[float]:
        """The trajectory rewards r_e in W_k, sorted ascending."""
        return list(self._teacher_writer._window)

    @property
    def returns(self) -> list[float]:
        """r_e of the trajectories with at least one stored transition, sorted ascending.

        In ``"topk"`` mode this equals :attr:`window`; in ``"fifo"`` mode it includes
        partially overwritten trajectories.
        """
        return sorted(self._teacher_writer._traj_return.values())

    @property
    def num_trajectories(self) -> int:
        """Number of trajectories with at least one stored transition."""
        return self._teacher_writer.num_trajectories

    @property
    def num_transitions(self) -> int:
        """Number of stored transitions (``== len(self)``)."""
        return self._teacher_writer.num_transitions

    @property
    def num_offered(self) -> int:
        """Number of finished agent trajectories offered (demonstrations excluded)."""
        return self._teacher_writer.num_offered

    @property
    def num_promoted(self) -> int:
        """Number of agent trajectories promoted into the buffer (demonstrations excluded)."""
        return self._teacher_writer.num_promoted

    @property
    def num_demonstrations(self) -> int:
        """Number of demonstration trajectories admitted through :meth:`add_demonstrations`."""
        return self._teacher_writer.num_demonstrations

    @property
    def stored_keys(self) -> list[NestedKey]:
        """The entries stored for every transition."""
        return list(self._stored_keys)

    def __len__(self) -> int:
        return self._teacher_writer.num_transitions

    def transitions(self) -> TensorDictBase:
        """All stored transitions, in storage-row order (no transform applied).

        Useful to inspect the teacher data or to compute statistics on it (e.g. to
        initialise an observation normaliser).
        """
        self._ensure_init()
        rows = self._teacher_writer.valid_rows()
        if rows.numel() == 0:
            raise RuntimeError("The teacher buffer is empty.")
        with self._replay_lock:
            return self._storage.get(rows.to(self._storage.device))

    # -------------------------------------------------------------- writes
    def add_demonstrations(self, demonstrations: TensorDictBase) -> int:
        """Seeds the buffer with demonstration trajectories; they are always admitted.

        Args:
            demonstrations (TensorDictBase): one trajectory ``[T]``, several concatenated
                ``[N]`` (split after each ``done_key``), or padded ``[n, T]`` with a bool
                ``("collector", "mask")``. Every trajectory must end with ``done_key``
                set. Rank them by their delayed reward (as agent trajectories are).

        Returns:
            the number of demonstration trajectories admitted. In ``"topk"`` mode, those
            beyond the K best are dropped at once (a warning is logged).
        """
        self._ensure_init()
        td, mask = self._prepare(demonstrations)
        trajectories = []
        for i, stream in enumerate(self._streams(td, mask)):
            segments, tail = self._split(stream)
            if tail is not None:
                raise ValueError(
                    f"Demonstration stream {i} ends with {tail.shape[0]} steps after its "
                    f"last {_key_str(self._done_key)}=True: demonstrations must be whole "
                    "episodes (set done on the last step of each)."
                )
            trajectories.extend(segments)
        self._check_lengths(trajectories, "A demonstration trajectory")
        with self._replay_lock, self._write_lock:
            written = [
                self._teacher_writer.admit(
                    trajectory.select(*self._stored_keys),
                    self._trajectory_reward(trajectory),
                    demonstration=True,
                )
                for trajectory in trajectories
            ]
        dropped = sum(rows is None for rows in written)
        if dropped:
            torchrl_logger.warning(
                f"TopKTeacherReplayBuffer: {dropped} of {len(trajectories)} demonstrations "
                f"ranked below the k={self.k} stored trajectories and were not kept."
            )
        return len(trajectories)

    def offer(self, trajectory: TensorDictBase) -> bool:
        """The promotion test of Algorithm 1 for one finished trajectory.

        Args:
            trajectory (TensorDictBase): one whole trajectory, ``[T]`` or padded ``[1, T]``
                / ``[T]`` with a bool ``("collector", "mask")``; its last (valid) step has
                ``done_key`` set and no earlier step does.

        Returns:
            whether the trajectory was promoted (``r_e > C``).
        """
        self._ensure_init()
        td, mask = self._prepare(trajectory)
        streams = self._streams(td, mask)
        pieces = [self._split(stream) for stream in streams]
        segments = [seg for segs, _ in pieces for seg in segs]
        if len(segments) != 1 or any(tail is not None for _, tail in pieces):
            raise ValueError(
                f"offer() takes exactly one finished trajectory (its last step, and only "
                f"it, has {_key_str(self._done_key)}=True); got {len(segments)} finished "
                f"trajectories and {sum(tail is not None for _, tail in pieces)} unfinished "
                f"ones in a tensordict of shape {tuple(trajectory.shape)}. Use "
                "offer_many()/extend() for several trajectories."
            )
        self._check_lengths(segments, "The offered trajectory")
        return self._admit_many(segments)[0] is not None

    def offer_many(self, tensordicts: TensorDictBase) -> torch.Tensor:
        """Offers every trajectory finished in ``tensordicts``; see :meth:`extend`.

        Returns:
            a bool tensor with one promotion decision per finished trajectory, in the
            order they were offered.
        """
        rows = self._offer_stream_batch(tensordicts)
        return torch.tensor([r is not None for r in rows], dtype=torch.bool)

    def extend(
        self, tensordicts: TensorDictBase, *, update_priority: bool | None = None
    ) -> torch.Tensor:
        """Splits ``tensordicts`` into trajectories and offers each finished one.

        Nothing is written without passing the promotion rule, so a collector writing
        into this buffer cannot bypass the threshold.

        - A ``[T]`` (one stream) or ``[B, T]`` (``B`` streams, time last, e.g. a collector
          batch) input is split after each ``done_key``. Trajectories are offered in the
          order they finish (time step, then stream). The unfinished tail of each stream
          is kept and prepended to the same stream at the next call, so episodes spanning
          collector batches are offered whole once they end (the number of streams must
          then stay the same).
        - A padded ``[n, T]`` input with ``("collector", "mask")`` holds one trajectory
          per row (``split_trajectories`` output); every row must be finished.

        Args:
            tensordicts (TensorDictBase): the transitions, see above.

        Keyword Args:
            update_priority: unsupported (the buffer is not prioritized), must be ``None``.

        Returns:
            the storage rows written for the promoted trajectories (a 1-D long tensor,
            empty if none was promoted). Unlike other TorchRL buffers, no ``"index"`` entry
            is written into ``tensordicts``.
        """
        if update_priority is not None:
            raise ValueError(
                "TopKTeacherReplayBuffer is not prioritized: update_priority must be None."
            )
        rows = [r for r in self._offer_stream_batch(tensordicts) if r is not None]
        if not rows:
            return torch.zeros(0, dtype=torch.long)
        return torch.cat(rows)

    def add(self, data: TensorDictBase) -> torch.Tensor:
        """Appends one time step to the episodes in progress.

        ``data`` is one transition (``batch_size=[]``, a single stream) or one step of
        ``B`` environments (``batch_size=[B]``, ``B`` streams), as a collector with
        ``extend_buffer=False`` writes it. Equivalent to ``extend(data.unsqueeze(-1))``:
        an episode is offered once its transition with ``done_key`` set arrives. The
        steps of an unfinished episode are kept as a list of chunks and concatenated
        once, when it ends, so the cost per step does not grow with the episode length.
        """
        if not isinstance(data, TensorDictBase) or data.batch_dims > 1:
            raise ValueError(
                "TopKTeacherReplayBuffer.add takes one time step (a TensorDict with "
                "batch_size=[] or [num_envs]); use extend()/offer() for trajectories, got "
                f"{type(data).__name__} with shape {tuple(getattr(data, 'shape', ()))}."
            )
        if self._transform is None or not len(self._transform):
            # Drop the keys that are not stored before reshaping (the transform, if any,
            # must see the full step).
            data = data.select(*self._needed_keys, _MASK_KEY, strict=False)
        return self.extend(data.unsqueeze(-1))

    def __setitem__(self, index, value) -> None:
        raise RuntimeError(
            "TopKTeacherReplayBuffer cannot be written by index: use offer(), extend() or "
            "add_demonstrations(), which keep the trajectory bookkeeping and the "
            "promotion rule consistent."
        )

    def clear_unfinished(self) -> None:
        """Drops the unfinished episode tails kept between two :meth:`extend` calls."""
        self._teacher_writer.clear_pending()

    # ------------------------------------------------------------ helpers
    def _ensure_init(self) -> None:
        if not self._initialized:
            self._init()

    def _prepare(self, td: TensorDictBase) -> tuple[TensorDictBase, torch.Tensor | None]:
        if not isinstance(td, TensorDictBase):
            raise TypeError(
                "TopKTeacherReplayBuffer expects a TensorDict of transitions, got "
                f"{type(td).__name__}."
            )
        if self._transform is not None and len(self._transform):
            td = self._transform.inv(td)
        mask = td.get(_MASK_KEY, None)
        for key in self._needed_keys:
            # direct lookups: listing every key costs more than the rest of a per-step add()
            if td.get(key, None) is None:
                raise KeyError(
                    f"The trajectory has no entry {_key_str(key)}, which the teacher buffer "
                    f"needs (stored keys: {[_key_str(k) for k in self._stored_keys]}, "
                    f"rank_key={_key_str(self._rank_key)}, done_key="
                    f"{_key_str(self._done_key)}). Add it or build the buffer with other keys=."
                )
        if td.batch_dims == 0:
            raise ValueError(
                "Expected a trajectory with a time dimension (batch_size=[T]), got "
                "batch_size=[]; use add() for a single transition."
            )
        return td.select(*self._needed_keys), mask

    def _streams(
        self, td: TensorDictBase, mask: torch.Tensor | None
    ) -> list[TensorDictBase]:
        if mask is None:
            if td.batch_dims == 1:
                return [td]
            return list(td.reshape(-1, td.shape[-1]).unbind(0))
        if mask.dtype != torch.bool or mask.numel() != td.numel():
            raise ValueError(
                f"{_key_str(_MASK_KEY)} must be a bool tensor with one entry per step "
                f"(shape {tuple(td.shape)}), got dtype {mask.dtype} and shape {tuple(mask.shape)}."
            )
        mask = mask.reshape(td.shape)
        if td.batch_dims == 1:
            return [td[mask]]
        rows = td.reshape(-1, td.shape[-1])
        masks = mask.reshape(-1, td.shape[-1])
        return [row[m] for row, m in zip(rows.unbind(0), masks.unbind(0))]

    def _split(
        self, stream: TensorDictBase
    ) -> tuple[list[TensorDictBase], TensorDictBase | None]:
        length = stream.shape[0]
        done = stream.get(self._done_key)
        if done.numel() != length:
            raise ValueError(
                f"{_key_str(self._done_key)} must have one flag per step (shape [T] or "
                f"[T, 1]), got shape {tuple(done.shape)} for {length} steps."
            )
        ends = (done.reshape(length).bool().nonzero().squeeze(-1) + 1).tolist()
        segments, start = [], 0
        for end in ends:
            segments.append(stream[start:end])
            start = end
        if start == 0:
            # No done in the stream (every step of a per-step add()): skip the indexing.
            tail = stream if length else None
        else:
            tail = stream[start:] if start < length else None
        return segments, tail

    def _trajectory_reward(self, trajectory: TensorDictBase) -> float:
        return float(trajectory.get(self._rank_key).to(torch.float64).sum())

    def _check_lengths(self, trajectories: list[TensorDictBase], what: str) -> None:
        for trajectory in trajectories:
            self._teacher_writer.check_length(trajectory.shape[0], what)

    def _admit_many(self, trajectories: list[TensorDictBase]) -> list[torch.Tensor | None]:
        with self._replay_lock, self._write_lock:
            return [
                self._teacher_writer.admit(
                    trajectory.select(*self._stored_keys),
                    self._trajectory_reward(trajectory),
                    demonstration=False,
                )
                for trajectory in trajectories
            ]

    def _offer_stream_batch(self, tensordicts: TensorDictBase) -> list[torch.Tensor | None]:
        self._ensure_init()
        td, mask = self._prepare(tensordicts)
        streams = self._streams(td, mask)
        writer = self._teacher_writer
        if mask is not None:
            finished = []
            for i, stream in enumerate(streams):
                segments, tail = self._split(stream)
                if tail is not None:
                    raise ValueError(
                        f"Row {i} of the padded input ends with {tail.shape[0]} steps without "
                        f"{_key_str(self._done_key)}=True. Padded inputs must hold finished "
                        "trajectories; pass the unpadded [B, T] collector batch to extend() "
                        "to have unfinished episodes completed across calls."
                    )
                finished.extend(segments)
            self._check_lengths(finished, "An offered trajectory")
            return self._admit_many(finished)
        if writer._pending and len(streams) != writer._pending_streams:
            raise ValueError(
                f"extend() got {len(streams)} streams but unfinished episodes are pending "
                f"from a batch with {writer._pending_streams} streams; keep the batch shape, "
                "or call clear_unfinished() first."
            )
        # (end time in this batch, stream, trajectory): offered in the order they finish
        finished: list[tuple[int, int, TensorDictBase]] = []
        tails: dict[int, list[TensorDictBase]] = {}
        tail_lens: dict[int, int] = {}
        for b, stream in enumerate(streams):
            chunks = writer._pending.get(b, [])
            pending_len = writer._pending_len.get(b, 0)
            segments, tail = self._split(stream)
            if segments and chunks:
                # The episode carried over from earlier calls ends in this batch: the
                # only place its chunks are concatenated.
                finished.append(
                    (segments[0].shape[0], b, torch.cat([*chunks, segments[0]], 0))
                )
                chunks, pending_len = [], 0
            elif segments:
                finished.append((segments[0].shape[0], b, segments[0]))
            end = segments[0].shape[0] if segments else 0
            for segment in segments[1:]:
                end += segment.shape[0]
                finished.append((end, b, segment))
            if tail is not None:
                length = pending_len + tail.shape[0]
                self._teacher_writer.check_length(
                    length, f"The unfinished episode of stream {b}"
                )
                # clone: the input may be a view the caller (or collector) overwrites.
                tails[b] = [*chunks, tail.clone()]
                tail_lens[b] = length
            elif chunks and not segments:
                # A zero-length batch: the episode in progress is unchanged.
                tails[b], tail_lens[b] = chunks, pending_len
        self._check_lengths([seg for _, _, seg in finished], "An offered trajectory")
        finished.sort(key=lambda item: item[:2])
        writer._pending = tails
        writer._pending_len = tail_lens
        writer._pending_streams = len(streams) if tails else 0
        return self._admit_many([seg for _, _, seg in finished])
