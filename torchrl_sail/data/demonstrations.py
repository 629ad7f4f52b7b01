"""Teacher demonstrations: the paper's ``.npz`` files and the project's own directory format.

Both loaders (and :mod:`torchrl_sail.data.minari`'s, for Minari datasets) return a flat
transition tensordict that follows the README's data conventions (``"observation"``,
``"action"``, ``("next", ...)`` entries with ``done = terminated | truncated``). Rewards stay
*dense*: SAIL's delayed, trajectory-wise reward is produced after loading by
:class:`~torchrl_sail.DelayedRewardTransform` (offline mode).
"""
from __future__ import annotations

import json
import os
import re
import shutil
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.utils import NestedKey

from torchrl_sail.data.keys import TRANSITION_KEYS

__all__ = [
    "Demonstrations",
    "check_demonstration_dims",
    "load_demonstrations",
    "load_sb_demonstrations",
    "save_demonstrations",
]

# Our metadata file; tensordict writes its own ``meta.json`` beside it.
METADATA_FILE = "metadata.json"
_SB_KEYS = ("obs", "actions", "rewards", "episode_starts")
# SAIL's teacher files are named expert_data_no_img_<Env>_scores_<score>_episodes_<n>.npz
_SB_NAME = re.compile(
    r"expert_data_(?:no_img_)?(?P<env>[A-Za-z0-9]+)_scores_(?P<score>-?[0-9.]+)_episodes_[0-9]+$"
)
# float32 rounding in the recorder: actions may exceed +-1 by ~1e-7
_ACTION_ROUNDING = 1e-5
# The time column of the paper's files matches 1 - t/T to ~3e-8.
_TIME_FEATURE_ATOL = 1e-5
_FLAGS = (("next", "done"), ("next", "terminated"), ("next", "truncated"))


class Demonstrations(NamedTuple):
    """Teacher demonstrations: flat ``[N]`` transitions plus JSON-able metadata.

    The episodes are concatenated in file order, each ending at a row where
    ``("next", "done")`` is ``True``. ``metadata`` always has ``episode_returns`` (dense,
    undiscounted), ``episode_lengths`` and ``source`` (the file the data was first read
    from), plus whatever the file or its recorder provides.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail.data.demonstrations import Demonstrations
        >>> data, metadata = Demonstrations(TensorDict(batch_size=[2]), {"episode_returns": [2.0]})
        >>> data.batch_size, metadata["episode_returns"]
        (torch.Size([2]), [2.0])
    """

    data: TensorDictBase
    metadata: dict[str, Any]


