"""A teacher's observation columns against the env's: which ones the env does not reproduce, and
choosing the columns to keep.

A demonstration recorded under another simulator version can hold columns the env fills
differently: the SAIL authors' Ant files hold Ant's 84 contact-force columns as 0.0 in every row
(mujoco-py 2.x reported none), where Ant-v4 fills them. A discriminator then tells the teacher's
rows from the agent's by those columns alone. :func:`unreproduced_columns` finds such columns from
a short rollout of the env; :func:`parse_columns` and :func:`keep_columns` drop or keep columns of
the demonstrations (the env must then produce the same columns, e.g. Ant-v4 with
``use_contact_forces=False``).
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase

__all__ = ["column_ranges", "keep_columns", "parse_columns", "unreproduced_columns"]

#: A teacher column lies "far outside" the env's when it is more than this many env ranges away from it.
FAR = 10.0


def parse_columns(spec: str, width: int, *, key: str = "columns") -> list[int]:
    """The column indices of ``spec``: comma-separated indices and inclusive ranges, e.g. ``"0-26,111"``.

    Raises:
        ValueError: a malformed item, a reversed range or an index outside ``[0, width)``, naming
            ``key`` (the config key the spec came from) and ``width``.

    Examples:
        >>> parse_columns("27-29, 5", width=112)
        [5, 27, 28, 29]
    """
    columns = set()
    for item in str(spec).split(","):
        item = item.strip()
        low, _, high = item.partition("-")
        try:
            first, last = int(low), int(high or low)
        except ValueError:
            raise ValueError(
                f"{key}={spec!r}: {item!r} is not an index or a range like 27-110 (comma-separated)"
            ) from None
        if first > last or first < 0 or last >= width:
            raise ValueError(
                f"{key}={spec!r}: {item!r} is not a range of columns 0-{width - 1} (the teacher's {width})"
            )
        columns.update(range(first, last + 1))
    return sorted(columns)


def column_ranges(columns: list[int]) -> str:
    """The inverse of :func:`parse_columns`: ``[5, 27, 28, 29]`` is ``"5,27-29"``.

    Examples:
        >>> column_ranges([5, 27, 28, 29])
        '5,27-29'
    """
    ranges, start = [], None
    for i, column in enumerate(columns):
        if start is None:
            start = column
        if i + 1 == len(columns) or columns[i + 1] != column + 1:
            ranges.append(str(start) if start == column else f"{start}-{column}")
            start = None
    return ",".join(ranges)


def keep_columns(data: TensorDictBase, columns: list[int], *, key: str = "observation") -> TensorDictBase:
    """``data`` with only ``columns`` of ``key`` and ``("next", key)`` (in that order), a new tensordict."""
    index = torch.as_tensor(columns, dtype=torch.long)
    data = data.clone(recurse=False)
    data["next"] = data["next"].clone(recurse=False)
    for name in (key, ("next", key)):
        data.set(name, data.get(name).index_select(-1, index.to(data.get(name).device)))
    return data


def unreproduced_columns(
    teacher: torch.Tensor, env: torch.Tensor, *, env_episodes: torch.Tensor | None = None, far: float = FAR
) -> list[dict]:
    """The columns of ``teacher`` observations (``[N, D]``) that ``env`` observations (``[M, D]``, e.g. a
    short random rollout) do not reproduce.

    A column is named when it is constant in the teacher and varies in the env within an episode
    (``"constant"``; ``env_episodes``, ``[M]`` episode ids, tells the episodes apart: a column the env
    holds constant through each episode, such as Reacher's target, is not named), or when the
    teacher's values lie more than ``far`` times the env's range away from it (``"outside"``). A
    teacher's skill alone moves few columns that far: a random rollout is enough.

    Returns:
        One ``{"column", "kind", "teacher": (min, max), "env": (min, max)}`` per column, in order.

    Examples:
        >>> teacher = torch.tensor([[0.0, 1.0, 500.0], [0.0, 2.0, 501.0]])
        >>> env = torch.tensor([[0.3, 1.5, 0.0], [-0.2, 2.5, 1.0]])
        >>> [(c["column"], c["kind"]) for c in unreproduced_columns(teacher, env)]
        [(0, 'constant'), (2, 'outside')]
        >>> [c["column"] for c in unreproduced_columns(teacher, env, env_episodes=torch.tensor([0, 1]))]
        [2]
    """
    # a one-time check before training: on the CPU, whatever device the demonstrations or the env are on
    teacher, env = teacher.detach().cpu().double(), env.detach().cpu().double()
    if env_episodes is not None:
        env_episodes = env_episodes.cpu()
    t_low, t_high = teacher.min(0).values, teacher.max(0).values
    e_low, e_high = env.min(0).values, env.max(0).values
    e_range = e_high - e_low
    if env_episodes is None:
        varies = e_range > 0
    else:
        varies = torch.zeros_like(e_range, dtype=torch.bool)
        for episode in env_episodes.unique():
            rows = env[env_episodes == episode]
            varies |= rows.max(0).values > rows.min(0).values
    distance = torch.maximum(e_low - t_high, t_low - e_high).clamp_min(0)
    found = []
    for column in range(teacher.shape[-1]):
        if t_low[column] == t_high[column] and varies[column]:
            kind = "constant"
        elif e_range[column] > 0 and distance[column] > far * e_range[column]:
            kind = "outside"
        else:
            continue
        found.append(
            {
                "column": column,
                "kind": kind,
                "teacher": (t_low[column].item(), t_high[column].item()),
                "env": (e_low[column].item(), e_high[column].item()),
            }
        )
    return found
