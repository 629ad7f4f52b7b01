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
from tensordict.utils import expand_as_right, NestedKey
from torchrl.data.tensor_specs import Composite, TensorSpec, Unbounded
from torchrl.envs.common import EnvBase
from torchrl.envs.transforms import (
    Compose,
    DTypeCastTransform,
    StepCounter,
    Transform,
)
from torchrl.envs.transforms.utils import _get_reset

__all__ = ["DelayedRewardTransform"]

_ROUNDINGS = ("floor", "none")
# Relative distance to an integer under which ``scale * R`` counts as that integer before
# flooring: binary floats make e.g. ``0.3 * 10 == 2.9999999999999996``, which would floor
# to 2. 1e-12 is far below the resolution of a float32 reward (~6e-8 relative).
_SNAP_RTOL = 1e-12
_DONE_NAMES = ("done", "terminated", "truncated")


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

    Where to put it in a :class:`~torchrl.envs.Compose`: after ``DoubleToFloat`` (which
    would otherwise cast the float64 running return to float32) and after any transform
    that sets ``done`` (e.g. ``StepCounter(max_steps)``, whose truncation must release the
    reward). Both misplacements are detected: a ``ValueError`` is raised when such a
    transform comes *after* this one in the same ``Compose`` (checked when the transform
    is put in a ``Compose`` and again when the env builds its specs, so a later
    ``append_transform`` is caught too; transforms of an outer ``TransformedEnv`` wrapping
    this env are not seen). To also log the dense return under another key, put
    ``RewardSum(in_keys=["reward"], out_keys=["dense_return"])`` *before* this transform
    (torchrl 0.14.1's ``RewardSum`` needs the explicit ``in_keys`` when ``out_keys`` is
    given); the final sums are equal either way.

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
        reset_keys (list of NestedKey, optional): reset entries used to zero the running
            return; discovered from the parent env when ``None`` (as in ``RewardSum``).

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
        if isinstance(scale, bool) or not isinstance(scale, (int, float)):
            raise TypeError(
                f"scale must be a positive real number, got {scale!r} "
                f"({type(scale).__name__})."
            )
        if not (scale > 0 and scale < float("inf")):
            raise ValueError(f"scale must be finite and > 0, got {scale!r}.")
        if rounding not in _ROUNDINGS:
            raise ValueError(
                f"rounding must be one of {_ROUNDINGS}, got {rounding!r}: use 'floor' for "
                "the paper's r_e = floor(scale * R) or 'none' for r_e = scale * R."
            )
        reward_key = unravel_key(reward_key)
        return_key = unravel_key(return_key)
        if return_key == reward_key:
            raise ValueError(
                f"return_key and reward_key must differ (both are {reward_key!r}): the "
                "dense return must not be written where the learner reads the reward."
            )
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
                    f"{type(self).__name__}: reset_keys were not provided and no parent "
                    "env was found. Pass reset_keys=['_reset'] (or your env's reset key) "
                    "when using the transform without a container env."
                )
            reset_keys = list(parent._filtered_reset_keys)
            if len(reset_keys) != 1:
                raise ValueError(
                    f"{type(self).__name__} tracks one reward but the env has reset keys "
                    f"{reset_keys}; pass the one matching reward_key={self.reward_key!r} "
                    "as reset_keys=[...]."
                )
            self._reset_keys = reset_keys
        return reset_keys

    @reset_keys.setter
    def reset_keys(self, value: Sequence[NestedKey] | NestedKey | None) -> None:
        if value is not None:
            if isinstance(value, (str, tuple)):
                value = [value]
            value = [unravel_key(v) for v in value]
            if len(value) != 1:
                raise ValueError(
                    f"{type(self).__name__} expects exactly one reset key, got {value}."
                )
        self._reset_keys = value

    def set_container(self, container: Transform | EnvBase) -> None:
        super().set_container(container)
        self._check_placement()

    def _transforms_after(self) -> list[Transform]:
        """The transforms that run after this one, in every enclosing ``Compose``.

        Walks the container chain through ``__dict__`` only: :attr:`parent` would build
        the parent env, which may not be complete yet when ``set_container`` runs.
        """
        after = []
        child = self
        container_ref = self.__dict__.get("_container", None)
        while container_ref is not None:
            container = container_ref()
            if not isinstance(container, Compose):
                break
            siblings = list(container.transforms)
            index = next((i for i, t in enumerate(siblings) if t is child), None)
            if index is None:
                # Mid-edit of the Compose (e.g. __setitem__): nothing reliable to scan.
                break
            after.extend(_flatten(siblings[index + 1 :]))
            child = container
            container_ref = container.__dict__.get("_container", None)
        return after

    def _sets_done(self, transform: Transform) -> bool:
        if isinstance(transform, StepCounter):
            # Without max_steps it only counts; with update_done=False it leaves done alone.
            return transform.max_steps is not None and transform.update_done
        done_keys = {self.done_key}
        for key in transform.__dict__.get("_out_keys", None) or []:
            key = unravel_key(key)
            leaf = key if isinstance(key, str) else key[-1]
            if key in done_keys or leaf in _DONE_NAMES:
                return True
        return False

    def _casts_return(self, transform: Transform) -> bool:
        if not isinstance(transform, DTypeCastTransform):
            return False
        if transform.dtype_in != torch.float64 or transform.dtype_out == torch.float64:
            return False
        # No explicit in_keys: every float64 entry of the specs is cast, ours included.
        in_keys = transform.__dict__.get("_in_keys", None)
        return in_keys is None or self.return_key in [unravel_key(k) for k in in_keys]

    def _check_placement(self) -> None:
        """Raises if a later transform of the same ``Compose`` breaks the delayed reward.

        A done set after this transform ran is never seen by it, so those episodes
        would silently end with reward 0; a float64 -> float32 cast after it would round
        the running return the floor is computed from.
        """
        name = type(self).__name__
        problems = []
        for transform in self._transforms_after():
            label = _describe(transform)
            if self._sets_done(transform):
                problems.append(
                    f"{label} comes after {name} in the Compose and can set "
                    f"{self.done_key!r}/'truncated' after the delayed reward was computed, "
                    "so the episodes it ends would get reward 0. Put "
                    f"{label} before {name} in the Compose."
                )
            if self._casts_return(transform):
                problems.append(
                    f"{label} comes after {name} in the Compose and would cast the "
                    f"float64 running return {self.return_key!r} to "
                    f"{transform.dtype_out}, losing the precision floor(scale * R) needs. "
                    f"Put {label} before {name} in the Compose, or give it explicit "
                    f"in_keys that do not include {self.return_key!r}."
                )
        if problems:
            raise ValueError(" ".join(problems))

    def _delayed_value(self, episode_return: torch.Tensor) -> torch.Tensor:
        """Maps float64 dense returns to ``g(scale * R)`` (still float64)."""
        value = episode_return * self.scale
        if self.rounding == "floor":
            nearest = value.round()
            close = (value - nearest).abs() <= _SNAP_RTOL * nearest.abs().clamp_min(1.0)
            value = torch.where(close, nearest, value).floor()
        return value

    @staticmethod
    def _done_like(done: torch.Tensor, reward: torch.Tensor, done_key) -> torch.Tensor:
        done = done.bool()
        if done.ndim < reward.ndim:
            done = expand_as_right(done, reward)
        try:
            return done.expand_as(reward)
        except RuntimeError as err:
            raise ValueError(
                f"The done entry {done_key!r} of shape {tuple(done.shape)} cannot be "
                f"broadcast to the reward shape {tuple(reward.shape)}."
            ) from err

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        _reset = _get_reset(self.reset_keys[0], tensordict)
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

    def _step(
        self, tensordict: TensorDictBase, next_tensordict: TensorDictBase
    ) -> TensorDictBase:
        reward = next_tensordict.get(self.reward_key, None)
        if reward is None:
            raise KeyError(
                f"{type(self).__name__}: reward entry {self.reward_key!r} not found in the "
                "step output; set reward_key to the env's reward key."
            )
        done = next_tensordict.get(self.done_key, None)
        if done is None:
            raise KeyError(
                f"{type(self).__name__}: done entry {self.done_key!r} not found in the "
                "step output; set done_key to the env's done key."
            )
        prev = tensordict.get(self.return_key, None)
        if prev is None:
            prev = torch.zeros(reward.shape, dtype=torch.float64, device=reward.device)
        episode_return = prev + reward.to(torch.float64)
        done = self._done_like(done, reward, self.done_key)
        delayed = torch.where(
            done, self._delayed_value(episode_return), 0.0
        ).to(reward.dtype)
        next_tensordict.set(self.return_key, episode_return)
        next_tensordict.set(self.reward_key, delayed)
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
        if tensordict.batch_dims == 0:
            raise ValueError(
                f"{type(self).__name__}.forward needs trajectories with a time dimension "
                f"(batch shape [*, T]); got batch_size={tuple(tensordict.batch_size)}."
            )
        names = tensordict.names
        time_dim = names.index("time") if "time" in names else tensordict.batch_dims - 1
        reward_key = unravel_key(("next", self.reward_key))
        done_key = unravel_key(("next", self.done_key))
        reward = tensordict.get(reward_key, None)
        if reward is None:
            raise KeyError(
                f"{type(self).__name__}.forward: dense reward {reward_key!r} not found in "
                "the tensordict; set reward_key to the key of the dense reward."
            )
        done = tensordict.get(done_key, None)
        if done is None:
            raise KeyError(
                f"{type(self).__name__}.forward: {done_key!r} not found in the "
                "tensordict; the episode ends are needed to split the trajectories."
            )
        done = self._done_like(done, reward, done_key)
        episode_return = _segment_cumsum(
            reward.to(torch.float64).movedim(time_dim, -1),
            done.movedim(time_dim, -1),
        ).movedim(-1, time_dim)
        delayed = torch.where(
            done, self._delayed_value(episode_return), 0.0
        ).to(reward.dtype)
        tensordict.set(unravel_key(("next", self.return_key)), episode_return)
        tensordict.set(reward_key, delayed)
        return tensordict

    def _return_spec(self) -> Unbounded:
        parent = self.parent
        reward_spec = parent.full_reward_spec
        if self.reward_key not in parent.reward_keys:
            raise KeyError(
                f"{type(self).__name__}: reward_key {self.reward_key!r} is not in the env "
                f"reward keys {parent.reward_keys}."
            )
        spec = reward_spec[self.reward_key]
        return Unbounded(shape=spec.shape, dtype=torch.float64, device=spec.device)

    def _add_return_spec(self, spec: Composite) -> Composite:
        spec[self.return_key] = self._return_spec()
        return spec

    def transform_observation_spec(self, observation_spec: TensorSpec) -> TensorSpec:
        # Specs are rebuilt after every append/insert, so this also catches transforms
        # added to the Compose after set_container ran.
        self._check_placement()
        return self._add_return_spec(observation_spec)

    def transform_input_spec(self, input_spec: TensorSpec) -> TensorSpec:
        input_spec = super().transform_input_spec(input_spec)
        state_spec = input_spec["full_state_spec"]
        if state_spec is None:
            state_spec = Composite(shape=input_spec.shape, device=input_spec.device)
        input_spec["full_state_spec"] = self._add_return_spec(state_spec)
        return input_spec

    def transform_reward_spec(self, reward_spec: TensorSpec) -> TensorSpec:
        # The delayed reward can leave any bound of the dense reward, so only the dtype,
        # shape and device are kept.
        spec = reward_spec[self.reward_key]
        if not isinstance(spec, Unbounded):
            reward_spec[self.reward_key] = Unbounded(
                shape=spec.shape, dtype=spec.dtype, device=spec.device
            )
        return reward_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(scale={self.scale}, rounding={self.rounding!r}, "
            f"reward_key={self.reward_key!r}, done_key={self.done_key!r}, "
            f"return_key={self.return_key!r})"
        )


def _flatten(transforms: Sequence[Transform]) -> list[Transform]:
    flat = []
    for transform in transforms:
        if isinstance(transform, Compose):
            flat.extend(_flatten(list(transform.transforms)))
        else:
            flat.append(transform)
    return flat


def _describe(transform: Transform) -> str:
    if isinstance(transform, StepCounter):
        return f"StepCounter(max_steps={transform.max_steps})"
    return f"{type(transform).__name__}()"


def _segment_cumsum(values: torch.Tensor, done: torch.Tensor) -> torch.Tensor:
    """Running sums along the last dim, restarting after each ``done``.

    Every episode is scattered into its own zero-padded row and summed with one
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
