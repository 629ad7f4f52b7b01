"""The project's own demonstration format: a folder of tensordict memmap files plus ``metadata.json``.

This module imports only the core, :mod:`torchrl_sail.data.episodes`, and registers its
reader there (a folder with ``metadata.json``).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase

from torchrl_sail.data.episodes import (
    Demonstrations,
    check_transitions,
    json_default,
    publish_directory,
    register_reader,
    resolve_time_feature,
)

__all__ = ["METADATA_FILE", "load_demonstration_folder", "save_demonstrations"]

#: Our metadata file; tensordict writes its own ``meta.json`` beside it.
METADATA_FILE = "metadata.json"
_TENSORDICT_META = "meta.json"


def save_demonstrations(
    path: str | os.PathLike,
    demos_or_data: Demonstrations | TensorDictBase,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Saves demonstrations to a directory: tensordict's memmap files plus ``metadata.json``.

    The transitions are written by :meth:`~tensordict.TensorDict.memmap` (a ``.memmap``
    file per entry and tensordict's own ``meta.json``), the metadata as ``metadata.json``
    beside them. All of it goes to a staging directory next to ``path`` that is then
    swapped in, so a failed save leaves an existing dataset intact.

    ``episode_returns`` and ``episode_lengths`` are computed from ``("next", "reward")``
    and ``("next", "done")`` when the metadata lacks them; ``source`` defaults to ``path``.

    Args:
        path: the destination directory, replaced if it exists. A ``.npz`` name is refused
            (:func:`~torchrl_sail.load_demonstrations` reads it as the stable-baselines format).
        demos_or_data: a :class:`~torchrl_sail.Demonstrations` or a flat ``[N]`` transition
            tensordict.
        metadata: JSON-able metadata (numpy/torch values are converted); updates the
            metadata of a :class:`~torchrl_sail.Demonstrations`.

    Returns:
        Path: the written directory.

    Raises:
        ValueError: a ``.npz`` name, or transitions that fail the checks of
            :func:`~torchrl_sail.data.episodes.check_transitions` (a NaN included).
        TypeError: neither demonstrations nor a tensordict, or metadata that is not JSON-able.

    Examples:
        >>> import os, tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import load_demonstrations, save_demonstrations
        >>> done = torch.tensor([[False], [True], [False], [True]])
        >>> td = TensorDict({"observation": torch.zeros(4, 2), "action": torch.zeros(4, 1),
        ...     ("next", "observation"): torch.ones(4, 2), ("next", "reward"): torch.ones(4, 1),
        ...     ("next", "done"): done, ("next", "terminated"): done,
        ...     ("next", "truncated"): torch.zeros_like(done)}, batch_size=[4])
        >>> path = save_demonstrations(os.path.join(tempfile.mkdtemp(), "demos"), td)
        >>> data, meta = load_demonstrations(path)
        >>> meta["episode_returns"], meta["episode_lengths"]
        ([2.0, 2.0], [2, 2])
        >>> bool((data == td).all())
        True
    """
    path = Path(path)
    if path.suffix == ".npz":
        raise ValueError(f"{path}: '.npz' names the stable-baselines format; use another name.")
    if isinstance(demos_or_data, Demonstrations):
        data, meta = demos_or_data.data, {**demos_or_data.metadata, **(metadata or {})}
    elif isinstance(demos_or_data, TensorDictBase):
        data, meta = demos_or_data, dict(metadata or {})
    else:
        raise TypeError(f"expected Demonstrations or a TensorDict, got {type(demos_or_data)}.")
    check_transitions(data, f"data to save to {path}")
    if "episode_returns" not in meta or "episode_lengths" not in meta:
        ends = torch.nonzero(data["next", "done"].reshape(-1)).reshape(-1) + 1
        lengths = torch.diff(ends, prepend=ends.new_zeros(1)).tolist()
        episodes = data["next", "reward"].reshape(-1).double().split(lengths)
        meta.setdefault("episode_returns", [float(rewards.sum()) for rewards in episodes])
        meta.setdefault("episode_lengths", lengths)
    meta.setdefault("source", str(path))

    text = json.dumps(meta, indent=2, default=json_default(f"metadata for {path}"))

    def write(staging: Path) -> None:
        data.detach().cpu().memmap(staging, copy_existing=True)
        (staging / METADATA_FILE).write_text(text)

    publish_directory(path, write)
    return path


