"""Teacher demonstrations: loading the paper's files, saving and loading our own format.

SAIL starts its teacher buffer from a few sub-optimal demonstrations. The paper's
demonstrations are stable-baselines ``ExpertDataset`` ``.npz`` files (see
``shared/data/teachers/README.md``) whose layout differs from TorchRL's in ways that are
easy to get wrong: episode boundaries are stored as an object array of "episode starts",
the recorded ``next_obs`` of the last step of an episode is the *next* episode's reset
observation (the recorder auto-reset), the HalfCheetah files have no ``next_obs`` at all,
and every observation carries one extra column, the remaining-time feature ``1 - t/T``.

This module turns such a file into a flat TorchRL transition tensordict that follows the
project's data conventions (``"observation"``, ``"action"``, ``("next", ...)`` entries with
``done = terminated | truncated`` and ``"step_count"``), and offers one simple, safe
on-disk format of our own (a ``torch.save`` dict that loads with ``weights_only=True``,
written atomically) so converted or collected demonstrations can be stored and reloaded.

Rewards are kept *dense* (the recorded per-step MuJoCo rewards). SAIL's learner only ever
sees the delayed, trajectory-wise reward; producing it from these dense rewards is the job
of :class:`~torchrl_sail.DelayedRewardTransform` (offline mode), applied by the user after
loading, so the demonstrations themselves stay a faithful copy of the file.
"""
from __future__ import annotations

import json
import os
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.utils import NestedKey

from torchrl_sail._io import atomic_save
from torchrl_sail.data._keys import TRANSITION_KEYS

__all__ = [
    "Demonstrations",
    "check_demonstration_dims",
    "load_demonstrations",
    "load_sb_demonstrations",
    "save_demonstrations",
]

FORMAT_TAG = "torchrl_sail.demonstrations"
FORMAT_VERSION = 1
SB_FORMAT_TAG = "stable_baselines.ExpertDataset"

# Keys every transition tensordict must carry (README "Data conventions").
_REQUIRED_KEYS = TRANSITION_KEYS
_SB_REQUIRED_KEYS = ("obs", "actions", "rewards", "episode_starts")
# SAIL's teacher files are named expert_data_no_img_<Env>_scores_<score>_episodes_<n>.npz
_SB_NAME = re.compile(
    r"expert_data_(?:no_img_)?(?P<env>[A-Za-z0-9]+)_scores_(?P<score>-?[0-9.]+)"
    r"_episodes_(?P<n>[0-9]+)$"
)
# float32 rounding in the recorder: actions may exceed +-1 by ~1e-7
_ACTION_ROUNDING = 1e-5
# The time column of the paper's files matches 1 - t/T to ~3e-8.
_TIME_FEATURE_ATOL = 1e-5


class Demonstrations(NamedTuple):
    """Teacher demonstrations: flat transitions plus JSON-able metadata.

    ``data`` holds ``N`` transitions (batch size ``[N]``), the episodes concatenated in file
    order; an episode ends at each row where ``("next", "done")`` is ``True``.
    ``metadata`` always has ``episode_returns`` (dense, undiscounted, one float per
    episode), ``episode_lengths``, ``source`` (the file the data was first read from) and
    ``format`` (that file's format), plus whatever the file or the recorder provides.

    Being a ``NamedTuple`` it unpacks as ``data, metadata = load_demonstrations(path)``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail.data.demonstrations import Demonstrations
        >>> done = torch.tensor([[False], [True]])
        >>> td = TensorDict(
        ...     {
        ...         "observation": torch.zeros(2, 3),
        ...         "action": torch.zeros(2, 1),
        ...         "next": {
        ...             "observation": torch.zeros(2, 3),
        ...             "reward": torch.ones(2, 1),
        ...             "done": done,
        ...             "terminated": done.clone(),
        ...             "truncated": torch.zeros(2, 1, dtype=torch.bool),
        ...         },
        ...     },
        ...     batch_size=[2],
        ... )
        >>> data, metadata = Demonstrations(td, {"episode_returns": [2.0]})
        >>> data.batch_size, metadata["episode_returns"]
        (torch.Size([2]), [2.0])
    """

    data: TensorDictBase
    metadata: dict[str, Any]


