"""Exact-ratio sampling from SAIL's teacher buffer R_T and agent buffer R_B, with a source tag.

SAIL's TD3 batches hold ``round(alpha * B)`` teacher rows and the rest agent rows (the
authors' 128 + 128 while ``alpha = 0.5``, 0 + 256 after the switch), and the discriminator
batches 256 + 256. This follows TorchRL's :class:`~torchrl.data.OfflineToOnlineReplayBuffer`
(exact per-call counts, ``torch.cat``, teacher rows first, a read-side transform on the
concatenated batch), but wraps two buffers the user built instead of owning the agent
buffer, accepts a teacher share of 0 or 1, and tags each row with its source.
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
    """

    def __init__(
        self,
        teacher: ReplayBuffer,
        agent: ReplayBuffer,
        *,
        keys: Sequence[NestedKey] = TRANSITION_KEYS,
        tag_key: NestedKey = "is_teacher",
        transform: Callable[[TensorDictBase], TensorDictBase] | None = None,
    ) -> None:
        self.teacher = teacher
        self.agent = agent
        self.keys = list(keys)
        self.tag_key = tag_key
        self.transform = transform

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
        parts = [
            buffer.sample(n * count).select(*self.keys).reshape(*shape[:-1], n)
            for buffer, n in ((self.teacher, num_teacher), (self.agent, batch_size - num_teacher))
            if n
        ]
        out = torch.cat(parts, -1) if len(parts) == 2 else parts[0]
        tag = torch.zeros(shape, dtype=torch.bool, device=out.device)
        tag[..., :num_teacher] = True
        out.set(self.tag_key, tag)
        return out if self.transform is None else self.transform(out)

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(teacher={type(self.teacher).__name__}, "
            f"agent={type(self.agent).__name__}, keys={self.keys})"
        )
