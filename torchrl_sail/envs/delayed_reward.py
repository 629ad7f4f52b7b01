"""Trajectory-wise (delayed) reward transform for the SAIL setting.

SAIL (Self-Adaptive Imitation Learning) is evaluated on tasks with *extremely delayed*
rewards: the agent gets no per-step feedback, only one coarse-grained trajectory-wise
reward ``r_e = floor(0.1 * R)`` (``R`` the undiscounted dense return) when the episode
ends. The MuJoCo benchmarks are dense, so this module turns them into that setting with
a TorchRL :class:`~torchrl.envs.transforms.Transform` that works in an environment
(single, serial or parallel, with partial resets) and offline on collected trajectories.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase, unravel_key
from tensordict.utils import NestedKey, expand_as_right
from torchrl.data.tensor_specs import Composite, TensorSpec, Unbounded
from torchrl.envs.transforms import Transform

from torchrl_sail._compat import filtered_reset_keys, reset_mask

__all__ = ["DelayedRewardTransform"]

_ROUNDINGS = ("floor", "none")
# Relative distance to an integer under which ``scale * R`` counts as that integer before
# flooring: binary floats make e.g. ``0.3 * 10 == 2.9999999999999996``, which would floor
# to 2. 1e-12 is far below the resolution of a float32 reward (~6e-8 relative).
_SNAP_RTOL = 1e-12


class DelayedRewardTransform(Transform):
    """Replaces a dense per-step reward by the paper's trajectory-wise (delayed) reward.

    The reward is ``0`` at every step except the last step of an episode (the step where
    ``done`` = terminated OR truncated is ``True``), where it is
    ``r_e = g(scale * R)``, ``R`` the undiscounted dense return of the episode and ``g``
    the rounding (``floor`` by default). With the defaults this is the SAIL paper's
    coarse-grained feedback ``r_e = floor(0.1 * R)``.

    The running dense return is written to ``return_key`` (``"episode_return"`` by
    default); at the ``done`` step it holds the full dense return ``R``. It is meant for
    logging and evaluation only: the ``reward_key`` entry carries the delayed reward
    alone, so the dense per-step reward never reaches a learner through it.

    The running return is episode state and lives in the tensordict, registered in the
    observation spec and in the full state spec (as :class:`~torchrl.envs.RewardSum`
    does), never in Python attributes. It is therefore correct in batched envs with
    partial resets (only the sub-envs flagged by ``"_reset"`` are zeroed) and when the
    transform runs inside :class:`~torchrl.envs.ParallelEnv` workers. It is accumulated
    in ``float64`` (so 1000 float32 rewards floor like their exact sum); the emitted
    reward keeps the dtype and shape of the reward spec.

    .. note:: **Placement in a** :class:`~torchrl.envs.Compose`. Put this transform
        after ``DoubleToFloat`` (which would otherwise cast the float64 running return
        to float32 and change the floor) and after any transform that sets ``done``,
        e.g. ``StepCounter(max_steps)``: a ``done`` set after this transform ran is not
        seen, and that episode ends with reward 0. To also log the dense return under
        another key, put ``RewardSum(in_keys=["reward"], out_keys=["dense_return"])``
        *before* this transform (torchrl 0.14.1's ``RewardSum`` needs the explicit
        ``in_keys`` when ``out_keys`` is given); the final sums are equal either way.

    Offline, calling the transform (:meth:`forward`) on a batch of **complete**
    trajectories ``[*, T]`` gives exactly the rewards the env mode gives on the same data
    (see :meth:`forward`). Do not append it to a replay buffer that samples shuffled
    transitions: a delayed reward needs the whole trajectory.

    Args:
        scale (float, optional): positive factor applied to the dense return before
            rounding. Defaults to ``0.1``.

    Keyword Args:
        rounding (str, optional): ``"floor"`` (the paper) or ``"none"`` (keep
            ``scale * R`` as is). Defaults to ``"floor"``.
        reward_key (NestedKey, optional): the dense reward entry, overwritten with the
            delayed reward. Defaults to ``"reward"``.
        done_key (NestedKey, optional): the end-of-episode flag. Defaults to ``"done"``.
        return_key (NestedKey, optional): where the running dense return (float64) is
            written. Defaults to ``"episode_return"``.
        reset_keys (list of NestedKey, optional): the reset entry (one key) used to zero
            the running return; discovered from the parent env when ``None`` (as in
            ``RewardSum``).

    Examples:
        >>> import torch
        >>> from torchrl.envs import (
        ...     Compose, DoubleToFloat, GymEnv, RewardSum, StepCounter, TransformedEnv
        ... )
        >>> from torchrl_sail import DelayedRewardTransform
        >>> env = TransformedEnv(
        ...     GymEnv("Pendulum-v1"),
        ...     Compose(
        ...         DoubleToFloat(),
        ...         StepCounter(max_steps=5),
        ...         RewardSum(in_keys=["reward"], out_keys=["dense_return"]),
        ...         DelayedRewardTransform(),
        ...     ),
        ... )
        >>> _ = env.set_seed(0)
        >>> rollout = env.rollout(5)
        >>> reward = rollout["next", "reward"].squeeze(-1)
        >>> bool((reward[:-1] == 0).all())
        True
        >>> dense_return = rollout["next", "episode_return"][-1]
        >>> bool(reward[-1] == torch.floor(0.1 * dense_return).float())
        True
        >>> rollout["next", "episode_return"].dtype
        torch.float64
        >>> torch.allclose(rollout["next", "dense_return"][-1].double(), dense_return)
        True
    """

    def __init__(
        self,
        scale: float = 0.1,
        *,
        rounding: str = "floor",
        reward_key: NestedKey = "reward",
        done_key: NestedKey = "done",
        return_key: NestedKey = "episode_return",
        reset_keys: Sequence[NestedKey] | None = None,
    ) -> None:
        if not 0 < scale < float("inf"):
            raise ValueError(f"scale must be finite and > 0, got {scale!r}.")
        if rounding not in _ROUNDINGS:
            raise ValueError(f"rounding must be one of {_ROUNDINGS}, got {rounding!r}.")
        reward_key = unravel_key(reward_key)
        return_key = unravel_key(return_key)
        if return_key == reward_key:
            # The learner reads reward_key: the dense return must not end up there.
            raise ValueError(f"return_key and reward_key must differ, both are {reward_key!r}.")
        super().__init__(in_keys=[reward_key], out_keys=[reward_key, return_key])
        self.scale = float(scale)
        self.rounding = rounding
        self.reward_key = reward_key
        self.done_key = unravel_key(done_key)
        self.return_key = return_key
        self.reset_keys = reset_keys

    @property
    def reset_keys(self) -> list[NestedKey]:
        reset_keys = self.__dict__.get("_reset_keys", None)
        if reset_keys is None:
            parent = self.parent
            if parent is None:
                raise TypeError(
                    "reset_keys not provided and no parent env found: pass "
                    "reset_keys=['_reset'] when using the transform without an env."
                )
            reset_keys = filtered_reset_keys(parent)
            self._reset_keys = reset_keys
        return reset_keys

    @reset_keys.setter
    def reset_keys(self, value: Sequence[NestedKey] | NestedKey | None) -> None:
        if value is not None:
            if isinstance(value, (str, tuple)):
                value = [value]
            value = [unravel_key(v) for v in value]
        self._reset_keys = value

    def _delayed_value(self, episode_return: torch.Tensor) -> torch.Tensor:
        """Maps float64 dense returns to ``g(scale * R)`` (still float64)."""
        value = episode_return * self.scale
        if self.rounding == "floor":
            nearest = value.round()
            close = (value - nearest).abs() <= _SNAP_RTOL * nearest.abs().clamp_min(1.0)
            value = torch.where(close, nearest, value).floor()
        return value

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        _reset = reset_mask(self.reset_keys[0], tensordict)
        value = tensordict.get(self.return_key, None)
        if value is None:
            value = self._return_spec().zero()
        else:
            # Only the flagged sub-envs start a new episode; the others keep counting.
            value = torch.where(expand_as_right(~_reset, value), value, 0.0)
        tensordict_reset.set(self.return_key, value)
        return tensordict_reset

    def _reset_on_native_autoreset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        return self._reset(tensordict, tensordict_reset)

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        reward = next_tensordict[self.reward_key]
        # 0.0 when the input was not produced by reset (as RewardSum does).
        episode_return = tensordict.get(self.return_key, 0.0) + reward.to(torch.float64)
        done = _done_like(next_tensordict[self.done_key], reward)
        delayed = torch.where(done, self._delayed_value(episode_return), 0.0)
        next_tensordict.set(self.return_key, episode_return)
        next_tensordict.set(self.reward_key, delayed.to(reward.dtype))
        return next_tensordict

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Computes the delayed rewards of complete trajectories offline.

        Reads the dense ``("next", reward_key)`` and ``("next", done_key)`` of a
        ``[*, T]`` tensordict (time dim = the one named ``"time"``, else the last batch
        dim), splits every row into episodes at each ``done``, and writes the delayed
        reward to ``("next", reward_key)`` and the running dense return (float64) to
        ``("next", return_key)``, in place. Each episode is summed from its first step
        in the same order as the env mode, so both give bit-identical values. A trailing
        segment without ``done`` keeps reward 0, as in the env mode.

        Args:
            tensordict (TensorDictBase): complete trajectories with dense rewards.

        Returns:
            the same tensordict, updated.
        """
        names = tensordict.names
        time_dim = names.index("time") if "time" in names else tensordict.batch_dims - 1
        reward_key = unravel_key(("next", self.reward_key))
        reward = tensordict[reward_key]
        done = _done_like(tensordict[unravel_key(("next", self.done_key))], reward)
        episode_return = _segment_cumsum(
            reward.to(torch.float64).movedim(time_dim, -1),
            done.movedim(time_dim, -1),
        ).movedim(-1, time_dim)
        delayed = torch.where(done, self._delayed_value(episode_return), 0.0)
        tensordict.set(unravel_key(("next", self.return_key)), episode_return)
        tensordict.set(reward_key, delayed.to(reward.dtype))
        return tensordict

    def _return_spec(self) -> Unbounded:
        spec = self.parent.full_reward_spec[self.reward_key]
        return Unbounded(shape=spec.shape, dtype=torch.float64, device=spec.device)

    def transform_observation_spec(self, observation_spec: TensorSpec) -> TensorSpec:
        observation_spec[self.return_key] = self._return_spec()
        return observation_spec

    def transform_input_spec(self, input_spec: TensorSpec) -> TensorSpec:
        input_spec = super().transform_input_spec(input_spec)
        state_spec = input_spec["full_state_spec"]
        if state_spec is None:
            state_spec = Composite(shape=input_spec.shape, device=input_spec.device)
        state_spec[self.return_key] = self._return_spec()
        input_spec["full_state_spec"] = state_spec
        return input_spec

    def transform_reward_spec(self, reward_spec: TensorSpec) -> TensorSpec:
        # The delayed reward can leave any bound of the dense reward, so only the dtype,
        # shape and device are kept.
        spec = reward_spec[self.reward_key]
        if not isinstance(spec, Unbounded):
            reward_spec[self.reward_key] = Unbounded(shape=spec.shape, dtype=spec.dtype, device=spec.device)
        return reward_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(scale={self.scale}, rounding={self.rounding!r}, "
            f"reward_key={self.reward_key!r}, done_key={self.done_key!r}, "
            f"return_key={self.return_key!r})"
        )