def load_demonstration_folder(
    path: str | os.PathLike, *, max_episode_steps: int = 1000, time_feature: bool | None = None
) -> Demonstrations:
    """Loads a :func:`save_demonstrations` folder, checked, into an in-memory tensordict.

    The folder is read with :meth:`~tensordict.TensorDict.load_memmap` (pickled objects
    refused) into an ordinary tensordict, with its ``metadata.json``, and checked by
    :func:`~torchrl_sail.data.episodes.check_transitions` (a NaN or infinity is an error
    naming the entry and row).

    Time feature (:func:`~torchrl_sail.data.episodes.resolve_time_feature`, the rule of every
    format): ``time_feature=None`` (default) or ``False`` returns the data as saved (nothing is
    detected: the metadata saved with it says whether it has the column);
    ``True`` keeps a last observation column equal to ``1 - t/T`` (``t`` from
    ``"step_count"``, else counted from the done flags; ``T = max_episode_steps``) and
    otherwise appends it; it sets the metadata's ``time_feature`` and
    ``time_feature_appended``.

    Args:
        path: the folder.

    Keyword Args:
        max_episode_steps (int): ``T`` of the time feature. Defaults to ``1000``.
        time_feature (bool, optional): see above. Defaults to ``None``.

    Returns:
        Demonstrations: ``(data, metadata)``.

    Raises:
        FileNotFoundError: no ``metadata.json`` in ``path``.
        ValueError: invalid content (the message names the folder, the entry and the problem),
            or a last column that is the time feature of another ``T``.

    Examples:
        >>> import os, tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import save_demonstrations
        >>> from torchrl_sail.data.folder import load_demonstration_folder
        >>> done = torch.tensor([[False], [True]])
        >>> td = TensorDict({"observation": torch.zeros(2, 2), "action": torch.zeros(2, 1),
        ...     ("next", "observation"): torch.zeros(2, 2), ("next", "reward"): torch.ones(2, 1),
        ...     ("next", "done"): done, ("next", "terminated"): done,
        ...     ("next", "truncated"): torch.zeros_like(done)}, batch_size=[2])
        >>> path = save_demonstrations(os.path.join(tempfile.mkdtemp(), "demos"), td)
        >>> data, meta = load_demonstration_folder(path, time_feature=True, max_episode_steps=10)
        >>> data["observation"][:, -1].tolist(), meta["time_feature_appended"]
        ([1.0, 0.8999999761581421], True)
    """
    path = Path(path)
    if max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}.")
    if not (path / METADATA_FILE).is_file():
        raise FileNotFoundError(f"{path}: no {METADATA_FILE}; not a folder written by save_demonstrations.")
    data = TensorDict.load_memmap(path, allow_pickle=False).to_tensordict()
    check_transitions(data, str(path))
    metadata = json.loads((path / METADATA_FILE).read_text())
    if time_feature:  # (None: as saved, the folder's metadata says whether it has the column)
        data, has_feature, appended = resolve_time_feature(
            data, max_episode_steps=max_episode_steps, time_feature=True, where=str(path)
        )
        metadata.update(time_feature=has_feature, time_feature_appended=appended)
        if appended and "observation_dim" in metadata:
            metadata["observation_dim"] = int(data["observation"].shape[-1])
    return Demonstrations(data, metadata)


def _is_folder(path: str | os.PathLike) -> bool:
    # both metadata files: a Minari dataset's data/ folder has a metadata.json too
    return (Path(path) / METADATA_FILE).is_file() and (Path(path) / _TENSORDICT_META).is_file()


register_reader(
    f"a directory written by save_demonstrations (with {METADATA_FILE})", _is_folder, load_demonstration_folder
)