# --------------------------------------------------------------------------------------
# stable-baselines ExpertDataset (.npz)
# --------------------------------------------------------------------------------------
def load_sb_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a stable-baselines ``ExpertDataset`` ``.npz`` file (the SAIL teacher files).

    The file is read with ``numpy.load(allow_pickle=True)`` because ``episode_starts`` is
    an object array: only load files you trust.

    The returned transitions follow the project's conventions:

    - ``"observation"``: the file's ``obs`` as float32, *including* its last column, the
      remaining-time feature ``1 - t/max_episode_steps`` the teacher was trained with (an
      env producing matching observations needs :class:`~torchrl_sail.TimeFeature`).
    - ``"action"``: float32; float32 rounding overshoots of ``[-1, 1]`` (about ``1e-7`` in
      the paper's files) are clamped.
    - ``"step_count"`` ``[N, 1]`` int64: the in-episode index ``t`` of ``"observation"``.
    - ``("next", "reward")`` ``[N, 1]`` float32: the recorded *dense* rewards. SAIL's
      delayed reward ``floor(0.1 * R)`` at the last step is obtained by applying
      ``DelayedRewardTransform`` to this data afterwards; the loader does not do it.
    - ``("next", "observation")``: ``obs[t + 1]`` of the same episode. The file's
      ``next_obs`` is never used: its last entry per episode is the next episode's reset
      observation, and the HalfCheetah files do not have it.
    - ``("next", "done")`` is ``True`` on the last step of each episode, with
      ``("next", "terminated")`` if the episode is shorter than ``max_episode_steps`` (the
      Hopper teacher fell) and ``("next", "truncated")`` if it reached it.

    The true final next state of an episode was not recorded. It is approximated by the
    last observation with the time column advanced to ``1 - (t + 1)/max_episode_steps``
    (unchanged when the file has no time feature). Whether a TD target reads this
    approximation depends on how the episode ended and on the loss:

    - terminated episodes (``terminated=True``): never bootstrapped from;
    - truncated episodes (full ``max_episode_steps``: ``terminated=False``,
      ``truncated=True``): :class:`~torchrl_sail.SAILLoss` and TorchRL's ``TD3Loss``
      bootstrap unless ``("next", "terminated")`` is set, so by default their target
      *does* use the approximated next observation. It is never bootstrapped from only
      when the loss treats ``done`` as terminal, ``loss.set_keys(terminated="done")``:
      the authors' convention (``done=1`` at time-limit truncation, for teacher and
      agent data alike), which the SAIL example uses.

    The flags are kept as recorded (a time-limit end is ``truncated``, not
    ``terminated``); whether truncation is terminal is the loss's choice.

    Args:
        path: the ``.npz`` file.

    Keyword Args:
        max_episode_steps (int): the episode time limit ``T`` used when recording
            (1000 for the MuJoCo tasks, 50 for Reacher). Defaults to ``1000``.
        time_feature (bool, optional): whether the last observation column is the
            remaining-time feature. ``None`` (default) detects it by comparing the column
            with ``1 - t/T``; ``True`` raises if it does not match; ``False`` never
            touches the column.

    Returns:
        Demonstrations: ``(data, metadata)``; ``metadata["episode_returns"]`` are the
        file's recorded returns (checked against the per-episode sums of ``rewards``).

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the file is not a readable ``.npz``, misses a key, has inconsistent
            shapes, an episode longer than ``max_episode_steps``, or recorded returns that
            do not match its rewards. The message names the file.

    Examples:
        >>> import numpy as np, tempfile, os
        >>> from torchrl_sail import load_sb_demonstrations
        >>> T, lengths = 1000, [3, 2]  # two short episodes: both "fell"
        >>> t = np.concatenate([np.arange(n) for n in lengths])
        >>> obs = np.stack([np.full(5, 0.5), 1 - t / T], axis=1).astype("float32")
        >>> starts = np.empty(5, dtype=object)
        >>> starts[:] = [True] + [np.array([x]) for x in (False, False, True, False)]
        >>> path = os.path.join(tempfile.mkdtemp(), "demo.npz")
        >>> np.savez(path, obs=obs, actions=np.zeros((5, 1), "float32"),
        ...          rewards=np.ones((5, 1), "float32"), episode_returns=np.array([3.0, 2.0]),
        ...          episode_starts=starts)
        >>> data, meta = load_sb_demonstrations(path)
        >>> meta["episode_lengths"], meta["episode_returns"]
        ([3, 2], [3.0, 2.0])
        >>> data["next", "done"].squeeze(-1).tolist()
        [False, False, True, False, True]
        >>> data["step_count"].squeeze(-1).tolist()
        [0, 1, 2, 0, 1]
        >>> data["next", "terminated"].squeeze(-1).tolist()  # shorter than T: terminated
        [False, False, True, False, True]
        >>> round(data["next", "observation"][2, -1].item(), 3)  # 1 - 3/1000
        0.997
    """
    path = Path(path)
    if max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}.")
    arrays = _read_npz(path)
    for key in _SB_REQUIRED_KEYS:
        if key not in arrays:
            raise ValueError(
                f"{path}: missing key {key!r} (found {sorted(arrays)}); a stable-baselines "
                f"ExpertDataset .npz needs {list(_SB_REQUIRED_KEYS)}."
            )

    obs = np.asarray(arrays["obs"])
    if obs.ndim != 2:
        raise ValueError(f"{path}: 'obs' must be 2-D (N, obs_dim), got shape {obs.shape}.")
    n = obs.shape[0]
    if n == 0:
        raise ValueError(f"{path}: the file holds no transitions ('obs' is empty).")
    actions = np.asarray(arrays["actions"])
    if actions.ndim == 1:
        actions = actions[:, None]
    rewards = np.asarray(arrays["rewards"])
    if rewards.ndim == 2 and rewards.shape[1] == 1:
        rewards = rewards[:, 0]
    for key, arr in (("actions", actions), ("rewards", rewards)):
        if arr.shape[0] != n:
            raise ValueError(
                f"{path}: {key!r} has {arr.shape[0]} rows but 'obs' has {n}."
            )
    if rewards.ndim != 1:
        raise ValueError(
            f"{path}: 'rewards' must have shape (N,) or (N, 1), got {rewards.shape}."
        )
    starts = _episode_starts(path, arrays["episode_starts"], n)

    start_idx = np.flatnonzero(starts)
    end_idx = np.append(start_idx[1:], n)  # exclusive
    lengths = end_idx - start_idx
    too_long = np.flatnonzero(lengths > max_episode_steps)
    if too_long.size:
        ep = int(too_long[0])
        raise ValueError(
            f"{path}: episode {ep} has {int(lengths[ep])} steps, more than "
            f"max_episode_steps={max_episode_steps}; pass the time limit the file was "
            f"recorded with."
        )
    step = np.arange(n) - np.repeat(start_idx, lengths)
    last = end_idx - 1

    time_col = 1.0 - step / max_episode_steps
    time_err = np.abs(obs[:, -1].astype(np.float64) - time_col)
    has_time_feature = bool(time_err.max() <= _TIME_FEATURE_ATOL)
    if time_feature is None:
        time_feature = has_time_feature
    elif time_feature and not has_time_feature:
        row = int(time_err.argmax())
        raise ValueError(
            f"{path}: the last observation column is not the time feature 1 - t/T with "
            f"T={max_episode_steps} (row {row}: {float(obs[row, -1]):.6g} vs "
            f"{time_col[row]:.6g}); check max_episode_steps or pass time_feature=False."
        )

    dense_sums = np.add.reduceat(rewards.astype(np.float64), start_idx)
    if "episode_returns" in arrays:
        returns = np.asarray(arrays["episode_returns"], dtype=np.float64).reshape(-1)
        if returns.shape[0] != start_idx.size:
            raise ValueError(
                f"{path}: 'episode_returns' has {returns.shape[0]} entries but "
                f"'episode_starts' marks {start_idx.size} episodes."
            )
        # The recorder summed float64 rewards before they were stored as float32.
        abs_sums = np.add.reduceat(np.abs(rewards.astype(np.float64)), start_idx)
        tol = 1e-3 + 1e-5 * abs_sums
        bad = np.flatnonzero(np.abs(returns - dense_sums) > tol)
        if bad.size:
            ep = int(bad[0])
            raise ValueError(
                f"{path}: episode {ep} (rows {int(start_idx[ep])}..{int(last[ep])}) has "
                f"recorded return {returns[ep]:.6f} but its rewards sum to "
                f"{dense_sums[ep]:.6f}; the file's 'rewards' and 'episode_returns' "
                f"disagree (corrupt or mis-assembled file)."
            )
    else:
        returns = dense_sums

    actions = actions.astype(np.float32)
    overshoot = float(np.abs(actions).max()) - 1.0
    if overshoot > _ACTION_ROUNDING:
        raise ValueError(
            f"{path}: actions reach {1.0 + overshoot:.6g} in absolute value, outside "
            f"[-1, 1]; rescale them to the normalised action space first."
        )
    actions = np.clip(actions, -1.0, 1.0)

    obs_t = torch.as_tensor(obs, dtype=torch.float32)
    next_obs = torch.empty_like(obs_t)
    next_obs[:-1] = obs_t[1:]
    last_t = torch.as_tensor(last)
    # Approximate final next states (see docstring): read by a TD target only for
    # truncated episodes, and only when the loss does not treat done as terminal.
    next_obs[last_t] = obs_t[last_t]
    if time_feature:
        next_obs[last_t, -1] = torch.as_tensor(
            1.0 - lengths / max_episode_steps, dtype=torch.float32
        )
    done = torch.zeros(n, 1, dtype=torch.bool)
    done[last_t] = True
    truncated = torch.zeros(n, 1, dtype=torch.bool)
    truncated[last_t] = torch.as_tensor(lengths >= max_episode_steps).unsqueeze(-1)
    terminated = done & ~truncated

    data = TensorDict(
        {
            "observation": obs_t,
            "action": torch.as_tensor(actions),
            "step_count": torch.as_tensor(step, dtype=torch.int64).unsqueeze(-1),
            "next": {
                "observation": next_obs,
                "reward": torch.as_tensor(rewards, dtype=torch.float32).unsqueeze(-1),
                "done": done,
                "terminated": terminated,
                "truncated": truncated,
            },
        },
        batch_size=[n],
    )

    metadata: dict[str, Any] = {
        "format": SB_FORMAT_TAG,
        "source": str(path),
        "n_episodes": int(start_idx.size),
        "n_transitions": int(n),
        "episode_returns": [float(r) for r in returns],
        "episode_lengths": [int(x) for x in lengths],
        "observation_dim": int(obs.shape[1]),
        "action_dim": int(actions.shape[1]),
        "max_episode_steps": int(max_episode_steps),
        "time_feature": bool(time_feature),
        "file_keys": sorted(arrays),
        "next_observation": (
            "obs[t+1] within episodes; last step of an episode: copy of the last "
            "observation (time feature advanced), an approximation. Never bootstrapped "
            "from after a termination; after a truncation (terminated=False, "
            "truncated=True) SAILLoss/TD3Loss bootstrap from it by default, and never "
            "with loss.set_keys(terminated='done') (the authors' convention)"
        ),
    }
    match = _SB_NAME.search(path.stem)
    if match:
        metadata.update(
            env_name=match["env"],
            nominal_score=float(match["score"]),
            recorder=(
                "illidanlab/SAIL teacher_dataset: stable-baselines ExpertDataset recorded "
                "through TimeLimit + TimeFeatureWrapper + auto-resetting VecEnv"
            ),
        )
    return Demonstrations(data, metadata)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    if not path.exists():
        raise FileNotFoundError(f"demonstration file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise ValueError(
            f"{path}: not a zip/npz archive (corrupt or truncated file?); expected a "
            f"stable-baselines ExpertDataset .npz."
        )
    try:
        with np.load(path, allow_pickle=True) as npz:
            return {key: npz[key] for key in npz.files}
    except Exception as err:  # zipfile/zlib/pickle/EOF/format errors of a damaged archive
        raise ValueError(
            f"{path}: cannot read the .npz (corrupt or truncated file?): {err}"
        ) from err


def _episode_starts(path: Path, raw: np.ndarray, n: int) -> np.ndarray:
    """``episode_starts`` as a bool vector; copes with the object-array layout."""
    raw = np.asarray(raw)
    if raw.shape[:1] != (n,):
        raise ValueError(
            f"{path}: 'episode_starts' has shape {raw.shape}, expected ({n},) like 'obs'."
        )
    if raw.dtype == object:
        # element 0 is a Python bool, the others 1-element arrays; float(x) fails on
        # numpy >= 2 for those, so take the single element explicitly.
        try:
            starts = np.array([bool(np.asarray(x).ravel()[0]) for x in raw], dtype=bool)
        except (IndexError, TypeError, ValueError) as err:
            raise ValueError(
                f"{path}: 'episode_starts' entries must be booleans: {err}"
            ) from err
    else:
        starts = raw.reshape(n, -1)[:, 0].astype(bool)
    if not starts[0]:
        raise ValueError(
            f"{path}: 'episode_starts'[0] is False; the first row must start an episode."
        )
    return starts


# --------------------------------------------------------------------------------------
# The project's own format (.pt)
# --------------------------------------------------------------------------------------
def save_demonstrations(
    path: str | os.PathLike,
    demos_or_data: Demonstrations | TensorDictBase,
    metadata: Mapping[str, Any] | None = None,
) -> Path:
    """Saves demonstrations to one ``.pt`` file, atomically.

    The file is ``torch.save`` of a plain dict ``{"format": "torchrl_sail.demonstrations",
    "version": 1, "metadata": {...}, "data": data.to_dict()}``: tensors, strings and
    numbers only, so it loads with ``torch.load(weights_only=True)`` (no pickled classes).
    It is written to a temporary file in the same directory, fsynced and moved into place
    with ``os.replace``: a crash never leaves a half-written file where a good one was.

    ``episode_returns`` and ``episode_lengths`` are recomputed from ``("next", "reward")``
    and ``("next", "done")`` when the metadata lacks them (the returns are then the sums
    of whatever reward the data holds, dense for the loaders' output). ``source`` and
    ``format`` default to this file and this format; an existing ``source`` (e.g. the
    ``.npz`` the data came from) is kept as provenance. The metadata is stored verbatim
    otherwise, so ``load_demonstrations`` gives back exactly what was saved.

    Args:
        path: destination, conventionally with a ``.pt`` suffix (``.npz`` is refused
            because that suffix means the stable-baselines format).
        demos_or_data: a :class:`Demonstrations` or a flat ``[N]`` transition tensordict.
        metadata: metadata to store; overrides (updates) the metadata of a
            :class:`Demonstrations`. Must be JSON-able (numpy/torch scalars are converted).

    Returns:
        Path: the written file.

    Examples:
        >>> import os, tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import load_demonstrations, save_demonstrations
        >>> done = torch.tensor([[False], [True], [False], [True]])
        >>> td = TensorDict(
        ...     {
        ...         "observation": torch.arange(8.0).view(4, 2),
        ...         "action": torch.zeros(4, 1),
        ...         "next": {
        ...             "observation": torch.arange(2.0, 10.0).view(4, 2),
        ...             "reward": torch.tensor([[1.0], [2.0], [3.0], [4.0]]),
        ...             "done": done,
        ...             "terminated": done.clone(),
        ...             "truncated": torch.zeros(4, 1, dtype=torch.bool),
        ...         },
        ...     },
        ...     batch_size=[4],
        ... )
        >>> path = save_demonstrations(os.path.join(tempfile.mkdtemp(), "d.pt"), td)
        >>> data, meta = load_demonstrations(path)
        >>> meta["episode_returns"], meta["episode_lengths"]
        ([3.0, 7.0], [2, 2])
        >>> bool((data == td).all())
        True
    """
    path = Path(path)
    if path.suffix == ".npz":
        raise ValueError(
            f"{path}: '.npz' is the stable-baselines format; save the project's format "
            f"under a '.pt' name."
        )
    if isinstance(demos_or_data, Demonstrations):
        data, base_meta = demos_or_data
        meta = dict(base_meta)
    elif isinstance(demos_or_data, TensorDictBase):
        data, meta = demos_or_data, {}
    else:
        raise TypeError(
            f"save_demonstrations expects a Demonstrations or a TensorDict, got "
            f"{type(demos_or_data).__name__}."
        )
    if metadata is not None:
        meta.update(metadata)
    _validate_transitions(data, where=f"data to save to {path}")
    if "episode_returns" not in meta or "episode_lengths" not in meta:
        returns, lengths = _episode_stats(data)
        meta.setdefault("episode_returns", returns)
        meta.setdefault("episode_lengths", lengths)
    meta.setdefault("source", str(path))
    meta.setdefault("format", FORMAT_TAG)
    meta = _jsonable(meta, path)

    payload = {
        "format": FORMAT_TAG,
        "version": FORMAT_VERSION,
        "metadata": meta,
        "data": data.detach().cpu().to_dict(),
    }
    atomic_save(payload, path)
    return path


def _jsonable(meta: Mapping[str, Any], path: Path) -> dict[str, Any]:
    def convert(obj: Any) -> Any:
        if isinstance(obj, (np.ndarray, np.generic, torch.Tensor)):
            return obj.tolist()
        if isinstance(obj, Path):
            return str(obj)
        if isinstance(obj, (tuple, set)):
            return list(obj)
        raise TypeError(
            f"metadata for {path} must be JSON-able; got a {type(obj).__name__}: {obj!r}"
        )

    return json.loads(json.dumps(dict(meta), default=convert))


def load_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
) -> Demonstrations:
    """Loads demonstrations from a stable-baselines ``.npz`` or the project's ``.pt``.

    The format is recognised from the content (a ``.npz`` archive or a ``torch.save``
    archive), falling back to the suffix. ``.npz`` files go through
    :func:`load_sb_demonstrations`. Project files are loaded with
    ``torch.load(weights_only=True)`` and validated: the ``format``/``version`` tags, the
    required transition keys (``"observation"``, ``"action"``, and ``("next", ...)``
    ``observation``/``reward``/``done``/``terminated``/``truncated``) with one common batch
    size ``N``, at least one ``done`` and ``done`` on the last row (the data must end on a
    complete episode).

    Args:
        path: the file to read.

    Keyword Args:
        max_episode_steps (int): passed to :func:`load_sb_demonstrations` for ``.npz``
            files; unused for the project's format. Defaults to ``1000``.

    Returns:
        Demonstrations: ``(data, metadata)`` exactly as saved for the project's format.

    Raises:
        FileNotFoundError: the file does not exist (the message names it).
        ValueError: corrupt, truncated or foreign file, or invalid content; the message
            names the file and the problem.

    Examples:
        >>> import os, tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import load_demonstrations
        >>> path = os.path.join(tempfile.mkdtemp(), "bad.pt")
        >>> torch.save({"format": "something.else", "version": 1}, path)
        >>> try:
        ...     load_demonstrations(path)
        ... except ValueError as err:
        ...     print("format tag" in str(err))
        True
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"demonstration file not found: {path}")
    kind = _sniff(path)
    if kind == "npz":
        return load_sb_demonstrations(path, max_episode_steps=max_episode_steps)
    if kind == "torch":
        return _load_project_file(path)
    raise ValueError(
        f"{path}: not a zip/npz or torch.save archive (corrupt or truncated file?); "
        f"expected a stable-baselines .npz or a file written by save_demonstrations."
    )


