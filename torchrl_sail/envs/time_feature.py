"""Remaining-time observation feature, as in the SAIL teacher demonstrations.

The SAIL authors trained their teachers and agents on observations with one extra last
column, the remaining-time feature ``1 - t/T`` of stable-baselines' ``TimeFeatureWrapper``
(``t`` = steps already taken in the episode, ``T`` = the time limit, 1000 for MuJoCo).
The published teacher ``.npz`` files store it, so a policy or discriminator that consumes
those demonstrations needs the same column on the env observations. This module appends it
from the step count that TorchRL's :class:`~torchrl.envs.StepCounter` already keeps.
"""
from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase, unravel_key
from tensordict.utils import NestedKey
from torchrl.data.tensor_specs import Bounded, Composite, TensorSpec, Unbounded
from torchrl.envs.transforms import Transform

__all__ = ["TimeFeature"]


class TimeFeature(Transform):
    """Appends the remaining-time feature ``1 - t/T`` as the last observation column.

    ``t`` is the number of steps already taken in the episode, read from the
    ``step_count_key`` entry written by :class:`~torchrl.envs.StepCounter` (so the
    feature is ``1.0`` on the reset observation and ``1 - t/T`` after ``t`` steps), and
    ``T = max_steps``. This is exactly the column of the SAIL teacher demonstrations
    (stable-baselines ``TimeFeatureWrapper``, ``T = 1000`` for the MuJoCo tasks). The
    feature is not clipped: if episodes run longer than ``max_steps`` it goes negative,
    as in the original wrapper, so keep ``max_steps`` equal to the time limit.

    ``StepCounter()`` must come before ``TimeFeature`` in the
    :class:`~torchrl.envs.Compose` (this transform does not count steps itself); a
    missing step count raises a ``KeyError`` that says so.

    The observation spec grows by one on its last dim with the same dtype; a ``Bounded``
    spec gets ``[0, 1]`` bounds for the new column, an ``Unbounded`` one stays
    ``Unbounded``. The feature has the dtype of the observation.

    Offline, calling the transform (:meth:`forward`) on a transition tensordict appends
    the feature to the root observation (using the root ``step_count_key``) and to the
    ``("next", ...)`` observation (using ``("next", step_count_key)``). It is not
    idempotent: apply it to raw observations only once.

    Keyword Args:
        max_steps (int): the time limit ``T`` (> 0). 1000 for the MuJoCo tasks.
        in_keys (list of NestedKey, optional): observations to extend. Defaults to
            ``["observation"]``.
        out_keys (list of NestedKey, optional): where the extended observations are
            written. Defaults to ``in_keys``.
        step_count_key (NestedKey, optional): the step count entry. Defaults to
            ``"step_count"``.

    Examples:
        >>> from torchrl.envs import Compose, DoubleToFloat, GymEnv, StepCounter, TransformedEnv
        >>> from torchrl_sail import TimeFeature
        >>> env = TransformedEnv(
        ...     GymEnv("Pendulum-v1"),
        ...     Compose(DoubleToFloat(), StepCounter(), TimeFeature(max_steps=200)),
        ... )
        >>> env.observation_spec["observation"].shape
        torch.Size([4])
        >>> _ = env.set_seed(0)
        >>> rollout = env.rollout(3)
        >>> rollout["observation"][:, -1].tolist()
        [1.0, 0.9950000047683716, 0.9900000095367432]
        >>> round(rollout["next", "observation"][-1, -1].item(), 4)
        0.985
    """

    def __init__(
        self,
        *,
        max_steps: int,
        in_keys: Sequence[NestedKey] | None = None,
        out_keys: Sequence[NestedKey] | None = None,
        step_count_key: NestedKey = "step_count",
    ) -> None:
        if isinstance(max_steps, bool) or not isinstance(max_steps, int):
            raise TypeError(
                f"max_steps must be an int (the episode time limit T), got {max_steps!r} "
                f"({type(max_steps).__name__})."
            )
        if max_steps <= 0:
            raise ValueError(f"max_steps must be > 0, got {max_steps}.")
        if in_keys is None:
            in_keys = ["observation"]
        if out_keys is None:
            out_keys = in_keys
        super().__init__(in_keys=in_keys, out_keys=out_keys)
        if len(self.in_keys) != len(self.out_keys):
            raise ValueError(
                f"TimeFeature needs one out_key per in_key, got in_keys={self.in_keys} "
                f"and out_keys={self.out_keys}."
            )
        self.max_steps = max_steps
        self.step_count_key = unravel_key(step_count_key)

    def _missing_step_count(self, where: str) -> KeyError:
        return KeyError(
            f"TimeFeature: step count entry {self.step_count_key!r} not found in {where}. "
            "TimeFeature reads the step count written by torchrl's StepCounter: put "
            "StepCounter() before TimeFeature in the Compose (or set step_count_key)."
        )

    def _feature(self, step_count: torch.Tensor, obs: torch.Tensor) -> torch.Tensor:
        # Computed in float64, then cast once, so the float32 value is the nearest to
        # 1 - t/T (as the teacher data, which match it to ~3e-8).
        if not obs.is_floating_point():
            raise TypeError(
                f"TimeFeature: observations must be floating point to hold 1 - t/T, got "
                f"{obs.dtype}; cast them first (e.g. DoubleToFloat or DTypeCastTransform)."
            )
        feature = (1.0 - step_count.to(torch.float64) / self.max_steps).to(obs.dtype)
        target = (*obs.shape[:-1], 1)
        if feature.ndim == len(target) - 1:
            feature = feature.unsqueeze(-1)
        try:
            return feature.expand(target)
        except RuntimeError as err:
            raise ValueError(
                f"TimeFeature: step count of shape {tuple(step_count.shape)} does not "
                f"match the observation of shape {tuple(obs.shape)}; expected a step "
                f"count of shape {target}."
            ) from err

    def _append(self, tensordict: TensorDictBase, where: str) -> TensorDictBase:
        step_count = None
        for in_key, out_key in zip(self.in_keys, self.out_keys):
            obs = tensordict.get(in_key, None)
            if obs is None:
                if not self.missing_tolerance:
                    raise KeyError(
                        f"TimeFeature: observation {in_key!r} not found in {where}; "
                        "set in_keys to the observation entries to extend."
                    )
                continue
            if step_count is None:
                step_count = tensordict.get(self.step_count_key, None)
                if step_count is None:
                    raise self._missing_step_count(where)
            tensordict.set(
                out_key, torch.cat([obs, self._feature(step_count, obs)], dim=-1)
            )
        return tensordict

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        return self._append(next_tensordict, "the step output")

    def _reset(
        self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase
    ) -> TensorDictBase:
        return self._append(tensordict_reset, "the reset output")

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Appends the feature to the root and ``("next", ...)`` observations.

        Each observation uses the step count next to it: the root ``step_count_key``
        for the root observation and ``("next", step_count_key)`` for the next one.
        Entries whose observation is absent are skipped, but at least one must be there.

        Args:
            tensordict (TensorDictBase): a transition (or trajectory) tensordict.

        Returns:
            the same tensordict, updated in place.
        """
        found = False
        next_td = tensordict.get("next", None)
        for td, where in ((tensordict, "the root tensordict"), (next_td, '"next"')):
            if td is None or not isinstance(td, TensorDictBase):
                continue
            present = [k for k in self.in_keys if td.get(k, None) is not None]
            if not present:
                continue
            found = True
            if len(present) != len(self.in_keys):
                missing = [k for k in self.in_keys if k not in present]
                raise KeyError(
                    f"TimeFeature: observations {missing} not found in {where}."
                )
            self._append(td, where)
        if not found:
            raise KeyError(
                f"TimeFeature: none of the observations {self.in_keys} were found at the "
                "root or under 'next' of the tensordict."
            )
        return tensordict

    def _extend_spec(self, spec: TensorSpec, key: NestedKey) -> TensorSpec:
        shape = (*spec.shape[:-1], spec.shape[-1] + 1)
        if isinstance(spec, Bounded):
            low = spec.space.low
            high = spec.space.high
            col = torch.zeros((*low.shape[:-1], 1), dtype=low.dtype, device=low.device)
            return Bounded(
                low=torch.cat([low, col], -1),
                high=torch.cat([high, col + 1], -1),
                shape=shape,
                dtype=spec.dtype,
                device=spec.device,
            )
        if isinstance(spec, Unbounded):
            return Unbounded(shape=shape, dtype=spec.dtype, device=spec.device)
        raise TypeError(
            f"TimeFeature: observation {key!r} has a {type(spec).__name__} spec; only "
            "Bounded and Unbounded (continuous) observation specs can be extended."
        )

    def transform_observation_spec(self, observation_spec: TensorSpec) -> TensorSpec:
        if not isinstance(observation_spec, Composite):
            raise TypeError(
                "TimeFeature expects a Composite observation spec, got "
                f"{type(observation_spec).__name__}."
            )
        keys = observation_spec.keys(True, True)
        if self.step_count_key not in keys:
            raise self._missing_step_count("the observation spec")
        for in_key, out_key in zip(self.in_keys, self.out_keys):
            if in_key not in keys:
                raise KeyError(
                    f"TimeFeature: observation {in_key!r} not in the observation spec "
                    f"(keys: {list(keys)}); set in_keys accordingly."
                )
            observation_spec[out_key] = self._extend_spec(
                observation_spec[in_key], in_key
            )
        return observation_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(max_steps={self.max_steps}, in_keys={self.in_keys}, "
            f"out_keys={self.out_keys}, step_count_key={self.step_count_key!r})"
        )
