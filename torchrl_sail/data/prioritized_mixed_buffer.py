"""Prioritized sampling over a fixed demonstration buffer and the agent's replay together (DDPGfD).

DDPGfD (Vecerik et al. 2017) keeps its demonstrations in the replay for good and samples them
beside the agent's transitions by prioritized experience replay (Schaul et al. 2016), each
demonstration's priority raised by a constant bonus, so the demonstration share of a batch
follows the priorities instead of a fixed ratio. TorchRL's
:class:`~torchrl.data.PrioritizedSampler` prioritizes the rows of one storage; here the
demonstrations stay in their own buffer (never evicted by the agent's ring) and one priority
tree spans both buffers' rows, so a draw and its importance weight are those of PER over the
union.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torchrl.data.replay_buffers import ReplayBuffer, TensorStorage

from torchrl_sail._compat import storage_tensordict
from torchrl_sail.data.keys import TRANSITION_KEYS

__all__ = ["PrioritizedMixedReplayBuffer"]


class _PriorityTree:
    """Sum and min segment trees over ``size`` leaves (float64): set leaves, read the root, find by mass.

    Unset leaves hold 0 in the sum tree and ``inf`` in the min tree, so the roots are the sum and
    the min over the leaves set so far.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.width = 1 << max(0, (size - 1).bit_length())  # leaves: [width, width + size)
        self.sum = np.zeros(2 * self.width)
        self.min = np.full(2 * self.width, np.inf)

    def set(self, position: np.ndarray, value: np.ndarray) -> None:
        self._write(position, value, value)

    def clear(self, position: np.ndarray) -> None:
        """Unsets leaves: 0 in the sum tree, ``inf`` in the min tree."""
        self._write(position, 0.0, np.inf)

    def _write(self, position: np.ndarray, sum_value, min_value) -> None:
        node = position + self.width
        self.sum[node], self.min[node] = sum_value, min_value
        for _ in range(self.width.bit_length() - 1):  # every level from the leaves' parents to the root
            # a parent listed twice gets the same value twice: no need to deduplicate
            node //= 2
            self.sum[node] = self.sum[2 * node] + self.sum[2 * node + 1]
            self.min[node] = np.minimum(self.min[2 * node], self.min[2 * node + 1])

    def leaves(self, position: np.ndarray) -> np.ndarray:
        return self.sum[position + self.width]

    @property
    def total(self) -> float:
        return float(self.sum[1])

    @property
    def minimum(self) -> float:
        return float(self.min[1])

    def find(self, mass: np.ndarray, count: int) -> np.ndarray:
        """The leaf ``i`` whose interval ``[S_{i-1}, S_i)`` of the prefix sums holds each mass, when
        the leaves set are the first ``count``."""
        node = np.ones(mass.shape, dtype=np.int64)
        mass = mass.copy()
        while node[0] < self.width:
            left = 2 * node
            go_right = mass >= self.sum[left]
            mass -= np.where(go_right, self.sum[left], 0.0)
            node = left + go_right
        # a mass within rounding of the total can descend past the last set leaf: take that leaf
        return np.minimum(node - self.width, count - 1)


