"""Exact-ratio sampling from SAIL's teacher buffer R_T and agent buffer R_B, with a source tag.

Every SAIL critic/actor step uses a batch made of ``N_teacher`` rows from the teacher
buffer and ``N_agent`` rows from the agent's own replay buffer (128 + 128 in the authors'
code while ``alpha = 0.5``, 0 + 256 after the switch), and the loss
(:class:`~torchrl_sail.SAILLoss`) weighs the two groups with ``alpha``. So the batch must
carry, for every row, which buffer it came from.

This follows TorchRL's :class:`~torchrl.data.OfflineToOnlineReplayBuffer` pattern (exact
per-call counts from each buffer, ``torch.cat``, teacher rows first, a read-side
transform applied to the concatenated batch). We wrap two existing buffers instead of
reusing that class because it (a) builds and owns its online buffer from a storage,
whereas SAIL's agent buffer is any user-built buffer (with its own sampler, info keys,
etc.), (b) has no per-row source tag, which the loss needs, (c) takes a fraction in
``(0, 1)`` instead of exact counts, so neither an all-agent batch (``alpha = 0``) nor an
all-teacher one can be requested, and (d) concatenates the raw samples, which fails as soon
as the two buffers write different bookkeeping keys.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey, unravel_key

from torchrl.data.replay_buffers import ReplayBuffer

__all__ = ["MixedReplayBuffer"]

# Written by samplers/buffers *about* the draw, not part of the transition. They differ
# between buffers (e.g. a [B] vs a [B, 2] "index", priorities only on prioritized
# buffers), which breaks torch.cat, and a leftover ("collector", "mask") would be picked
# up by the loss auto-mask (LossModule.loss_mask_key = "auto") and silently drop rows.
_BOOKKEEPING_KEYS: tuple[tuple[str, ...], ...] = (
    ("index",),
    ("priority_weight",),
    ("collector", "mask"),
)


def _check_key(key, what: str) -> NestedKey:
    try:
        return unravel_key(key)
    except RuntimeError as err:
        raise TypeError(
            f"MixedReplayBuffer: {what} must be a NestedKey (a str or a tuple of str), "
            f"got {key!r}."
        ) from err


def _as_tuple(key: NestedKey) -> tuple[str, ...]:
    key = unravel_key(key)
    return key if isinstance(key, tuple) else (key,)


def _is_bookkeeping(key: NestedKey) -> bool:
    key = _as_tuple(key)
    return any(key[: len(b)] == b for b in _BOOKKEEPING_KEYS)


class MixedReplayBuffer:
    """Samples exactly ``num_teacher`` teacher rows and ``num_agent`` agent rows, tagged.

    :meth:`sample` draws ``num_teacher`` transitions from ``teacher`` and ``num_agent``
    from ``agent`` (each via ``buffer.sample(n)``), restricts both to a common key set,
    concatenates them (teacher rows first) into a flat ``[num_teacher + num_agent]`` batch
    and writes the boolean tag ``tag_key`` (``True`` for teacher rows). The counts are
    exact on every call, not a stochastic mixture. A buffer asked for 0 rows is not
    touched, so the teacher buffer may be empty while ``num_teacher = 0``.

    Common keys: ``keys`` if given, otherwise the leaf keys both samples share, minus
    sampling bookkeeping (``"index"``, ``"priority_weight"``, ``("collector", "mask")`` and
    their sub-keys) and minus ``tag_key`` (always rewritten). Concatenation needs identical
    key sets, and a stray mask from one buffer would be read by the loss auto-mask.

    Limitation, no prioritized replay: ``"priority_weight"`` and ``"index"`` are dropped
    from both halves (with the default ``keys=None``). They are written per buffer and
    differ between buffers (a ``[B]`` vs ``[B, 2]`` index, weights only on prioritized
    buffers), so they cannot be concatenated, and without each buffer's own ``"index"``
    the mixed batch cannot route TD errors back to ``update_priority``. Batches from
    this class therefore never reach :class:`~torchrl_sail.SAILLoss`'s prioritized-weight
    path: every row has weight 1, even when a half comes from a
    :class:`~torchrl.data.TensorDictPrioritizedReplayBuffer` (naming
    ``"priority_weight"`` in ``keys=`` is not supported either). ``SAILLoss`` still
    accepts ``"priority_weight"`` (normalised within each group) in batches you build
    yourself: sample the buffers directly, concatenate, write the tag, and call each
    buffer's ``update_priority`` with its own ``"index"``.

    Any TorchRL replay buffer whose ``sample(batch_size)`` returns a flat ``[batch_size]``
    tensordict of transitions works on either side (e.g. a
    :class:`~torchrl.data.TensorDictReplayBuffer`, or the project's
    :class:`~torchrl_sail.TopKTeacherReplayBuffer`). Build them without a ``batch_size``
    (or ignore TorchRL's one-time "conflicting batch_sizes" warning): the counts passed to
    :meth:`sample` always prevail.

    Args:
        teacher (ReplayBuffer): the teacher buffer ``R_T``.
        agent (ReplayBuffer): the agent (self-replay) buffer ``R_B``.

    Keyword Args:
        tag_key (NestedKey, optional): where the teacher tag is written (bool, shape
            ``[num_teacher + num_agent]``). Defaults to ``"is_teacher"``, the key read by
            :class:`~torchrl_sail.SAILLoss`.
        keys (sequence of NestedKey, optional): the exact key set kept from both samples,
            e.g. ``loss.in_keys``. A key missing from a sample raises a ``KeyError``.
            Defaults to ``None`` (the shared keys, see above).
        transform (Callable[[TensorDictBase], TensorDictBase], optional): applied to the
            mixed batch after concatenation and tagging, e.g. a
            :class:`~torchrl_sail.DiscriminatorReward` that writes the imitation reward for
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
        >>> rb = MixedReplayBuffer(teacher, agent)
        >>> batch = rb.sample(2, 3)
        >>> batch.batch_size
        torch.Size([5])
        >>> batch["is_teacher"].tolist()
        [True, True, False, False, False]
        >>> batch["observation"][:, 0].tolist()
        [1.0, 1.0, 0.0, 0.0, 0.0]
        >>> "index" in batch.keys()  # sampling bookkeeping is dropped
        False
        >>> MixedReplayBuffer.split(256, alpha=0.5)
        (128, 128)
    """

    def __init__(
        self,
        teacher: ReplayBuffer,
        agent: ReplayBuffer,
        *,
        tag_key: NestedKey = "is_teacher",
        keys: Sequence[NestedKey] | None = None,
        transform: Callable[[TensorDictBase], TensorDictBase] | None = None,
    ) -> None:
        for name, buffer in (("teacher", teacher), ("agent", agent)):
            if not callable(getattr(buffer, "sample", None)):
                raise TypeError(
                    f"MixedReplayBuffer: the {name} buffer must be a replay buffer with "
                    f"a sample(batch_size) method, got {type(buffer).__name__}."
                )
        tag_key = _check_key(tag_key, "tag_key")
        if keys is not None:
            if isinstance(keys, (str, tuple)):
                raise TypeError(
                    f"MixedReplayBuffer: keys must be a list of keys, got {keys!r}; "
                    f"wrap a single key in a list."
                )
            keys = [_check_key(k, "each entry of keys") for k in keys]
            # The tag is always rewritten by sample(), so it is never read from a half.
            keys = [k for k in keys if k != tag_key]
            if not keys:
                raise ValueError(
                    "MixedReplayBuffer: keys must name at least one entry besides "
                    f"the tag {tag_key!r}."
                )
        if transform is not None and not callable(transform):
            raise TypeError(
                f"MixedReplayBuffer: transform must be a callable td -> td, got "
                f"{type(transform).__name__}."
            )
        self._teacher = teacher
        self._agent = agent
        self.tag_key = tag_key
        self.keys = keys
        self.transform = transform

    @property
    def teacher(self) -> ReplayBuffer:
        """The teacher buffer ``R_T``."""
        return self._teacher

    @property
    def agent(self) -> ReplayBuffer:
        """The agent (self-replay) buffer ``R_B``."""
        return self._agent

    @staticmethod
    def split(batch_size: int, alpha: float) -> tuple[int, int]:
        """Split a batch size into ``(num_teacher, num_agent)`` for a teacher share ``alpha``.

        ``num_teacher = round(alpha * batch_size)``, as in
        :class:`~torchrl.data.OfflineToOnlineReplayBuffer`.

        Args:
            batch_size (int): total rows, positive.
            alpha (float): teacher share, in ``[0, 1]`` (e.g. ``float(loss.alpha)``).

        Returns:
            ``(num_teacher, num_agent)``, summing to ``batch_size``.
        """
        if isinstance(batch_size, bool) or not isinstance(batch_size, int):
            raise TypeError(
                f"MixedReplayBuffer.split: batch_size must be an int, got {batch_size!r}."
            )
        if batch_size <= 0:
            raise ValueError(
                f"MixedReplayBuffer.split: batch_size must be positive, got {batch_size}."
            )
        alpha = float(alpha)
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(
                f"MixedReplayBuffer.split: alpha must be in [0, 1], got {alpha}."
            )
        num_teacher = round(alpha * batch_size)
        return num_teacher, batch_size - num_teacher

    def _sample_one(self, name: str, buffer: ReplayBuffer, n: int) -> TensorDictBase:
        try:
            size = len(buffer)
        except TypeError:  # buffers without __len__: let sample() speak for itself
            size = None
        if size == 0:
            raise ValueError(
                f"MixedReplayBuffer: the {name} buffer is empty but {n} {name} rows were "
                f"requested; fill it first"
                + (
                    " (e.g. with the demonstrations), or sample with num_teacher=0."
                    if name == "teacher"
                    else " (e.g. with warm-up transitions), or sample with num_agent=0."
                )
            )
        out = buffer.sample(n)
        if not isinstance(out, TensorDictBase):
            raise TypeError(
                f"MixedReplayBuffer: the {name} buffer returned a "
                f"{type(out).__name__}, expected a TensorDict of transitions."
            )
        if out.batch_size != torch.Size([n]):
            raise ValueError(
                f"MixedReplayBuffer: the {name} buffer returned a batch of shape "
                f"{tuple(out.batch_size)} for sample({n}); flat [{n}] transitions are "
                f"needed (flatten trajectory samples with .reshape(-1) in a transform)."
            )
        return out

    def _common_keys(self, samples: dict[str, TensorDictBase]) -> list[NestedKey]:
        if self.keys is not None:
            for name, td in samples.items():
                present = set(td.keys(include_nested=True, leaves_only=True))
                for key in self.keys:
                    if key not in present and key not in td.keys(include_nested=True):
                        raise KeyError(
                            f"MixedReplayBuffer: key {key!r} is missing from the {name} "
                            f"buffer's samples, which have: "
                            f"{', '.join(sorted(map(str, present)))}; fix the buffer "
                            f"contents or the keys= argument."
                        )
            return list(self.keys)
        common = None
        for td in samples.values():
            leaves = {
                unravel_key(k) for k in td.keys(include_nested=True, leaves_only=True)
            }
            common = leaves if common is None else common & leaves
        # sorted: a deterministic key order (and error messages) across runs
        return sorted(
            (k for k in common if not _is_bookkeeping(k) and k != self.tag_key), key=str
        )

    def sample(self, num_teacher: int, num_agent: int) -> TensorDictBase:
        """Draw a tagged ``[num_teacher + num_agent]`` batch, teacher rows first.

        Args:
            num_teacher (int): rows from the teacher buffer (may be 0).
            num_agent (int): rows from the agent buffer (may be 0).

        Returns:
            the concatenated batch with ``tag_key`` set, after ``transform``.
        """
        for name, n in (("num_teacher", num_teacher), ("num_agent", num_agent)):
            if isinstance(n, bool) or not isinstance(n, int):
                raise TypeError(
                    f"MixedReplayBuffer.sample: {name} must be an int, got {n!r}."
                )
            if n < 0:
                raise ValueError(
                    f"MixedReplayBuffer.sample: {name} must be >= 0, got {n}."
                )
        if num_teacher + num_agent == 0:
            raise ValueError(
                "MixedReplayBuffer.sample: num_teacher + num_agent must be positive, "
                "got 0 + 0."
            )
        samples: dict[str, TensorDictBase] = {}
        if num_teacher:
            samples["teacher"] = self._sample_one("teacher", self._teacher, num_teacher)
        if num_agent:
            samples["agent"] = self._sample_one("agent", self._agent, num_agent)
        keys = self._common_keys(samples)
        parts = [td.select(*keys) for td in samples.values()]
        if len(parts) == 2:
            self._check_compatible(parts[0], parts[1], keys)
            out = torch.cat(parts, dim=0)
        else:
            out = parts[0]
        tag = torch.zeros(out.batch_size, dtype=torch.bool, device=out.device)
        tag[:num_teacher] = True
        out.set(self.tag_key, tag)
        if self.transform is not None:
            out = self.transform(out)
        return out

    @staticmethod
    def _check_compatible(
        teacher: TensorDictBase, agent: TensorDictBase, keys: list[NestedKey]
    ) -> None:
        # torch.cat would silently promote dtypes (float64 demos would turn the whole
        # batch float64) or fail with an unhelpful message on a feature-size mismatch.
        for key in keys:
            t, a = teacher.get(key), agent.get(key)
            if not isinstance(t, torch.Tensor) or not isinstance(a, torch.Tensor):
                continue
            if t.dtype != a.dtype or t.shape[1:] != a.shape[1:]:
                raise ValueError(
                    f"MixedReplayBuffer: entry {key!r} differs between the teacher "
                    f"(dtype {t.dtype}, per-row shape {tuple(t.shape[1:])}) and agent "
                    f"(dtype {a.dtype}, per-row shape {tuple(a.shape[1:])}) samples; "
                    f"store both with the same dtype and feature size."
                )

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(teacher={type(self._teacher).__name__}, "
            f"agent={type(self._agent).__name__}, tag_key={self.tag_key!r}, "
            f"keys={self.keys!r})"
        )
