"""Remaining-time observation feature, as in the SAIL teacher demonstrations.

The SAIL authors trained their teachers and agents on observations with one extra last
column, the remaining-time feature ``1 - t/T`` of stable-baselines' ``TimeFeatureWrapper``
(``t`` = steps already taken in the episode, ``T`` = the time limit, 1000 for MuJoCo).
The published teacher ``.npz`` files store it, so an actor or discriminator that consumes
those demonstrations needs the same column on the env observations. This module appends it
from the step count that TorchRL's :class:`~torchrl.envs.StepCounter` already keeps.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase, unravel_key
from tensordict.utils import NestedKey
from torchrl.data.tensor_specs import TensorSpec
from torchrl.envs.transforms import Transform

from torchrl_sail.envs._specs import append_unit_column

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

    .. note:: **Placement in a** :class:`~torchrl.envs.Compose`. Put ``StepCounter()``
        before ``TimeFeature``: this transform does not count steps itself, and reads
        the count that ``StepCounter`` wrote (a ``KeyError`` on ``step_count_key``
        otherwise).

    The observations must be floating point (e.g. after ``DoubleToFloat``): the feature
    has the dtype of the observation. The observation spec grows by one on its last dim
    with the same dtype; a ``Bounded`` spec gets ``[0, 1]`` bounds for the new column,
    an ``Unbounded`` one stays ``Unbounded``.

    Offline, calling the transform (:meth:`forward`) on a transition tensordict appends
    the feature to the root observation (using the root ``step_count_key``) and to the
    ``("next", ...)`` observation (using ``("next", step_count_key)``). It is not
    idempotent: apply it to raw observations only once.

    Keyword Args:
        max_steps (int): the time limit ``T`` (> 0). 1000 for the MuJoCo tasks.
        in_keys (list of NestedKey, optional): observations to extend. Defaults to
            ``["observation"]``.
        out_keys (list of NestedKey, optional): where the extended observations are
            written, one per ``in_key``. Defaults to ``in_keys``.
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
        if max_steps <= 0:
            raise ValueError(f"max_steps must be > 0, got {max_steps}.")
        if in_keys is None:
            in_keys = ["observation"]
        if out_keys is None:
            out_keys = in_keys
        super().__init__(in_keys=in_keys, out_keys=out_keys)
        if len(self.in_keys) != len(self.out_keys):
            # zip would silently drop the extra in_keys
            raise ValueError(
                f"out_keys needs one entry per in_key, got in_keys={self.in_keys} and out_keys={self.out_keys}."
            )
        self.max_steps = max_steps
        self.step_count_key = unravel_key(step_count_key)

    def _append(self, tensordict: TensorDictBase) -> TensorDictBase:
        step_count = tensordict[self.step_count_key]
        for in_key, out_key in zip(self.in_keys, self.out_keys, strict=True):
            obs = tensordict[in_key]
            # Computed in float64, then cast once, so the float32 value is the nearest
            # to 1 - t/T (as the teacher data, which match it to ~3e-8).
            feature = (1.0 - step_count.to(torch.float64) / self.max_steps).to(obs.dtype)
            if feature.ndim == obs.ndim - 1:
                feature = feature.unsqueeze(-1)
            feature = feature.expand(*obs.shape[:-1], 1)
            tensordict.set(out_key, torch.cat([obs, feature], dim=-1))
        return tensordict

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        return self._append(next_tensordict)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        return self._append(tensordict_reset)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Appends the feature to the root and ``("next", ...)`` observations.

        Each observation uses the step count next to it: the root ``step_count_key``
        for the root observation and ``("next", step_count_key)`` for the next one.
        A level (root or ``"next"``) that holds none of the observations is skipped.

        Args:
            tensordict (TensorDictBase): a transition (or trajectory) tensordict.

        Returns:
            the same tensordict, updated in place.
        """
        for td in (tensordict, tensordict.get("next", None)):
            if td is not None and any(k in td.keys(True) for k in self.in_keys):
                self._append(td)
        return tensordict

    def transform_observation_spec(self, observation_spec: TensorSpec) -> TensorSpec:
        for in_key, out_key in zip(self.in_keys, self.out_keys, strict=True):
            observation_spec[out_key] = append_unit_column(observation_spec[in_key], owner="TimeFeature", key=in_key)
        return observation_spec

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(max_steps={self.max_steps}, in_keys={self.in_keys}, "
            f"out_keys={self.out_keys}, step_count_key={self.step_count_key!r})"
        )
