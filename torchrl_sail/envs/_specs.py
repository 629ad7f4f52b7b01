"""Spec helper shared by the transforms that append a column to an observation."""

from __future__ import annotations

import torch
from torchrl.data.tensor_specs import Bounded, TensorSpec, Unbounded


def append_unit_column(spec: TensorSpec, *, owner: str, key) -> TensorSpec:
    """``spec`` one wider on its last dim: a ``Bounded`` spec gets ``[0, 1]`` bounds for the new
    column, an ``Unbounded`` one stays ``Unbounded``; other specs are refused, naming ``owner``."""
    shape = (*spec.shape[:-1], spec.shape[-1] + 1)
    if isinstance(spec, Bounded):
        low, high = spec.space.low, spec.space.high
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
        f"{owner} extends Bounded and Unbounded observation specs only; {key!r} has a {type(spec).__name__} spec."
    )
