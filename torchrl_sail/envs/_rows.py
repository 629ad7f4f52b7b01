"""Row-wise transforms of a block of batches compute once per distinct stored row."""

from __future__ import annotations

import torch


def distinct_rows(ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor] | None:
    """``(one position per distinct id, each row's index into those)`` for row ids, ``None`` if all differ.

    ``values[first][inverse]`` then equals ``values`` for any per-row function of rows that share
    their id. Finding the distinct ids synchronises with the host once on CUDA.
    """
    ids = ids.reshape(-1)
    distinct, inverse = torch.unique(ids, return_inverse=True)
    if distinct.numel() == ids.numel():
        return None
    # any of an id's repeats stands for it: they hold the same row
    first = torch.empty_like(distinct).scatter_(0, inverse, torch.arange(ids.numel(), device=ids.device))
    return first, inverse