def _done_like(done: torch.Tensor, reward: torch.Tensor) -> torch.Tensor:
    """``done`` as a bool tensor of the reward's shape (it may lack trailing dims)."""
    done = done.bool()
    if done.ndim < reward.ndim:
        done = expand_as_right(done, reward)
    return done.expand_as(reward)


def _segment_cumsum(values: torch.Tensor, done: torch.Tensor) -> torch.Tensor:
    """Running sums along the last dim, restarting after each ``done``.

    Every episode is scattered into a separate zero-padded row and summed with one
    ``cumsum``, so the additions happen in the same order as a step-by-step accumulator
    (bit-identical float64 results, unlike differences of a global cumsum). Memory is
    ``n_episodes * longest_episode``.
    """
    shape = values.shape
    T = shape[-1]
    if T == 0 or values.numel() == 0:
        return values.clone()
    values = values.reshape(-1, T)
    done = done.reshape(-1, T)
    rows = values.shape[0]
    steps = torch.arange(T, device=values.device).expand(rows, T)
    done_long = done.long()
    # episode index of each step within its row: number of dones strictly before it
    episode = done_long.cumsum(-1) - done_long
    last_done = torch.where(done, steps, -1).cummax(-1).values
    prev_done = torch.cat([last_done.new_full((rows, 1), -1), last_done[:, :-1]], -1)
    position = steps - (prev_done + 1)
    episodes_per_row = episode[:, -1] + 1
    row_offset = episodes_per_row.cumsum(0) - episodes_per_row
    global_episode = row_offset[:, None] + episode
    padded = values.new_zeros(int(episodes_per_row.sum()), int(position.max()) + 1)
    padded[global_episode, position] = values
    return padded.cumsum(-1)[global_episode, position].reshape(shape)