def load_sb_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a stable-baselines ``ExpertDataset`` ``.npz`` file (the SAIL teacher files).

    ``episode_starts`` is an object array, so the file is read with ``allow_pickle=True``:
    only load files you trust. The result:

    - ``"observation"``: the file's ``obs`` as float32, *including* its last column, the
      remaining-time feature ``1 - t/max_episode_steps`` (an env producing matching
      observations needs :class:`~torchrl_sail.TimeFeature`).
    - ``"action"``: float32, float32 rounding overshoots of ``[-1, 1]`` clamped.
    - ``"step_count"`` ``[N, 1]`` int64: the in-episode index ``t``.
    - ``("next", "reward")`` ``[N, 1]`` float32: the recorded dense rewards.
    - ``("next", "observation")``: ``obs[t + 1]`` of the same episode. The file's
      ``next_obs`` is never used: its last entry per episode is the next episode's reset
      observation (the recorder auto-reset), and the HalfCheetah files do not have it.
    - ``("next", "done")`` on the last step of each episode, with ``"terminated"`` if the
      episode is shorter than ``max_episode_steps`` (the Hopper teacher fell) and
      ``"truncated"`` if it reached it.

    The true final next state of an episode was not recorded: it is approximated by the
    last observation with the time column advanced to ``1 - (t + 1)/max_episode_steps``.
    A TD target never reads it after a termination; after a truncation,
    :class:`~torchrl_sail.SAILLoss` and ``TD3Loss`` bootstrap from it unless
    ``loss.set_keys(terminated="done")`` (the authors' convention, used by the example).

    Args:
        path: the ``.npz`` file.

    Keyword Args:
        max_episode_steps (int): the episode time limit ``T`` of the recording.
            Defaults to ``1000`` (the MuJoCo tasks).
        time_feature (bool, optional): whether the last observation column is the
            remaining-time feature. ``None`` (default) detects it by comparing the column
            with ``1 - t/T``; ``True`` raises if it does not match; ``False`` never
            touches the column.

    Returns:
        Demonstrations: ``(data, metadata)``, with the file's ``episode_returns``.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: unreadable file, missing key, inconsistent shapes, an episode longer
            than ``max_episode_steps``, or ``episode_returns`` that are not the sums of
            ``rewards``.

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
        >>> data["step_count"].squeeze(-1).tolist()
        [0, 1, 2, 0, 1]
        >>> data["next", "terminated"].squeeze(-1).tolist()  # done, shorter than T: terminated
        [False, False, True, False, True]
        >>> round(data["next", "observation"][2, -1].item(), 3)  # 1 - 3/1000
        0.997
    """
    path = Path(path)
    if max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}.")
    if not path.is_file():
        raise FileNotFoundError(f"demonstration file not found: {path}")
    try:
        # NpzFile, not np.load: np.load(allow_pickle=True) would unpickle a non-zip file.
        with np.lib.npyio.NpzFile(path, allow_pickle=True) as npz:
            arrays = {key: npz[key] for key in npz.files}
    except Exception as err:  # zipfile/zlib/pickle/EOF errors of a foreign or damaged file
        raise ValueError(f"{path}: not a readable .npz archive: {err}") from err
    missing = [key for key in _SB_KEYS if key not in arrays]
    if missing:
        raise ValueError(f"{path}: missing key {missing[0]!r}; found {sorted(arrays)}.")

    obs, raw_starts = arrays["obs"], arrays["episode_starts"]
    actions = arrays["actions"].reshape(len(arrays["actions"]), -1).astype(np.float32)
    rewards = arrays["rewards"].astype(np.float64)
    rewards = rewards[:, 0] if rewards.ndim == 2 and rewards.shape[1] == 1 else rewards
    n = len(obs)
    if obs.ndim != 2 or rewards.shape != (n,) or not len(actions) == len(raw_starts) == n > 0:
        raise ValueError(
            f"{path}: shapes obs {obs.shape}, actions {arrays['actions'].shape}, rewards "
            f"{arrays['rewards'].shape}, episode_starts {raw_starts.shape} are not (N, obs_dim), "
            f"(N, action_dim), (N,) or (N, 1), (N,) with N > 0."
        )
    # Element 0 of the object array is a Python bool, the others 1-element arrays.
    starts = np.array([np.asarray(x).ravel()[0] for x in raw_starts], dtype=bool)
    if not starts[0]:
        raise ValueError(f"{path}: 'episode_starts'[0] is False; row 0 must start an episode.")
    start_idx = np.flatnonzero(starts)
    lengths = np.diff(np.append(start_idx, n))
    if lengths.max() > max_episode_steps:
        raise ValueError(
            f"{path}: episode {lengths.argmax()} has {lengths.max()} steps, more than "
            f"max_episode_steps={max_episode_steps} (the time limit of the recording)."
        )
    step = np.arange(n) - np.repeat(start_idx, lengths)
    last = start_idx + lengths - 1

    time_err = np.abs(obs[:, -1].astype(np.float64) - (1.0 - step / max_episode_steps))
    if time_feature is None:
        time_feature = bool(time_err.max() <= _TIME_FEATURE_ATOL)
    elif time_feature and time_err.max() > _TIME_FEATURE_ATOL:
        raise ValueError(
            f"{path}: the last observation column is not the time feature 1 - t/T with "
            f"T={max_episode_steps} (off by {time_err.max():.3g} at row {time_err.argmax()}); "
            f"check max_episode_steps or pass time_feature=False."
        )

    returns = np.add.reduceat(rewards, start_idx)
    if "episode_returns" in arrays:
        recorded = arrays["episode_returns"].astype(np.float64).reshape(-1)
        if recorded.shape != returns.shape:
            raise ValueError(
                f"{path}: 'episode_returns' has {recorded.size} entries but "
                f"'episode_starts' marks {returns.size} episodes."
            )
        # The recorder summed float64 rewards before they were stored as float32.
        bad = np.abs(recorded - returns) > 1e-3 + 1e-5 * np.add.reduceat(np.abs(rewards), start_idx)
        if bad.any():
            ep = bad.argmax()
            raise ValueError(
                f"{path}: episode {ep} has recorded return {recorded[ep]:.6f} but its rewards "
                f"sum to {returns[ep]:.6f} (corrupt or mis-assembled file)."
            )
        returns = recorded
    if np.abs(actions).max() > 1.0 + _ACTION_ROUNDING:
        raise ValueError(
            f"{path}: actions reach {np.abs(actions).max():.6g} in absolute value, outside "
            f"[-1, 1]; rescale them to the normalised action space first."
        )

    obs_t = torch.as_tensor(obs, dtype=torch.float32)
    next_obs = torch.cat([obs_t[1:], obs_t[-1:]])
    next_obs[last] = obs_t[last]  # the approximated final next states (see above)
    if time_feature:
        next_obs[last, -1] = torch.as_tensor(1.0 - lengths / max_episode_steps).float()
    done = torch.zeros(n, 1, dtype=torch.bool)
    done[last] = True
    truncated = done & torch.as_tensor(np.repeat(lengths >= max_episode_steps, lengths))[:, None]
    data = TensorDict(
        {
            "observation": obs_t,
            "action": torch.as_tensor(np.clip(actions, -1.0, 1.0)),
            "step_count": torch.as_tensor(step, dtype=torch.int64).unsqueeze(-1),
            ("next", "observation"): next_obs,
            ("next", "reward"): torch.as_tensor(rewards, dtype=torch.float32).unsqueeze(-1),
            ("next", "done"): done,
            ("next", "terminated"): done & ~truncated,
            ("next", "truncated"): truncated,
        },
        batch_size=[n],
    )
    metadata = dict(
        format="stable_baselines.ExpertDataset", source=str(path), file_keys=sorted(arrays),
        n_episodes=len(lengths), n_transitions=n, episode_returns=returns.tolist(),
        episode_lengths=lengths.tolist(), observation_dim=obs.shape[1],
        action_dim=actions.shape[1], max_episode_steps=int(max_episode_steps),
        time_feature=time_feature,
    )
    if match := _SB_NAME.search(path.stem):
        metadata.update(env_name=match["env"], nominal_score=float(match["score"]))
    return Demonstrations(data, metadata)


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
            (:func:`load_demonstrations` reads it as the stable-baselines format).
        demos_or_data: a :class:`Demonstrations` or a flat ``[N]`` transition tensordict.
        metadata: JSON-able metadata (numpy/torch values are converted); updates the
            metadata of a :class:`Demonstrations`.

    Returns:
        Path: the written directory.

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
    _check_transitions(data, f"data to save to {path}")
    if "episode_returns" not in meta or "episode_lengths" not in meta:
        ends = torch.nonzero(data["next", "done"].reshape(-1)).reshape(-1) + 1
        lengths = torch.diff(ends, prepend=ends.new_zeros(1)).tolist()
        episodes = data["next", "reward"].reshape(-1).double().split(lengths)
        meta.setdefault("episode_returns", [float(rewards.sum()) for rewards in episodes])
        meta.setdefault("episode_lengths", lengths)
    meta.setdefault("source", str(path))

    text = json.dumps(meta, indent=2, default=_json_default(f"metadata for {path}"))

    def write(staging: Path) -> None:
        data.detach().cpu().memmap(staging, copy_existing=True)
        (staging / METADATA_FILE).write_text(text)

    _publish(path, write)
    return path


def _json_default(what: str) -> Callable[[Any], Any]:
    """``json.dumps(default=...)`` for metadata: arrays and tensors as lists, paths as strings, sets sorted."""

    def default(obj: Any) -> Any:
        if isinstance(obj, (np.ndarray, np.generic, torch.Tensor)):
            return obj.tolist()
        if isinstance(obj, os.PathLike):
            return os.fspath(obj)
        if isinstance(obj, set):
            return sorted(obj)
        raise TypeError(f"{what} must be JSON-able; got {obj!r}.")

    return default


def _publish(path: Path, write: Callable[[Path], None]) -> None:
    """Builds a directory with ``write(staging)`` and swaps it in for ``path``.

    Staging and backup sit beside ``path``, on its filesystem, so ``os.replace`` is a
    rename. An existing ``path`` is moved aside first (a non-empty directory cannot be
    replaced in one rename) and comes back if the swap fails.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    tag = uuid.uuid4().hex[:8]
    staging = path.with_name(f".{path.name}.{tag}.staging")
    backup = path.with_name(f".{path.name}.{tag}.backup")
    try:
        write(staging)
        if path.exists():
            os.replace(path, backup)
        try:
            os.replace(staging, path)
        except BaseException:
            if backup.exists():
                os.replace(backup, path)
            raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    shutil.rmtree(backup, ignore_errors=True)


def load_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a stable-baselines ``.npz``, a :func:`save_demonstrations` directory, a Minari dataset.

    A ``.npz`` file goes to :func:`load_sb_demonstrations`; ``"minari:<dataset id>"`` or a
    Minari dataset folder to :func:`~torchrl_sail.load_minari_demonstrations` (it needs the
    optional ``minari`` package: ``pip install -e '.[minari]'``). A directory is read with
    :meth:`~tensordict.TensorDict.load_memmap` (pickled objects refused) into an ordinary
    in-memory tensordict, with its ``metadata.json``, and checked: flat ``[N]``, the
    ``TRANSITION_KEYS`` of :mod:`torchrl_sail.data.keys`, bool ``[N, 1]`` flags with
    ``done == terminated | truncated``, and a done last row (complete episodes only).

    Args:
        path: a ``.npz`` file, a directory written by :func:`save_demonstrations`, or a
            Minari dataset: ``"minari:<dataset id>"`` (looked up under
            ``MINARI_DATASETS_PATH``, default ``~/.minari/datasets``) or its folder.

    Keyword Args:
        max_episode_steps (int): passed to :func:`load_sb_demonstrations` and
            :func:`~torchrl_sail.load_minari_demonstrations`; unused for directories.
            Defaults to ``1000``.
        time_feature (bool, optional): passed to the same two loaders (``None`` detects the
            column, ``True`` requires it of a ``.npz`` file and appends it to a Minari dataset
            recorded without it); unused for directories. Defaults to ``None``.

    Returns:
        Demonstrations: ``(data, metadata)``.

    Raises:
        FileNotFoundError: ``path`` does not exist (or no such local Minari dataset).
        ImportError: a Minari dataset, but ``minari`` is not installed.
        ValueError: ``path`` is none of these forms, or its content is invalid; the message
            names the file and the problem.

    Examples:
        >>> import os, tempfile
        >>> from torchrl_sail import load_demonstrations
        >>> path = os.path.join(tempfile.mkdtemp(), "demos.pt")
        >>> _ = open(path, "wb").write(b"not demonstrations")
        >>> try:
        ...     load_demonstrations(path)
        ... except ValueError as err:
        ...     print("a directory written by save_demonstrations" in str(err))
        True
    """
    # (the module imports minari lazily: it stays an optional dependency)
    from torchrl_sail.data.minari import is_minari_dataset, load_minari_demonstrations, MINARI_PREFIX

    by_id = os.fspath(path).startswith(MINARI_PREFIX)  # also from a Path("minari:<id>")
    if by_id or is_minari_dataset(path):
        return load_minari_demonstrations(
            os.fspath(path) if by_id else path, max_episode_steps=max_episode_steps,
            time_feature=time_feature,
        )
    path = Path(path)
    if path.suffix == ".npz" and path.is_file():
        return load_sb_demonstrations(
            path, max_episode_steps=max_episode_steps, time_feature=time_feature
        )
    if not (path / METADATA_FILE).is_file():
        raise (ValueError if path.exists() else FileNotFoundError)(
            f"{path}: not demonstrations; expected a stable-baselines ExpertDataset '.npz' "
            f"file, a directory written by save_demonstrations (with {METADATA_FILE}), or a "
            f"Minari dataset ('minari:<dataset id>' or its folder)."
        )
    data = TensorDict.load_memmap(path, allow_pickle=False).to_tensordict()
    _check_transitions(data, str(path))
    return Demonstrations(data, json.loads((path / METADATA_FILE).read_text()))


def _check_transitions(data: TensorDictBase, where: str) -> None:
    """Checks the README's transition layout; the error names ``where`` and the entry."""
    n = data.batch_size[0] if data.batch_dims == 1 else 0
    keys = set(data.keys(include_nested=True, leaves_only=True))
    missing = [key for key in TRANSITION_KEYS if key not in keys]
    bad = [k for k in _FLAGS if k in keys and data[k].dtype != torch.bool] + [
        k for k in (*_FLAGS, ("next", "reward")) if k in keys and data[k].shape != (n, 1)
    ]
    if n == 0:
        problem = f"expected a flat, non-empty [N] tensordict, got batch {list(data.batch_size)}"
    elif missing:
        problem = f"missing key {missing[0]!r}; required keys are {list(TRANSITION_KEYS)}"
    elif bad:
        problem = (
            f"{bad[0]!r} has dtype {data[bad[0]].dtype} and shape {tuple(data[bad[0]].shape)}; "
            f"expected shape ({n}, 1), bool for done/terminated/truncated"
        )
    elif data["observation"].shape != data["next", "observation"].shape:
        problem = (
            f"'observation' {tuple(data['observation'].shape)} and ('next', 'observation') "
            f"{tuple(data['next', 'observation'].shape)} differ"
        )
    elif not torch.equal(data[_FLAGS[0]], data[_FLAGS[1]] | data[_FLAGS[2]]):
        problem = "('next', 'done') != terminated | truncated"
    elif not data["next", "done"][-1].item():
        problem = "the last row is not done; demonstrations must end on a complete episode"
    else:
        return
    raise ValueError(f"{where}: {problem}.")


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
        env (EnvBase, optional): a TorchRL env to read the sizes from
            (``env.observation_spec[observation_key]``, ``env.action_spec``) where they
            are not given.
        observation_key (NestedKey): the observation entry. Defaults to ``"observation"``.
        action_key (NestedKey): the action entry. Defaults to ``"action"``.
        source (str or path, optional): named in errors; defaults to the ``source`` of a
            :class:`Demonstrations`.

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
        data, source = data.data, data.metadata.get("source") if source is None else source
    if env is not None:
        if observation_dim is None:
            observation_dim = int(env.observation_spec[observation_key].shape[-1])
        if action_dim is None:
            action_dim = int(env.action_spec.shape[-1])
    if observation_dim is None and action_dim is None:
        raise TypeError("check_demonstration_dims needs observation_dim/action_dim or env=.")
    name = f"teacher data ({source})" if source is not None else "teacher data"
    teacher_obs = data.get(observation_key).shape[-1] if observation_dim is not None else None
    if teacher_obs != observation_dim:
        if teacher_obs == observation_dim + 1:
            hint = "enable TimeFeature (the paper's teacher files end with the feature 1 - t/T)"
        elif teacher_obs + 1 == observation_dim:
            hint = "disable TimeFeature (the env appends it; these demonstrations do not have it)"
        else:
            hint = "the demonstrations were probably recorded on a different env"
        raise ValueError(
            f"{name}: {observation_key!r} has {teacher_obs} dims, env has {observation_dim}: "
            f"{hint}."
        )
    if action_dim is not None and data.get(action_key).shape[-1] != action_dim:
        raise ValueError(
            f"{name}: {action_key!r} has {data.get(action_key).shape[-1]} dims, env action has "
            f"{action_dim}: the demonstrations were recorded on a different env or action space."
        )