def _sniff(path: Path) -> str | None:
    if not zipfile.is_zipfile(path):
        return None
    try:
        with zipfile.ZipFile(path) as zf:
            names = zf.namelist()
    except (zipfile.BadZipFile, OSError):
        return None
    if any(name.endswith(".npy") for name in names):
        return "npz"
    if any(name.endswith("data.pkl") for name in names):
        return "torch"
    return {".npz": "npz", ".pt": "torch", ".pth": "torch"}.get(path.suffix)


def _load_project_file(path: Path) -> Demonstrations:
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises RuntimeError/UnpicklingError/EOFError/...
        raise ValueError(
            f"{path}: cannot be read with torch.load(weights_only=True) (corrupt, "
            f"truncated, or containing pickled objects?): {err}"
        ) from err
    if not isinstance(payload, dict):
        raise ValueError(
            f"{path}: expected a dict written by save_demonstrations, got "
            f"{type(payload).__name__}."
        )
    tag = payload.get("format")
    if tag != FORMAT_TAG:
        raise ValueError(
            f"{path}: wrong or missing format tag {tag!r} (expected {FORMAT_TAG!r}); not a "
            f"file written by save_demonstrations."
        )
    version = payload.get("version")
    if not isinstance(version, int) or version < 1:
        raise ValueError(f"{path}: missing or invalid 'version' {version!r}.")
    if version > FORMAT_VERSION:
        raise ValueError(
            f"{path}: format version {version} is newer than this torchrl_sail supports "
            f"({FORMAT_VERSION}); upgrade torchrl_sail."
        )
    for key in ("metadata", "data"):
        if not isinstance(payload.get(key), dict):
            raise ValueError(f"{path}: missing key {key!r} (or it is not a dict).")
    raw = payload["data"]
    n = _check_tensor_tree(raw, path)
    data = TensorDict(raw, batch_size=[n])
    _validate_transitions(data, where=str(path))
    metadata = payload["metadata"]
    lengths = metadata.get("episode_lengths")
    n_done = int(data["next", "done"].sum())
    if isinstance(lengths, list) and (len(lengths) != n_done or sum(lengths) != n):
        raise ValueError(
            f"{path}: metadata 'episode_lengths' ({len(lengths)} episodes, {sum(lengths)} "
            f"steps) disagrees with the data ({n_done} done flags, {n} rows)."
        )
    return Demonstrations(data, metadata)