class PrioritizedMixedReplayBuffer:
    """Draws batches from a fixed teacher buffer and an agent buffer by prioritized replay over both.

    Each stored row ``i`` has a priority ``p_i``; a batch draws ``batch_size`` rows with
    replacement, one in each of ``batch_size`` equal ranges of the total priority (PER's
    stratified draw), so that row ``i`` is drawn ``batch_size * P(i)`` times on average,
    ``P(i) = v_i / sum_k v_k``, ``v_i = (p_i + eps + teacher_eps [i is a teacher row]) ** alpha``,
    and carries the importance weight
    ``w_i = (N P(i)) ** -beta / max_k (N P(k)) ** -beta = (v_i / min_k v_k) ** -beta`` (``N``
    the rows stored) under ``"priority_weight"``, where TorchRL's losses read it. A row enters
    with the largest priority given so far (1 before any), as in TorchRL's
    :class:`~torchrl.data.PrioritizedSampler`: the teacher rows at construction, each agent row
    when the agent buffer writes it (the buffer attaches itself to the agent's storage, which
    calls :meth:`mark_update` on every write). :meth:`update_priority` sets new priorities, e.g.
    DDPGfD's ``delta^2 + lambda_3 |grad_a Q(s, a)|^2`` of the rows just learned from.

    As :class:`~torchrl_sail.MixedReplayBuffer`, a batch keeps ``keys`` of both buffers, teacher
    rows first, tagged ``True`` under ``tag_key``; their count follows the priorities. The teacher
    buffer must not change after construction (DDPGfD's demonstrations): its rows are gathered
    once, :meth:`sample` refuses a teacher buffer whose size changed, and a change that keeps its
    size goes unseen. Emptying the agent buffer (``agent.empty()``) drops its rows' priorities.

    Args:
        teacher (ReplayBuffer): the demonstrations, kept for good. With a
            :class:`~torchrl_sail.TeacherReplayBuffer`, the rows its writer filled; otherwise the
            first ``len(teacher)`` storage rows.
        agent (ReplayBuffer): the agent's replay, with a ``TensorStorage`` (e.g.
            ``LazyTensorStorage``) of TensorDicts, written by a writer that marks the rows it
            writes (TorchRL's ``RoundRobinWriter``, the default).

    Raises:
        TypeError: the agent's storage is not a ``TensorStorage``, or (at the first draw of agent
            rows) it holds plain tensors instead of a TensorDict.

    Keyword Args:
        alpha (float): the priority exponent (0: uniform). Defaults to ``0.6`` (PER's).
        beta (float): the importance-weight exponent (1: full correction). Defaults to ``0.4``.
        eps (float): added to every priority, > 0. Defaults to ``1e-6``.
        teacher_eps (float): added to the teacher rows' priorities (DDPGfD's ``epsilon_D``).
            Defaults to ``0.0``.
        keys (sequence of NestedKey): the entries kept from both buffers. Defaults to
            :data:`~torchrl_sail.TRANSITION_KEYS`.
        tag_key (NestedKey): where the teacher tag is written. Defaults to ``"is_teacher"``.
        index_key (NestedKey): where each row's position in the tree is written, read back by
            :meth:`update_tensordict_priority`. Defaults to ``"index"``.
        weight_key (NestedKey): where the importance weights are written. Defaults to
            ``"priority_weight"`` (TorchRL losses' ``tensor_keys.priority_weight``).
        priority_key (NestedKey): where :meth:`update_tensordict_priority` reads the new
            priorities. Defaults to ``"td_error"`` (TorchRL losses' ``tensor_keys.priority``).
        transform (Callable[[TensorDictBase], TensorDictBase], optional): applied to each batch.
            The two buffers' own transforms are not: their storages are read directly. Defaults to
            ``None``.
        row_id_key (NestedKey, optional): also write the tree position there, a distinct id per
            stored row, as :class:`~torchrl_sail.MixedReplayBuffer` does. Defaults to ``None``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
        >>> from torchrl_sail import PrioritizedMixedReplayBuffer
        >>> def rows(n, obs):
        ...     return TensorDict({"observation": torch.full((n, 1), obs)}, [n])
        >>> teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(4))
        >>> agent = TensorDictReplayBuffer(storage=LazyTensorStorage(100))
        >>> _ = teacher.extend(rows(4, 1.0))
        >>> rb = PrioritizedMixedReplayBuffer(teacher, agent, alpha=1.0, beta=1.0, eps=1e-9,
        ...                                   keys=["observation"])
        >>> _ = agent.extend(rows(4, 0.0))  # enters at the largest priority so far: 1
        >>> batch = rb.sample(6)
        >>> batch["is_teacher"].tolist() == sorted(batch["is_teacher"].tolist(), reverse=True)
        True
        >>> rb.update_priority(torch.tensor([4]), 3.0)  # positions: 4 teacher rows, then the agent's
        >>> [round(p, 6) for p in rb.probabilities().tolist()]
        [0.1, 0.1, 0.1, 0.1, 0.3, 0.1, 0.1, 0.1]
        >>> batch = rb.sample(1000)
        >>> round(batch["priority_weight"][batch["index"] == 4][0].item(), 6)  # (3 / 1) ** -beta
        0.333333
    """

    def __init__(
        self,
        teacher: ReplayBuffer,
        agent: ReplayBuffer,
        *,
        alpha: float = 0.6,
        beta: float = 0.4,
        eps: float = 1e-6,
        teacher_eps: float = 0.0,
        keys: Sequence[NestedKey] = TRANSITION_KEYS,
        tag_key: NestedKey = "is_teacher",
        index_key: NestedKey = "index",
        weight_key: NestedKey = "priority_weight",
        priority_key: NestedKey = "td_error",
        transform: Callable[[TensorDictBase], TensorDictBase] | None = None,
        row_id_key: NestedKey | None = None,
    ) -> None:
        for name, value in (("alpha", alpha), ("beta", beta), ("teacher_eps", teacher_eps)):
            _check_number(name, value, positive=False)
        _check_number("eps", eps, positive=True)
        stored_rows = getattr(teacher.writer, "stored_rows", None)
        self._teacher_rows = stored_rows().clone() if stored_rows is not None else torch.arange(len(teacher))
        if not self._teacher_rows.numel():
            raise ValueError("PrioritizedMixedReplayBuffer: the teacher buffer is empty; add the demonstrations first.")
        if not isinstance(agent.storage, TensorStorage):
            raise TypeError(
                "PrioritizedMixedReplayBuffer: the agent buffer needs a TensorStorage (e.g. LazyTensorStorage), "
                f"got a {type(agent.storage).__name__}."
            )
        self.teacher, self.agent = teacher, agent
        self.alpha, self.beta, self.eps, self.teacher_eps = float(alpha), float(beta), float(eps), float(teacher_eps)
        self.keys, self.tag_key, self.index_key = list(keys), tag_key, index_key
        self.weight_key, self.priority_key = weight_key, priority_key
        self.transform, self.row_id_key = transform, row_id_key
        self.num_teacher = self._teacher_rows.numel()
        # the demonstrations' entries, gathered once: the teacher buffer does not change
        self._teacher_data = teacher.storage[self._teacher_rows].select(*self.keys)
        # the agent storage's TensorDict and its entries in keys (the same tensors), every step
        # indexed in place of storage[index], which would index every entry stored
        self._agent_source = self._agent_data = None
        self._tree = _PriorityTree(self.num_teacher + agent.storage.max_size)
        self._set_until = 0  # every leaf from here on is unset
        self.max_priority = 1.0
        self._set(np.arange(self.num_teacher), np.full(self.num_teacher, self.max_priority))
        self.mark_update(torch.arange(len(agent)))
        agent.storage.attach(self)

    def mark_update(self, index, *, storage=None) -> None:
        """Gives the agent rows just written (their storage indices) the largest priority so far."""
        index = torch.as_tensor(index).reshape(-1)
        if index.numel():
            self._set(index.cpu().numpy() + self.num_teacher, np.full(index.shape, self.max_priority))

    def __len__(self) -> int:
        return self.num_teacher + len(self.agent)

    def sample(self, batch_size: int) -> TensorDictBase:
        """Draws a ``[batch_size]`` batch, teacher rows first, with positions, tags and weights."""
        if not (isinstance(batch_size, int) and batch_size >= 1):
            raise ValueError(
                f"PrioritizedMixedReplayBuffer.sample: batch_size must be an int >= 1, got {batch_size!r}."
            )
        if len(self.teacher) != self.num_teacher:
            raise RuntimeError(
                f"PrioritizedMixedReplayBuffer: the teacher buffer changed size ({self.num_teacher} rows at "
                f"construction, {len(self.teacher)} now); its priorities cover the rows it held then."
            )
        self._drop_unstored()
        tree = self._tree
        # Stratified, as PER's proportional variant (Schaul et al. 2016, Appendix B.2.1): one mass in
        # each of batch_size equal ranges of the total, so each row keeps its probability P(i) and a
        # batch's teacher share varies less than with independent draws. Increasing masses give
        # sorted positions: teacher rows first. torch's generator: seeded and checkpointed with the run.
        strata = torch.arange(batch_size, dtype=torch.float64) + torch.rand(batch_size, dtype=torch.float64)
        position = tree.find((strata * (tree.total / batch_size)).numpy(), len(self))
        weight = torch.as_tensor((tree.leaves(position) / tree.minimum) ** -self.beta, dtype=torch.float32)
        position = torch.as_tensor(position)
        is_teacher = position < self.num_teacher
        num_teacher = int(is_teacher.sum())
        parts = []
        if num_teacher:
            parts.append(self._teacher_data[position[:num_teacher]])
        if num_teacher < batch_size:
            parts.append(self._agent_entries()[position[num_teacher:] - self.num_teacher])
        out = torch.cat(parts, 0) if len(parts) == 2 else parts[0]
        out.set(self.tag_key, is_teacher.to(out.device))
        out.set(self.index_key, position.to(out.device))
        out.set(self.weight_key, weight.to(out.device))
        if self.row_id_key is not None:
            out.set(self.row_id_key, position.to(out.device))
        return out if self.transform is None else self.transform(out)

    def _agent_entries(self) -> TensorDictBase:
        source = storage_tensordict(self.agent.storage)
        if source is not self._agent_source:  # created at the first write, or replaced by a load
            if not isinstance(source, TensorDictBase):
                raise TypeError(
                    "PrioritizedMixedReplayBuffer: the agent storage must hold TensorDicts, it holds a "
                    f"{type(source).__name__}."
                )
            self._agent_source, self._agent_data = source, source.select(*self.keys)
        return self._agent_data

    def _drop_unstored(self) -> None:
        # the leaves of rows the agent buffer no longer holds (emptied) stay out of the draws and the weights
        stored = len(self)
        if self._set_until > stored:
            self._tree.clear(np.arange(stored, self._set_until))
            self._set_until = stored

    @torch.no_grad()
    def update_priority(self, index, priority) -> None:
        """Sets the raw priorities ``p`` of the rows at tree positions ``index`` (a number or one per row).

        Positions ``[0, num_teacher)`` are the teacher rows, ``num_teacher + i`` the agent's
        storage row ``i``; the priorities are finite and ``>= 0``. With repeated positions, the
        last one's priority is kept.
        """
        position = torch.as_tensor(index).reshape(-1).cpu().numpy()
        if not position.size:
            return
        priority = torch.as_tensor(priority, dtype=torch.float64).detach().cpu().expand(position.shape).numpy()
        # a stray position or priority would corrupt the tree's sums for every later draw
        if position.min() < 0 or position.max() >= len(self):
            stray = position[(position < 0) | (position >= len(self))]
            raise IndexError(
                f"PrioritizedMixedReplayBuffer.update_priority: positions must lie in [0, {len(self)}) (the rows "
                f"stored), got {stray[:4].tolist()}."
            )
        if not (np.isfinite(priority).all() and priority.min() >= 0):
            raise ValueError(
                "PrioritizedMixedReplayBuffer.update_priority: priorities must be finite and >= 0, got "
                f"{priority[~(np.isfinite(priority) & (priority >= 0))][:4].tolist()}."
            )
        self._set(position, priority)

    def _set(self, position: np.ndarray, priority: np.ndarray) -> None:
        self.max_priority = max(self.max_priority, float(priority.max()))
        last = position.size - 1 - np.unique(position[::-1], return_index=True)[1]
        position, priority = position[last], priority[last]
        bonus = np.where(position < self.num_teacher, self.teacher_eps, 0.0)
        self._tree.set(position, (priority + self.eps + bonus) ** self.alpha)
        self._set_until = max(self._set_until, int(position.max()) + 1)

    def update_tensordict_priority(self, batch: TensorDictBase) -> None:
        """:meth:`update_priority` with ``batch[index_key]`` and ``batch[priority_key]``."""
        self.update_priority(batch[self.index_key], batch[self.priority_key])

    def probabilities(self) -> torch.Tensor:
        """``P(i)`` of every stored row, teacher rows first (for logging and tests)."""
        self._drop_unstored()
        leaves = self._tree.leaves(np.arange(len(self)))
        return torch.as_tensor(leaves / self._tree.total)

    def state_dict(self) -> dict:
        return {
            "leaves": torch.as_tensor(self._tree.leaves(np.arange(len(self)))),
            "max_priority": self.max_priority,
            "num_teacher": self.num_teacher,
            # the leaves hold (p + eps + bonus) ** alpha: they mean the same only under the same three
            **self._settings(),
        }

    def load_state_dict(self, state: dict) -> None:
        name = "PrioritizedMixedReplayBuffer.load_state_dict"
        missing = [key for key in ("leaves", "max_priority", "num_teacher", *self._settings()) if key not in state]
        if missing:
            raise ValueError(
                f"{name}: the saved state has no {missing}: it was saved by an earlier torchrl_sail, whose "
                "priorities this one cannot check; restart the run."
            )
        leaves = state["leaves"].cpu().numpy()
        if state["num_teacher"] != self.num_teacher or leaves.size != len(self):
            raise ValueError(
                f"{name}: the saved priorities cover {state['num_teacher']} teacher and "
                f"{leaves.size - state['num_teacher']} agent rows, the buffers hold {self.num_teacher} and "
                f"{len(self.agent)} (restore the buffers first, with the same demonstrations)."
            )
        changed = {key: (state[key], value) for key, value in self._settings().items() if state[key] != value}
        if changed:
            raise ValueError(
                f"{name}: the saved priorities were set with "
                + ", ".join(f"{key}={saved} (here {now})" for key, (saved, now) in changed.items())
            )
        self.max_priority = float(state["max_priority"])
        self._tree = _PriorityTree(self._tree.size)  # no leaf of the state before survives the load
        self._tree.set(np.arange(leaves.size), leaves)
        self._set_until = leaves.size

    def _settings(self) -> dict:
        return {"alpha": self.alpha, "eps": self.eps, "teacher_eps": self.teacher_eps}

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(teacher rows={self.num_teacher}, agent={type(self.agent).__name__}, "
            f"alpha={self.alpha}, beta={self.beta}, eps={self.eps}, teacher_eps={self.teacher_eps})"
        )


def _check_number(name: str, value, *, positive: bool) -> None:
    ok = isinstance(value, (int, float)) and value < float("inf") and (value > 0 if positive else value >= 0)
    if not ok:
        bound = "> 0 (a row of priority 0 would get an infinite weight)" if positive else ">= 0"
        raise ValueError(f"PrioritizedMixedReplayBuffer: {name} must be a finite number {bound}, got {value!r}.")
