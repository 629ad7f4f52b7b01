"""DDPGfD's n-step transitions, stored beside the 1-step ones (TorchRL's ``MultiStepTransform``, to separate keys).

DDPGfD (Vecerik et al. 2017) trains its critic on the 1-step TD loss plus ``lambda_1`` times
an n-step TD loss *on the same sampled transitions*: each stored transition needs both its
1-step ``("next", ...)`` entries and its n-step ones. TorchRL's
:class:`~torchrl.envs.transforms.MultiStepTransform` computes the n-step lookahead on
``ReplayBuffer.extend`` (across collector batches, never across an episode end) but
*replaces* the ``"next"`` entries; :class:`NStepTransform` runs the same computation
(``_multi_step_func``) and writes the n-step view under its own key instead, ``"next_n"`` by
default. :func:`nstep_view` turns a batch into the n-step transition a TorchRL value
estimator reads.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase, unravel_key
from tensordict.utils import NestedKey
from torchrl.envs.transforms import MultiStepTransform

from torchrl_sail._compat import multi_step

__all__ = ["NStepTransform", "nstep_view"]

# TorchRL's name for the number of steps to the bootstrap observation (``_multi_step_func`` and
# the value estimators' ``steps_to_next_obs`` key).
_STEPS = "steps_to_next_obs"


class NStepTransform(MultiStepTransform):
    """Writes the n-step transition of every step under ``out_key``, beside the 1-step ``"next"``.

    For every step ``t``, with ``k`` the number of steps to the window's end (``n_steps``, or
    fewer when the episode ends inside the window, at its ``done_key``):

    - ``(out_key, reward_key)``: ``sum_{i<k} gamma^i r_{t+i}``, the discounted rewards of the
      window (never of the next episode);
    - ``(out_key, key)`` for ``key`` in ``keys`` (observation and done flags by default): the
      ``("next", key)`` entry of step ``t + k - 1``, i.e. the observation ``s_{t+k}`` to
      bootstrap from and whether the episode terminated (or was truncated) there;
    - ``(out_key, "steps_to_next_obs")``: ``k``, so that a TorchRL value estimator discounts
      the bootstrap by ``gamma ** k`` (see :func:`nstep_view`).

    The 1-step entries are left as they are. This is TorchRL's
    :class:`~torchrl.envs.transforms.MultiStepTransform` computation (``gamma`` and
    ``n_steps`` have its meaning), with two differences: the n-step view goes to ``out_key``
    instead of replacing ``"next"``, and the done flags are gathered at the window's end
    too (``MultiStepTransform`` keeps step ``t``'s, which would bootstrap from a terminal
    observation when the episode terminates inside the window).

    Two ways to call it:

    - :meth:`inv` (``ReplayBuffer.extend`` calls it when the transform is the buffer's):
      streaming, for collector batches ``[T]`` or ``[B, T]`` (time last, the same ``B``
      streams every call). As ``MultiStepTransform`` does, the last ``n_steps`` steps of
      each call wait for the next call, which brings their lookahead: every step comes out
      exactly once, with its full window, ``n_steps`` steps late.
    - :meth:`apply_to_trajectories`: whole episodes (each stream ends with ``done_key``),
      e.g. demonstrations; nothing is held back.

    Args:
        n_steps (int): the window length ``n`` (``n_steps=1`` copies the 1-step transition).
        gamma (float): the discount of the rewards inside the window.

    Keyword Args:
        out_key (NestedKey): where the n-step view is written. Defaults to ``"next_n"``.
        keys (sequence of NestedKey): the ``"next"`` entries read at the window's end.
            Defaults to ``("observation", "done", "terminated", "truncated")``.
        reward_key (NestedKey): the reward summed over the window. Defaults to ``"reward"``.
        done_key (NestedKey): the end-of-episode flag: no window crosses a step where it is
            ``True``. Defaults to ``"done"``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import NStepTransform
        >>> def steps(first, last, done_at=-1):  # observation t, reward t + 1
        ...     t = torch.arange(first, last + 1, dtype=torch.float32).unsqueeze(-1)
        ...     done = t == done_at
        ...     return TensorDict({"observation": t, ("next", "observation"): t + 1, ("next", "reward"): t + 1,
        ...                        ("next", "done"): done, ("next", "terminated"): done,
        ...                        ("next", "truncated"): torch.zeros_like(done)}, [len(t)])
        >>> nstep = NStepTransform(3, gamma=0.5)
        >>> out = nstep.inv(steps(0, 4, done_at=2))  # an episode ends at step 2
        >>> out["observation"].squeeze(-1).tolist()  # steps 2..4 wait for their lookahead
        [0.0, 1.0]
        >>> out = nstep.inv(steps(5, 9))
        >>> out["observation"].squeeze(-1).tolist()
        [2.0, 3.0, 4.0, 5.0, 6.0]
        >>> out["next_n", "observation"].squeeze(-1).tolist()  # s_{t+k}: never past the episode end
        [3.0, 6.0, 7.0, 8.0, 9.0]
        >>> out["next_n", "steps_to_next_obs"].squeeze(-1).tolist()
        [1, 3, 3, 3, 3]
        >>> out["next_n", "reward"].squeeze(-1).tolist()  # 4 + 0.5 * 5 + 0.25 * 6 = 8
        [3.0, 8.0, 9.75, 11.5, 13.25]
        >>> out["next_n", "terminated"].squeeze(-1).tolist(), out["next", "reward"].squeeze(-1).tolist()
        ([True, False, False, False, False], [3.0, 4.0, 5.0, 6.0, 7.0])
    """

    def __init__(
        self,
        n_steps: int,
        gamma: float,
        *,
        out_key: NestedKey = "next_n",
        keys: tuple[NestedKey, ...] = ("observation", "done", "terminated", "truncated"),
        reward_key: NestedKey = "reward",
        done_key: NestedKey = "done",
    ) -> None:
        if not 0 < gamma <= 1:
            raise ValueError(f"gamma must be in (0, 1], got {gamma}.")
        out_key = unravel_key(out_key)
        if out_key == "next":
            raise ValueError("out_key='next' would overwrite the 1-step transition: use MultiStepTransform for that.")
        keys = [unravel_key(key) for key in keys]
        reward_key, done_key = unravel_key(reward_key), unravel_key(done_key)
        if reward_key in keys or _STEPS in keys:
            raise ValueError(f"keys must not hold the reward ({reward_key!r}) or {_STEPS!r}: they are computed.")
        super().__init__(n_steps, gamma, reward_keys=[reward_key], done_key=done_key, done_keys=[])
        self.out_key = out_key
        self.keys = keys
        # what the inverse writes, e.g. for MixedReplayBuffer(keys=...) or a writer's keys
        self.out_keys_inv = [_nested(out_key, key) for key in (reward_key, *keys, _STEPS)]

    def _nstep(self, data: TensorDictBase) -> TensorDictBase:
        """``data`` with the n-step view of all its steps under ``out_key`` (the window is cut at ``data``'s end)."""
        reward_key = self.reward_keys[0]
        source = data.select(*{("next", key) for key in (reward_key, self.done_key, *self.keys)})
        # done_keys=[]: the done flags are gathered at the window's end like the observation
        out = multi_step(
            source,
            done_key=self.done_key,
            done_keys=[],
            reward_keys=[reward_key],
            mask_key=None,
            n_steps=self.n_steps,
            gamma=self.gamma,
        )
        view = out.get("next").select(reward_key, *self.keys)
        steps = out.get(_STEPS)
        view.set(_STEPS, steps.reshape(*data.batch_size, *view.get(reward_key).shape[data.batch_dims :]))
        data = data.copy()  # a new container: the caller's tensordict is not written
        data.set(self.out_key, view)
        return data

    def _append_tensordict(self, data: TensorDictBase) -> TensorDictBase:
        total = data if self._buffer is None else torch.cat([self._buffer, data], -1)
        # cloned: a collector may write its next batch into the tensors it yielded
        self._buffer = total[..., -self.n_steps :].clone()
        return total

    def _inv_call(self, tensordict: TensorDictBase) -> TensorDictBase:
        # MultiStepTransform's private validation (torchrl_sail._compat.SUBCLASS_HOOKS)
        if not self._validated:
            self._validate()
        total = self._append_tensordict(tensordict)
        # the steps whose window lies inside ``total``: all but the last n_steps (possibly none)
        return self._nstep(total)[..., : max(total.shape[-1] - self.n_steps, 0)]

    def apply_to_trajectories(self, trajectories: TensorDictBase) -> TensorDictBase:
        """The n-step view of whole episodes (``[T]`` or ``[B, T]``, each stream ending with ``done_key``).

        Independent of the streaming state of :meth:`inv`.

        Args:
            trajectories (TensorDictBase): one or more whole episodes per stream, time last.
        """
        done = trajectories.get(("next", self.done_key))
        last = done.reshape(*trajectories.batch_size, -1)[..., -1, :].any(-1)
        if not bool(last.all()):
            raise ValueError(
                f"NStepTransform.apply_to_trajectories needs whole episodes: a stream does not end "
                f"with ('next', {self.done_key!r})=True. Use inv() for a stream that goes on."
            )
        return self._nstep(trajectories)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        # the replay buffer's read path: the view is written on extend
        return tensordict

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        raise ValueError(self.ENV_ERR)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n_steps={self.n_steps}, gamma={self.gamma}, out_key={self.out_key!r})"


def _nested(prefix: NestedKey, key: NestedKey) -> tuple:
    prefix = prefix if isinstance(prefix, tuple) else (prefix,)
    return (*prefix, *(key if isinstance(key, tuple) else (key,)))


def nstep_view(
    batch: TensorDictBase, nstep_key: NestedKey = "next_n", *, steps_key: NestedKey = _STEPS
) -> TensorDictBase:
    """``batch`` as its n-step transition: ``"next"`` is ``batch[nstep_key]``, ``steps_key`` its step count.

    The root entries (observation, action, tags, weights) are shared with ``batch``; ``"next"``
    is the n-step view an :class:`NStepTransform` wrote, and its ``"steps_to_next_obs"`` entry
    is moved to ``steps_key``, where TorchRL's value estimators read it (their
    ``tensor_keys.steps_to_next_obs``, at the root): a TD(0) estimator then computes
    ``r_n + gamma ** k * (1 - terminated_n) * Q'(s_{t+k})``. No tensor is copied.

    Args:
        batch (TensorDictBase): transitions with the n-step view under ``nstep_key``.
        nstep_key (NestedKey): where the n-step view is. Defaults to ``"next_n"``.

    Keyword Args:
        steps_key (NestedKey): where the view's step count goes. Defaults to
            ``"steps_to_next_obs"`` (the estimators' default).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import nstep_view
        >>> batch = TensorDict({"observation": torch.zeros(2, 3), ("next", "reward"): torch.zeros(2, 1),
        ...                     ("next_n", "reward"): torch.ones(2, 1),
        ...                     ("next_n", "steps_to_next_obs"): torch.tensor([[3], [1]])}, [2])
        >>> view = nstep_view(batch)
        >>> sorted(view.keys(True, True), key=str)
        [('next', 'reward'), 'observation', 'steps_to_next_obs']
        >>> view["next", "reward"].squeeze(-1).tolist(), view["steps_to_next_obs"].squeeze(-1).tolist()
        ([1.0, 1.0], [3, 1])
    """
    nstep = batch.get(nstep_key)
    view = batch.exclude("next", nstep_key)
    view.set("next", nstep.exclude(_STEPS))
    view.set(steps_key, nstep.get(_STEPS))
    return view