def _check_tensor_tree(tree: Mapping, path: Path) -> int:
    """Checks that every leaf is a tensor with one common leading size; returns it."""
    sizes: dict[tuple, int] = {}

    def walk(node: Mapping, prefix: tuple) -> None:
        for key, value in node.items():
            full = prefix + (key,)
            if isinstance(value, Mapping):
                walk(value, full)
            elif isinstance(value, torch.Tensor) and value.ndim >= 1:
                sizes[full] = value.shape[0]
            else:
                raise ValueError(
                    f"{path}: data entry {full} is not a tensor with a batch dimension "
                    f"(got {type(value).__name__})."
                )

    walk(tree, ())
    if not sizes:
        raise ValueError(f"{path}: 'data' holds no tensors.")
    if len(set(sizes.values())) > 1:
        raise ValueError(
            f"{path}: inconsistent batch sizes in 'data': "
            + ", ".join(f"{k}: {v}" for k, v in sizes.items())
        )
    return next(iter(sizes.values()))


def _validate_transitions(data: TensorDictBase, *, where: str) -> None:
    """Checks the contract's transition layout on a flat ``[N]`` tensordict."""
    if data.batch_dims != 1:
        raise ValueError(
            f"{where}: demonstrations must be a flat [N] tensordict, got batch size "
            f"{tuple(data.batch_size)}; flatten it with data.reshape(-1)."
        )
    n = data.batch_size[0]
    if n == 0:
        raise ValueError(f"{where}: no transitions.")
    keys = data.keys(include_nested=True, leaves_only=True)
    for key in _REQUIRED_KEYS:
        if key not in keys:
            raise ValueError(
                f"{where}: missing key {key!r}; required keys are {list(_REQUIRED_KEYS)}."
            )
    for key in _REQUIRED_KEYS[3:]:
        shape = tuple(data.get(key).shape)
        if shape != (n, 1):
            raise ValueError(f"{where}: {key!r} must have shape ({n}, 1), got {shape}.")
    if data["observation"].shape != data["next", "observation"].shape:
        raise ValueError(
            f"{where}: 'observation' {tuple(data['observation'].shape)} and "
            f"('next', 'observation') {tuple(data['next', 'observation'].shape)} differ."
        )
    done = data["next", "done"]
    for key in (("next", "done"), ("next", "terminated"), ("next", "truncated")):
        if data.get(key).dtype != torch.bool:
            raise ValueError(f"{where}: {key!r} must be bool, got {data.get(key).dtype}.")
    if not torch.equal(done, data["next", "terminated"] | data["next", "truncated"]):
        raise ValueError(f"{where}: ('next', 'done') != terminated | truncated.")
    if not done.any():
        raise ValueError(f"{where}: no ('next', 'done') flag: no complete episode.")
    if not done[-1].item():
        raise ValueError(
            f"{where}: the last row is not done; demonstrations must end on a complete "
            f"episode."
        )


