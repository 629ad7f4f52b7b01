"""Imitation reward ``-log(1 - D(s, a))`` from the SAIL discriminator, as a TorchRL transform.

In SAIL the critic never sees the environment reward: it is trained on
``r' = -log(1 - D(s, a))``, recomputed with the *current* discriminator for every
sampled batch, teacher and agent rows alike (authors' ``get_imitate_reward``). This
transform is the reward half of the companion pair with
:class:`~torchrl_sail.DiscriminatorLoss` (as TorchRL's ``RNDTransform`` is to
``RNDLoss``): both hold the same :class:`~torchrl_sail.Discriminator`; the loss trains
it and the transform reads it under ``torch.no_grad()``.

Two call paths:

- replay-buffer path (:meth:`DiscriminatorReward.forward`): appended to a buffer with
  ``rb.append_transform(t)``, or applied to a sampled/mixed batch by hand, it writes
  ``("next", out_key)`` from the root ``(s, a)``. The reward is computed at sample time
  with the current D and the storage is never written.
- environment path (:meth:`DiscriminatorReward._step`): inside a
  :class:`~torchrl.envs.TransformedEnv`, it writes ``out_key`` into the step's
  ``"next"`` tensordict from ``(s_t, a_t)``, e.g. for logging the imitation reward of
  rollouts.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from tensordict.utils import NestedKey, unravel_key
from torchrl.data.tensor_specs import TensorSpec, Unbounded
from torchrl.envs.transforms import Transform

from torchrl_sail.envs._rows import distinct_rows

__all__ = ["DiscriminatorReward"]


class DiscriminatorReward(Transform):
    """Writes the SAIL imitation reward ``-log(1 - D(s, a))`` computed by a discriminator.

    The same transform gives the baselines' variants of it: ``kind="airl"`` is the
    ``log D - log(1 - D)`` reward of AIRL and DAC, and ``mode="add"`` with a ``coef`` adds
    the reward to the one already in the batch as shaping (POfD: the environment reward
    plus ``coef`` times the discriminator reward).

    With ``ℓ = D_logit(s, a)`` the reward is ``r' = -log(1 - σ(ℓ)) = softplus(ℓ)``,
    computed as ``softplus`` which is exact and numerically stable. The authors compute
    ``-log(1 - σ(ℓ) + 1e-8)``, which is capped at ``-log(1e-8) ≈ 18.42`` and slightly
    biased near ``σ(ℓ) = 1``; ``softplus`` has neither the cap nor the bias (the two
    agree to ~1e-5 whenever ``σ(ℓ)`` is not within ~1e-4 of 1). ``r'`` is always
    ``> 0``, equals ``log 2 ≈ 0.693`` at ``D = 0.5`` and is not clipped.

    The reward has the shape of the logit, ``[*batch, 1]``, and never carries
    gradients (computed under ``torch.no_grad()``).

    **Replay buffer** (:meth:`forward`): reads the root ``(s, a)`` (the discriminator's
    ``in_keys``) and writes ``("next", out_key)``. Appended with
    ``rb.append_transform(DiscriminatorReward(disc))``, rewards are recomputed with the
    current discriminator at every ``rb.sample()``, and the stored data is untouched.
    With the default ``out_key="reward"`` this overwrites the sampled
    ``("next", "reward")`` like TorchRL's GAIL example does, so a TD3-style loss reads
    it without remapping; pass e.g. ``out_key="imitation_reward"`` to keep the env
    reward and point the loss at ``("next", "imitation_reward")`` instead.

    **Environment** (:meth:`_step`): reads ``(s_t, a_t)`` from the step input and
    writes ``out_key`` into the ``"next"`` tensordict. When ``out_key`` is not already
    a reward key of the parent env, an :class:`~torchrl.data.Unbounded` entry shaped
    like the env reward is added to the reward spec.

    .. warning:: **Train/eval mode.** ``rb.append_transform`` calls ``.eval()`` on the
        transform (and so would ``env.eval()``). This transform overrides
        :meth:`train` so that its mode never propagates to the discriminator shared
        with :class:`~torchrl_sail.DiscriminatorLoss`: appending it to a buffer leaves
        the discriminator in whatever mode it was.

    .. warning:: **Staleness across processes.** A discriminator copied into env
        worker processes (``ParallelEnv``, multi-process collectors) is a snapshot that
        the learner's updates never reach, so rewards computed there go stale. SAIL
        needs rewards from the *current* D: compute them on the learner at sample time
        (buffer path). ``transform.clone()`` and :class:`~torchrl.envs.TransformedEnv`
        in the same process share the discriminator and stay current.

    Args:
        discriminator (Discriminator): a :class:`~torchrl_sail.Discriminator` (or any
            :class:`~tensordict.nn.TensorDictModule` whose ``.module`` is a
            :class:`~torchrl_sail.DiscriminatorNet`), shared with the loss.

    Keyword Args:
        out_key (NestedKey, optional): reward entry, written under ``"next"``.
            Defaults to ``"reward"``.
        keep_logit (bool, optional): buffer path only: also leave the discriminator
            logit at the root of the output tensordict (under the discriminator's
            out_key, e.g. ``"d_logit"``). Defaults to ``False``. The env path never
            writes the logit (it is not part of the env specs).
        chunk_size (int, optional): inputs with more rows (e.g. a ``[num_batches, B]``
            block from :meth:`MixedReplayBuffer.sample`) are evaluated this many rows at a
            time. Defaults to ``1024``.
        kind (str, optional): ``"gail"``: ``-log(1 - D) = softplus(ℓ)`` (SAIL, GAIL; always
            positive, a survival bonus), or ``"airl"``: ``log D - log(1 - D) = ℓ`` (AIRL, and
            DAC's reward; positive where D says teacher, negative where it says agent).
            Defaults to ``"gail"``.
        clip (tuple of float, optional): ``(low, high)``: ``D`` is clipped to ``[low, high]``
            before the reward is taken, e.g. ``(0.01, 0.99)`` for the SAIL authors' DAC
            reward ``-log(1 - clip(D, 0.01, 0.99))``. Computed exactly as a clamp of the logit
            to ``[logit(low), logit(high)]``. Defaults to ``None`` (no clipping).
        shift (float, optional): added to the reward before ``coef``: ``r = coef * (f(ℓ) + shift)``.
            ``shift=-log(2)`` centres ``-log(1 - D)`` at ``D = 1/2`` (negative where D says agent);
            with ``kind="airl"`` and ``clip=(0.01, 0.99)``, ``shift=log(99)`` floors the logit at 0
            (in ``[0, 2 log 99]``). A reward below 0 can pay an episode for ending early (a fall),
            one above 0 for lasting. Defaults to ``0.0``.
        coef (float, optional): the reward is multiplied by this. Defaults to ``1.0``.
        mode (str, optional): ``"replace"`` writes ``coef * r`` to ``out_key``; ``"add"``
            adds it to the value already there (e.g. ``r_env + coef * r_D`` as POfD
            shapes the environment reward). Defaults to ``"replace"``.
        row_id_key (NestedKey, optional): buffer path: when the input holds this entry
            (e.g. written by ``MixedReplayBuffer(row_id_key=...)``), D runs once per
            distinct id and every row with that id gets its reward. Rows with equal ids
            must hold equal ``(s, a)``. A block of 1000 batches of 256 rows drawn from a
            replay of 10k rows then costs 10k evaluations instead of 256k. Finding the
            distinct ids synchronises with the host once per call on CUDA. Defaults to
            ``None`` (every row evaluated).

    Examples:
        >>> import math
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
        >>> from torchrl_sail import Discriminator, DiscriminatorReward
        >>> disc = Discriminator(3, 1, num_cells=(16, 16))
        >>> t = DiscriminatorReward(disc)
        >>> data = TensorDict(
        ...     observation=torch.randn(10, 3),
        ...     action=torch.rand(10, 1),
        ...     next=TensorDict(reward=torch.zeros(10, 1), batch_size=[10]),
        ...     batch_size=[10],
        ... )
        >>> rb = TensorDictReplayBuffer(storage=LazyTensorStorage(10), batch_size=4)
        >>> _ = rb.extend(data)
        >>> _ = rb.append_transform(t)
        >>> disc.training  # append_transform put the transform, not D, in eval mode
        True
        >>> sample = rb.sample()
        >>> sample["next", "reward"].shape
        torch.Size([4, 1])
        >>> bool((sample["next", "reward"] > 0).all()), "d_logit" in sample.keys()
        (True, False)
        >>> bool((rb.storage[:]["next", "reward"] == 0).all())  # storage untouched
        True
        >>> shaping = DiscriminatorReward(disc, kind="airl", coef=0.1, mode="add")
        >>> data["next", "reward"] = torch.ones(10, 1)
        >>> logit = disc(data.clone())["d_logit"]
        >>> torch.allclose(shaping(data.clone())["next", "reward"], 1 + 0.1 * logit)
        True
        >>> clipped = DiscriminatorReward(disc, clip=(0.01, 0.99))  # the SAIL authors' DAC reward
        >>> d = torch.sigmoid(logit).clamp(0.01, 0.99)
        >>> torch.allclose(clipped(data.clone())["next", "reward"], -torch.log(1 - d))
        True
        >>> floored = DiscriminatorReward(disc, kind="airl", clip=(0.01, 0.99), shift=math.log(99))
        >>> bool((floored(data.clone())["next", "reward"] >= 0).all())  # the logit, floored at 0
        True
    """

    def __init__(
        self,
        discriminator: TensorDictModule,
        *,
        out_key: NestedKey = "reward",
        keep_logit: bool = False,
        chunk_size: int = 1024,
        kind: str = "gail",
        clip: tuple[float, float] | None = None,
        shift: float = 0.0,
        coef: float = 1.0,
        mode: str = "replace",
        row_id_key: NestedKey | None = None,
    ) -> None:
        if chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}.")
        if kind not in ("gail", "airl"):
            raise ValueError(f"kind must be 'gail' (-log(1 - D)) or 'airl' (log D - log(1 - D)), got {kind!r}.")
        if mode not in ("replace", "add"):
            raise ValueError(f"mode must be 'replace' or 'add', got {mode!r}.")
        if clip is not None and not (len(clip) == 2 and 0 < clip[0] < clip[1] < 1):
            raise ValueError(f"clip must be (low, high) with 0 < low < high < 1, got {clip!r}.")
        if not math.isfinite(shift):
            raise ValueError(f"shift must be finite, got {shift!r}.")
        super().__init__(in_keys=list(discriminator.in_keys), out_keys=[out_key])
        self.discriminator = discriminator
        self.keep_logit = keep_logit
        self.chunk_size = chunk_size
        self.kind = kind
        self.clip = None if clip is None else (float(clip[0]), float(clip[1]))
        # clip(sigmoid(l), low, high) == sigmoid(clamp(l, logit(low), logit(high))): sigmoid is monotone
        self._logit_bounds = None if clip is None else tuple(math.log(p / (1 - p)) for p in self.clip)
        self.shift = float(shift)
        self.coef = coef
        self.mode = mode
        self.row_id_key = row_id_key

    @property
    def out_key(self) -> NestedKey:
        """The reward key (relative to ``"next"``)."""
        return self.out_keys[0]

    def train(self, mode: bool = True) -> DiscriminatorReward:
        """Sets the mode of the transform only, never of the shared discriminator.

        ``rb.append_transform`` calls ``.eval()`` on transforms; propagating it would
        silently switch the discriminator being trained by
        :class:`~torchrl_sail.DiscriminatorLoss` to eval mode.

        Args:
            mode (bool, optional): training mode. Defaults to ``True``.
        """
        self.training = mode
        return self

    def _logit(self, tensordict: TensorDictBase) -> torch.Tensor:
        obs_key, act_key = self.discriminator.in_keys
        obs, act = tensordict[obs_key], tensordict[act_key]
        lead = obs.shape[:-1]
        obs, act = obs.reshape(lead.numel(), -1), act.reshape(lead.numel(), -1)
        ids = None if self.row_id_key is None else tensordict.get(self.row_id_key, None)
        rows = None if ids is None else distinct_rows(ids)
        if rows is not None:
            first, inverse = rows
            return self._evaluate(obs[first], act[first])[inverse].reshape(*lead, 1)
        return self._evaluate(obs, act).reshape(*lead, 1)

    def _reward(self, logit: torch.Tensor, current: TensorDictBase, key: NestedKey) -> torch.Tensor:
        if self._logit_bounds is not None:
            logit = logit.clamp(*self._logit_bounds)
        reward = F.softplus(logit) if self.kind == "gail" else logit
        if self.shift != 0.0:
            reward = reward + self.shift
        if self.coef != 1.0:
            reward = self.coef * reward
        if self.mode == "add":
            reward = current.get(key) + reward
        return reward

    def _evaluate(self, obs: torch.Tensor, act: torch.Tensor) -> torch.Tensor:
        """D's logit of ``[rows, dim]`` inputs, in D's dtype (also under autocast)."""
        net = self.discriminator.module
        rows = obs.shape[0]
        if rows <= self.chunk_size:
            return net(obs, act).to(net.dtype)
        # Large inputs (a block of batches) in chunks: bounded memory, and on CPU the per-row
        # cost is lowest at about a thousand rows. Each chunk is written into one output (a
        # list of small results kept alive between large freed activations fragments the heap).
        logit = torch.empty(rows, 1, dtype=net.dtype, device=obs.device)
        for start in range(0, rows, self.chunk_size):
            end = start + self.chunk_size
            logit[start:end] = net(obs[start:end], act[start:end])
        return logit

    @torch.no_grad()
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Writes ``("next", out_key)`` from the root ``(s, a)`` (replay-buffer path).

        Args:
            tensordict (TensorDictBase): transitions with the discriminator's
                observation and action keys at the root.
        """
        logit = self._logit(tensordict)
        key = unravel_key(("next", self.out_key))
        tensordict.set(key, self._reward(logit, tensordict, key))
        if self.keep_logit:
            tensordict.set(self.discriminator.out_keys[0], logit)
        return tensordict

    @torch.no_grad()
    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        logit = self._logit(tensordict)
        next_tensordict.set(self.out_key, self._reward(logit, next_tensordict, self.out_key))
        return next_tensordict

    def transform_reward_spec(self, reward_spec: TensorSpec) -> TensorSpec:
        out_key = self.out_key
        if out_key in reward_spec.keys(True, True):
            return reward_spec
        shape = (*reward_spec.shape, 1)
        device = reward_spec.device
        parent = self.parent
        if parent is not None:
            for reward_key in parent.reward_keys:
                if reward_key in reward_spec.keys(True, True):
                    shape = reward_spec[reward_key].shape
                    device = reward_spec[reward_key].device
                    break
        # softplus keeps the logit's dtype, i.e. the discriminator's parameter dtype.
        reward_spec[out_key] = Unbounded(shape=shape, device=device, dtype=self.discriminator.module.dtype)
        return reward_spec
