"""The SAIL authors' teacher files: stable-baselines ``ExpertDataset`` ``.npz`` archives.

See ``load_sb_demonstrations`` for the layout. This module imports only the core,
:mod:`torchrl_sail.data.episodes`, and registers its reader there (any ``.npz`` file).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDictBase

from torchrl_sail.data.episodes import (
    Demonstrations,
    check_action_bounds,
    check_finite,
    check_returns,
    check_transitions,
    episodes_to_transitions,
    register_reader,
    resolve_time_feature,
)
from torchrl_sail.data.paper_teachers import refused_teacher

__all__ = ["load_sb_demonstrations"]

_SB_KEYS = ("obs", "actions", "rewards", "episode_starts")
# SAIL's teacher files are named expert_data_no_img_<Env>_scores_<score>_episodes_<n>.npz
_SB_NAME = re.compile(r"expert_data_(?:no_img_)?(?P<env>[A-Za-z0-9]+)_scores_(?P<score>-?[0-9.]+)_episodes_[0-9]+$")


def load_sb_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a stable-baselines ``ExpertDataset`` ``.npz`` file (the SAIL teacher files).

    ``episode_starts`` is an object array, so the file is read with ``allow_pickle=True``:
    only load files you trust. The result:

    - ``"observation"``: the file's ``obs`` as float32 (the paper's files end with the
      remaining-time feature ``1 - t/max_episode_steps``; see ``time_feature`` for files
      without it).
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

    Time feature: the last ``obs`` column is taken to be the feature when it equals
    ``1 - t/T`` (``T = max_episode_steps``) on every row, to ``1e-5``
    (:func:`~torchrl_sail.data.episodes.resolve_time_feature`, the rule of every format).
    A file recorded without it (``obs`` as wide as the env's observation) gets it computed
    from the episode steps and appended when ``time_feature=True``, exactly as the env's
    :class:`~torchrl_sail.TimeFeature` computes it; a file that has it is left as it is.

    Args:
        path: the ``.npz`` file.

    Keyword Args:
        max_episode_steps (int): the episode time limit ``T`` of the recording.
            Defaults to ``1000`` (the MuJoCo tasks).
        time_feature (bool, optional): ``None`` (default) detects the column and changes
            nothing; ``True`` keeps it if present and appends it if not; ``False`` never
            touches the observations.

    Returns:
        Demonstrations: ``(data, metadata)``, with the file's ``episode_returns``, and
        ``time_feature`` (whether the result has the column) and ``time_feature_appended``.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: unreadable file, missing key, inconsistent shapes, a NaN or infinity
            (naming the key and row), an episode longer than ``max_episode_steps``,
            ``episode_returns`` that are not the sums of ``rewards``, actions outside
            ``[-1, 1]``, a last column that is the time feature of another ``T``, or a published
            SAIL teacher file that no env reproduces (by name, with the reason:
            :data:`~torchrl_sail.data.paper_teachers.REFUSED_TEACHERS`).

    Examples:
        >>> import numpy as np, tempfile, os, torch
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

        A file recorded without the time feature gets it computed:

        >>> np.savez(path, obs=obs[:, :1], actions=np.zeros((5, 1), "float32"),
        ...          rewards=np.ones((5, 1), "float32"), episode_starts=starts)
        >>> data, meta = load_sb_demonstrations(path, time_feature=True)
        >>> meta["time_feature_appended"], bool((data["observation"] == torch.from_numpy(obs)).all())
        (True, True)
    """
    path = Path(path)
    where = str(path)
    if max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}.")
    arrays = _read_archive(path, where)
    obs, actions, rewards = _checked_arrays(arrays, where)
    start_idx, lengths = _episodes(arrays["episode_starts"], len(obs), max_episode_steps, where)
    rewards = rewards.astype(np.float64)
    returns = _episode_returns(arrays, rewards, start_idx, lengths, where)
    check_action_bounds(
        actions, -1.0, 1.0, where, space="[-1, 1]", hint="; rescale them to the normalised action space first"
    )
    data, has_feature, appended = _transitions(
        obs,
        actions,
        rewards,
        start_idx,
        lengths,
        max_episode_steps=max_episode_steps,
        time_feature=time_feature,
        where=where,
    )
    check_transitions(data, where)

    metadata = dict(
        format="stable_baselines.ExpertDataset",
        source=where,
        file_keys=sorted(arrays),
        n_episodes=len(lengths),
        n_transitions=len(obs),
        episode_returns=returns.tolist(),
        episode_lengths=lengths.tolist(),
        observation_dim=int(data["observation"].shape[1]),
        action_dim=actions.shape[1],
        max_episode_steps=int(max_episode_steps),
        time_feature=has_feature,
        time_feature_appended=appended,
    )
    if match := _SB_NAME.search(path.stem):
        metadata.update(env_name=match["env"], nominal_score=float(match["score"]))
    return Demonstrations(data, metadata)