def _episode_stats(data: TensorDictBase) -> tuple[list[float], list[int]]:
    """Per-episode reward sums and lengths, episodes ending at done rows."""
    done = data["next", "done"].reshape(-1)
    ends = torch.nonzero(done).reshape(-1) + 1
    lengths = torch.diff(ends, prepend=ends.new_zeros(1))
    reward = data["next", "reward"].reshape(-1).double()
    segments = torch.split(reward[: int(ends[-1])], lengths.tolist())
    returns = [float(seg.sum()) for seg in segments]
    return returns, [int(x) for x in lengths]


# --------------------------------------------------------------------------------------
# Dimension check
# --------------------------------------------------------------------------------------
def check_demonstration_dims(
    data: Demonstrations | TensorDictBase,
    *,
    observation_dim: int | None = None,
    action_dim: int | None = None,
    env: Any = None,
    observation_key: NestedKey = "observation",
    action_key: NestedKey = "action",
    source: str | os.PathLike | None = None,
) -> None:
    """Checks that demonstrations fit the env's observation and action sizes.

    The paper's teacher files have one more observation column than the plain MuJoCo env
    (the remaining-time feature), so the commonest mistake is a missing or extra
    :class:`~torchrl_sail.TimeFeature`; the error says so.

    Args:
        data: a :class:`Demonstrations` or a transition tensordict.

    Keyword Args:
        observation_dim (int, optional): the env's observation size (last dim).
        action_dim (int, optional): the env's action size.
        env (EnvBase, optional): instead of the sizes, a TorchRL env: the sizes are read
            from ``env.observation_spec[observation_key]`` and ``env.action_spec``.
            Explicit sizes take precedence.
        observation_key (NestedKey): observation entry in ``data`` (and in the env's
            observation spec). Defaults to ``"observation"``.
        action_key (NestedKey): action entry in ``data``. Defaults to ``"action"``.
        source (str or path, optional): named in error messages; defaults to
            ``metadata["source"]`` of a :class:`Demonstrations`.

    Raises:
        ValueError: a size differs; the message says which, by how much, and the likely fix.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import check_demonstration_dims
        >>> td = TensorDict({"observation": torch.zeros(5, 12), "action": torch.zeros(5, 3)}, [5])
        >>> check_demonstration_dims(td, observation_dim=12, action_dim=3)  # fine
        >>> try:
        ...     check_demonstration_dims(td, observation_dim=11, action_dim=3)
        ... except ValueError as err:
        ...     print("enable TimeFeature" in str(err))
        True
    """
    if isinstance(data, Demonstrations):
        if source is None:
            source = data.metadata.get("source")
        data = data.data
    if env is not None:
        if observation_dim is None:
            observation_dim = int(env.observation_spec[observation_key].shape[-1])
        if action_dim is None:
            action_dim = int(env.action_spec.shape[-1])
    if observation_dim is None and action_dim is None:
        raise TypeError(
            "check_demonstration_dims needs observation_dim/action_dim or env=."
        )
    name = f"teacher data ({source})" if source is not None else "teacher data"
    if observation_dim is not None:
        teacher = int(data.get(observation_key).shape[-1])
        if teacher != observation_dim:
            if teacher == observation_dim + 1:
                hint = (
                    "enable TimeFeature (the paper's teacher files append the "
                    "remaining-time feature 1 - t/T as the last column)"
                )
            elif teacher + 1 == observation_dim:
                hint = (
                    "disable TimeFeature (the env appends the remaining-time feature "
                    "but these demonstrations do not have it)"
                )
            else:
                hint = "the demonstrations were probably recorded on a different env"
            raise ValueError(
                f"{name}: {observation_key!r} has {teacher} dims, env has "
                f"{observation_dim}: {hint}."
            )
    if action_dim is not None:
        teacher = int(data.get(action_key).shape[-1])
        if teacher != action_dim:
            raise ValueError(
                f"{name}: {action_key!r} has {teacher} dims, env action has {action_dim}: "
                f"the demonstrations were recorded on a different env or action space."
            )
