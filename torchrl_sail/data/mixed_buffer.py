"""Exact-ratio sampling from SAIL's teacher buffer R_T and agent buffer R_B, with a source tag.

SAIL's TD3 batches hold ``round(alpha * B)`` teacher rows and the rest agent rows (the
authors' 128 + 128 while ``alpha = 0.5``, 0 + 256 after the switch), and the discriminator
batches 256 + 256. This follows TorchRL's :class:`~torchrl.data.OfflineToOnlineReplayBuffer`
(exact per-call counts, ``torch.cat``, teacher rows first, a read-side transform on the
concatenated batch), but wraps two buffers the user built instead of owning the agent
buffer, accepts a teacher share of 0 or 1, and tags each row with its source.

It is not built on that class because SAIL's use breaks its contract in four places: its offline
side is immutable, while SAIL's teacher buffer takes promoted trajectories; it builds the online
buffer itself from a storage, where SAIL's agent buffer is the user's (and is checkpointed as
theirs); its constructor refuses a share of 0 or 1, SAIL's alpha after the switch and the
teacher-only batches; and it has neither the source tag that ``SAILLoss`` and the
discriminator read nor the per-row ids and multi-batch blocks (``num_batches``) that let a block's
reward be computed once per distinct row.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey
from torchrl.data.replay_buffers import ReplayBuffer

from torchrl_sail.data.keys import TRANSITION_KEYS

__all__ = ["MixedReplayBuffer"]


class MixedReplayBuffer:
    """Samples ``round(teacher_fraction * batch_size)`` teacher rows and the rest agent rows.

    :meth:`sample` draws from ``teacher`` and ``agent`` with ``buffer.sample(n)``, keeps
    ``keys`` of both, concatenates them (teacher rows first) and writes the bool tag
    ``tag_key`` (``True`` on teacher rows). The counts are exact on every call. A buffer
    asked for 0 rows is not touched. Sampling bookkeeping (``"index"``, priorities) is not
    in ``keys``: it differs between buffers and cannot be concatenated, so prioritized
    replay is not supported through this class.

    Args:
        teacher (ReplayBuffer): the teacher buffer ``R_T``.
        agent (ReplayBuffer): the agent's replay buffer ``R_B``.

    Keyword Args:
        keys (sequence of NestedKey): the entries kept from both samples. Defaults to
            :data:`~torchrl_sail.TRANSITION_KEYS`.
        tag_key (NestedKey): where the teacher tag is written (bool, batch shape).
            Defaults to ``"is_teacher"``.
        transform (Callable[[TensorDictBase], TensorDictBase], optional): applied to the
            mixed batch, e.g. a :class:`~torchrl_sail.DiscriminatorReward` that rewards
            both halves with the same discriminator. Defaults to ``None``.
        row_id_key (NestedKey, optional): where to write each row's id, an int64 that
            names the stored row it was drawn from: equal for every draw of that row
            within one :meth:`sample` call, different between rows and between the two
            buffers (``2 * index`` in the teacher buffer, ``2 * index + 1`` in the agent
            buffer). A row-wise transform can then compute once per distinct row, e.g.
            ``DiscriminatorReward(disc, row_id_key=...)`` when a block draws more rows than
            the buffers hold. Needs flat storages (1-D sample indices). Defaults to
            ``None`` (no id).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
        >>> from torchrl_sail import MixedReplayBuffer
        >>> def transitions(n, obs):
        ...     return TensorDict({"observation": torch.full((n, 3), obs),
        ...                        ("next", "reward"): torch.zeros(n, 1)}, [n])
        >>> teacher = TensorDictReplayBuffer(storage=LazyTensorStorage(100))
        >>> agent = TensorDictReplayBuffer(storage=LazyTensorStorage(100))
        >>> _ = teacher.extend(transitions(10, 1.0))
        >>> _ = agent.extend(transitions(20, 0.0))
        >>> rb = MixedReplayBuffer(teacher, agent, keys=["observation", ("next", "reward")])
        >>> batch = rb.sample(5, teacher_fraction=0.4)
        >>> batch["is_teacher"].tolist(), batch["observation"][:, 0].tolist()
        ([True, True, False, False, False], [1.0, 1.0, 0.0, 0.0, 0.0])
        >>> rb.sample(4, teacher_fraction=0.0)["is_teacher"].any()
        tensor(False)
        >>> block = rb.sample(5, teacher_fraction=0.4, num_batches=3)  # 3 batches at once
        >>> block.batch_size, block["is_teacher"].sum(-1).tolist()
        (torch.Size([3, 5]), [2, 2, 2])
        >>> rb = MixedReplayBuffer(teacher, agent, keys=["observation"], row_id_key="row_id")
        >>> block = rb.sample(10, teacher_fraction=0.5, num_batches=100)  # 1000 draws of 30 stored rows
        >>> block["row_id"].unique().numel() <= 30
        True
    """

    def __init__(
        self,
        teacher: ReplayBuffer,
        agent: ReplayBuffer,
        *,
        keys: Sequence[NestedKey] = TRANSITION_KEYS,
        tag_key: NestedKey = "is_teacher",
        transform: Callable[[TensorDictBase], TensorDictBase] | None = None,
        row_id_key: NestedKey | None = None,
    ) -> None:
        self.teacher = teacher
        self.agent = agent
        self.keys = list(keys)
        self.tag_key = tag_key
        self.transform = transform
        self.row_id_key = row_id_key

    def sample(self, batch_size: int, teacher_fraction: float, num_batches: int | None = None) -> TensorDictBase:
        """Draws a tagged ``[batch_size]`` batch, teacher rows first.

        Args:
            batch_size (int): total number of rows.
            teacher_fraction (float): the teacher share, in ``[0, 1]``; the batch holds
                ``round(teacher_fraction * batch_size)`` teacher rows, as in
                :class:`~torchrl.data.OfflineToOnlineReplayBuffer`.
            num_batches (int, optional): draw ``num_batches`` independent batches at once,
                as one ``[num_batches, batch_size]`` tensordict (each batch with the exact
                split, teacher rows first), e.g. the batches of a block of gradient steps
                during which neither buffer nor the transform's discriminator changes.
                One sampling call and one transform call instead of ``num_batches``.
                Defaults to ``None`` (one ``[batch_size]`` batch).
        """
        num_teacher = round(teacher_fraction * batch_size)
        shape = (batch_size,) if num_batches is None else (num_batches, batch_size)
        count = 1 if num_batches is None else num_batches
        parts, row_ids = [], []
        for source, (buffer, n) in enumerate(((self.teacher, num_teacher), (self.agent, batch_size - num_teacher))):
            if not n:
                continue
            if self.row_id_key is None:
                data = buffer.sample(n * count)
            else:
                data, info = buffer.sample(n * count, return_info=True)
                row_ids.append(_row_ids(info["index"], source).reshape(*shape[:-1], n))
            parts.append(data.select(*self.keys).reshape(*shape[:-1], n))
        out = torch.cat(parts, -1) if len(parts) == 2 else parts[0]
        tag = torch.zeros(shape, dtype=torch.bool, device=out.device)
        tag[..., :num_teacher] = True
        out.set(self.tag_key, tag)
        if row_ids:
            out.set(self.row_id_key, torch.cat(row_ids, -1) if len(row_ids) == 2 else row_ids[0])
        return out if self.transform is None else self.transform(out)

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(teacher={type(self.teacher).__name__}, "
            f"agent={type(self.agent).__name__}, keys={self.keys}, row_id_key={self.row_id_key})"
        )


def _row_ids(index, source: int) -> torch.Tensor:
    """Ids of the rows sampled from one buffer (``source`` 0: teacher, 1: agent): ``2 * index + source``."""
    if not (isinstance(index, torch.Tensor) and index.dim() == 1):
        shapes = [tuple(i.shape) for i in index] if isinstance(index, (tuple, list)) else getattr(index, "shape", index)
        raise ValueError(
            f"MixedReplayBuffer(row_id_key=...) needs flat storages (1-D sample indices); "
            f"the {('teacher', 'agent')[source]} buffer sampled indices of shape {shapes}."
        )
    return 2 * index + source