def _read_archive(path: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of the ``.npz`` file ``path``, which must exist, hold every key of ``_SB_KEYS``
    and not be a refused SAIL teacher."""
    if not path.is_file():
        raise FileNotFoundError(f"demonstration file not found: {path}")
    refused = refused_teacher(path.name)
    if refused:
        raise ValueError(f"{where}: this published SAIL teacher file is refused: {refused}.")
    try:
        # NpzFile, not np.load: np.load(allow_pickle=True) would unpickle a non-zip file.
        with np.lib.npyio.NpzFile(path, allow_pickle=True) as npz:
            arrays = {key: npz[key] for key in npz.files}
    except Exception as err:  # zipfile/zlib/pickle/EOF errors of a foreign or damaged file
        raise ValueError(f"{where}: not a readable .npz archive: {err}") from err
    missing = [key for key in _SB_KEYS if key not in arrays]
    if missing:
        raise ValueError(f"{where}: missing key {missing[0]!r}; found {sorted(arrays)}.")
    return arrays


def _checked_arrays(arrays: dict[str, np.ndarray], where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(obs, actions, rewards)`` as ``[N, obs_dim]``, ``[N, action_dim]`` and ``[N]``, once the shapes
    (``episode_starts`` included) agree and every number (``episode_returns`` included) is finite."""
    obs, raw_starts = arrays["obs"], arrays["episode_starts"]
    n = len(obs)
    actions = arrays["actions"].reshape(len(arrays["actions"]), -1)
    rewards = arrays["rewards"]
    rewards = rewards[:, 0] if rewards.ndim == 2 and rewards.shape[1] == 1 else rewards
    if obs.ndim != 2 or rewards.shape != (n,) or not len(actions) == len(raw_starts) == n > 0:
        raise ValueError(
            f"{where}: shapes obs {obs.shape}, actions {arrays['actions'].shape}, rewards "
            f"{arrays['rewards'].shape}, episode_starts {raw_starts.shape} are not (N, obs_dim), "
            f"(N, action_dim), (N,) or (N, 1), (N,) with N > 0."
        )
    read = {key: arrays[key] for key in ("obs", "actions", "rewards")}
    if "episode_returns" in arrays:
        read["episode_returns"] = arrays["episode_returns"]
    try:
        check_finite({key: np.asarray(value, dtype=np.float64) for key, value in read.items()}, where)
    except (TypeError, ValueError) as err:
        if "non-finite" in str(err):
            raise
        raise ValueError(f"{where}: non-numeric arrays: {err}") from err
    return obs, actions, rewards


def _episodes(raw_starts: np.ndarray, n: int, max_episode_steps: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """``(start_idx, lengths)`` of the episodes that ``episode_starts`` marks among ``n`` rows, none
    longer than ``max_episode_steps``."""
    # Element 0 of the object array is a Python bool, the others 1-element arrays.
    starts = np.array([np.asarray(x).ravel()[0] for x in raw_starts], dtype=bool)
    if not starts[0]:
        raise ValueError(f"{where}: 'episode_starts'[0] is False; row 0 must start an episode.")
    start_idx = np.flatnonzero(starts)
    lengths = np.diff(np.append(start_idx, n))
    if lengths.max() > max_episode_steps:
        raise ValueError(
            f"{where}: episode {lengths.argmax()} has {lengths.max()} steps, more than "
            f"max_episode_steps={max_episode_steps} (the time limit of the recording)."
        )
    return start_idx, lengths


def _episode_returns(
    arrays: dict[str, np.ndarray], rewards: np.ndarray, start_idx: np.ndarray, lengths: np.ndarray, where: str
) -> np.ndarray:
    """The file's ``episode_returns``, checked against the float64 ``rewards``; the sums of the
    rewards if the file has none."""
    returns = np.add.reduceat(rewards, start_idx)
    if "episode_returns" in arrays:
        recorded = arrays["episode_returns"].astype(np.float64).reshape(-1)
        if recorded.shape != returns.shape:
            raise ValueError(
                f"{where}: 'episode_returns' has {recorded.size} entries but "
                f"'episode_starts' marks {returns.size} episodes."
            )
        # The recorder summed float64 rewards before they were stored as float32.
        check_returns(recorded, rewards, lengths, where)
        returns = recorded
    return returns


def _transitions(
    obs: np.ndarray,
    actions: np.ndarray,
    rewards: np.ndarray,
    start_idx: np.ndarray,
    lengths: np.ndarray,
    *,
    max_episode_steps: int,
    time_feature: bool | None,
    where: str,
) -> tuple[TensorDictBase, bool, bool]:
    """The transitions of the episodes, with the approximated final next observations (see
    :func:`load_sb_demonstrations`), and ``resolve_time_feature``'s ``(has_feature, appended)``."""
    last = start_idx + lengths - 1
    # Each episode's observations plus its approximated final observation.
    with_final = np.insert(obs, last + 1, obs[last], axis=0)
    full_length = np.repeat(lengths >= max_episode_steps, lengths)
    done = np.zeros(len(obs), dtype=bool)
    done[last] = True
    data = episodes_to_transitions(
        with_final,
        np.clip(actions.astype(np.float32), -1.0, 1.0),
        rewards,
        done & ~full_length,
        done & full_length,
        lengths,
    )
    data, has_feature, appended = resolve_time_feature(
        data, max_episode_steps=max_episode_steps, time_feature=time_feature, where=where
    )
    if has_feature and not appended:  # advance the copied time column of the final next states
        final = torch.as_tensor(1.0 - lengths / max_episode_steps, dtype=data["observation"].dtype)
        data["next", "observation"][torch.as_tensor(last), -1] = final
    return data, has_feature, appended


def _is_npz(path: str | os.PathLike) -> bool:
    return Path(path).suffix == ".npz" and Path(path).is_file()


register_reader("a stable-baselines ExpertDataset '.npz' file", _is_npz, load_sb_demonstrations)
