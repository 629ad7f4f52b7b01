"""The core every demonstration format shares: episodes -> flat transitions, and the checks.

The formats (:mod:`~torchrl_sail.data.npz` for the paper's ``.npz`` files,
:mod:`~torchrl_sail.data.folder` for the project's folders,
:mod:`~torchrl_sail.data.minari` for Minari datasets) import this module and nothing else of
the package, so they never import each other. Each one registers a reader here
(:func:`register_reader`); :func:`read_demonstrations` dispatches a path to the reader that
accepts it, which is how :func:`~torchrl_sail.load_demonstrations` and
:func:`~torchrl_sail.export_minari_dataset` read any format without an import cycle
(``torchrl_sail.data`` imports every format module, so all readers are registered once the
package is imported).

What is checked here, with errors that name the file (``where``), the entry and the row:

- :func:`check_finite`: no NaN or infinity (they would surface much later, as a divergence);
- :func:`check_returns`: recorded episode returns are the sums of the dense rewards, to
  ``RETURNS_ATOL + RETURNS_RTOL * sum(|rewards|)`` (the recorders sum float64 rewards that are
  then stored as float32);
- :func:`check_action_bounds`: actions inside their space, to ``ACTION_ROUNDING``;
- :func:`check_transitions`: the README's transition layout;
- :func:`resolve_time_feature`: the remaining-time column ``1 - t/T``, detected, verified,
  or computed and appended.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase

from torchrl_sail.data.keys import TRANSITION_KEYS

__all__ = [
    "ACTION_ROUNDING",
    "Demonstrations",
    "RETURNS_ATOL",
    "RETURNS_RTOL",
    "TIME_FEATURE_ATOL",
    "check_action_bounds",
    "check_finite",
    "check_returns",
    "check_transitions",
    "episodes_to_transitions",
    "json_default",
    "publish_directory",
    "read_demonstrations",
    "register_reader",
    "resolve_time_feature",
    "steps_from_done",
    "time_limit_of",
]

#: float32 rounding in the recorders: actions may leave their bounds by ~1e-7.
ACTION_ROUNDING = 1e-5
#: The time column of the paper's files matches ``1 - t/T`` to ~3e-8.
TIME_FEATURE_ATOL = 1e-5
#: Recorded episode returns must match the sums of the rewards to
#: ``RETURNS_ATOL + RETURNS_RTOL * sum(|rewards|)``.
RETURNS_ATOL = 1e-3
RETURNS_RTOL = 1e-5

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


# ---------------------------------------------------------------------------------------------
# Readers: how load_demonstrations finds the format of a path.


class _Reader(NamedTuple):
    description: str
    accepts: Callable[[str | os.PathLike], bool]
    load: Callable[..., Demonstrations]


_READERS: list[_Reader] = []


def register_reader(
    description: str,
    accepts: Callable[[str | os.PathLike], bool],
    load: Callable[..., Demonstrations],
) -> None:
    """Registers a demonstration format for :func:`read_demonstrations`.

    Each format module calls this once, at import. The formats' ``accepts`` are mutually
    exclusive (a ``.npz`` file, a folder with ``metadata.json``, a Minari dataset), so the
    order of registration does not matter.

    Args:
        description (str): what the format is, for the error on a path no reader accepts.
        accepts (callable): ``accepts(path) -> bool``, cheap and without side effects.
        load (callable): ``load(path, *, max_episode_steps, time_feature) -> Demonstrations``.
    """
    if all(reader.load is not load for reader in _READERS):
        _READERS.append(_Reader(description, accepts, load))


def read_demonstrations(
    path: str | os.PathLike, *, max_episode_steps: int = 1000, time_feature: bool | None = None
) -> Demonstrations:
    """Reads ``path`` with the registered format that accepts it (see :func:`register_reader`).

    Raises:
        FileNotFoundError: no reader accepts ``path`` and it does not exist.
        ValueError: no reader accepts ``path`` (it exists but is no demonstrations).

    Examples:
        >>> import os, tempfile
        >>> from torchrl_sail.data.episodes import read_demonstrations
        >>> try:
        ...     read_demonstrations(os.path.join(tempfile.mkdtemp(), "absent.npz"))
        ... except FileNotFoundError as err:
        ...     print("absent.npz: not demonstrations" in str(err))
        True
    """
    for reader in _READERS:
        if reader.accepts(path):
            return reader.load(path, max_episode_steps=max_episode_steps, time_feature=time_feature)
    expected = [reader.description for reader in _READERS]
    expected = ", ".join(expected[:-1]) + f", or {expected[-1]}" if len(expected) > 1 else "".join(expected)
    raise (ValueError if Path(path).exists() else FileNotFoundError)(
        f"{path}: not demonstrations; expected {expected}."
    )


# ---------------------------------------------------------------------------------------------
# Checks shared by every format.


def check_finite(arrays: Mapping[Any, np.ndarray | torch.Tensor], where: str, *, row_name: str = "row") -> None:
    """Raises if any array holds a NaN or an infinity, naming ``where``, the key and the row.

    Args:
        arrays: ``{key: array}``; the first dim of each array is its rows. Non-float arrays
            are skipped.
        where (str): the file (and episode) the arrays come from, first in the message.

    Keyword Args:
        row_name (str): what a row is called in the message (``"row"``, ``"episode"``,
            ``"step"``). Defaults to ``"row"``.

    Raises:
        ValueError: ``"<where>: 'obs' has a non-finite value (nan) at row 3, column 2 ..."``.

    Examples:
        >>> import numpy as np
        >>> from torchrl_sail.data.episodes import check_finite
        >>> check_finite({"obs": np.zeros((3, 2))}, "demo.npz")  # fine
        >>> try:
        ...     check_finite({"obs": np.array([[0.0, 1.0], [np.inf, 0.0]])}, "demo.npz")
        ... except ValueError as err:
        ...     print(err)
        demo.npz: 'obs' has a non-finite value (inf) at row 1, column 0; demonstrations must be
        finite (a NaN or infinity would only surface later, as a divergence of training).
    """
    for key, array in arrays.items():
        if isinstance(array, torch.Tensor):
            if not array.is_floating_point():
                continue
            array = array.detach().cpu().numpy()
        array = np.asarray(array)
        if not np.issubdtype(array.dtype, np.floating):
            continue
        bad = ~np.isfinite(array)
        if bad.any():
            index = np.unravel_index(int(np.argmax(bad)), array.shape)
            position = f"{row_name} {index[0]}" if index else "its only entry"
            if len(index) > 1:
                position += ", column " + ", ".join(str(int(i)) for i in index[1:])
            raise ValueError(
                f"{where}: {key!r} has a non-finite value ({array[index]}) at {position}; demonstrations "
                f"must be finite (a NaN or infinity would only surface later, as a divergence of training)."
            )


def check_returns(
    recorded: Sequence[float] | np.ndarray,
    rewards: np.ndarray | torch.Tensor,
    lengths: Sequence[int] | np.ndarray,
    where: str,
    *,
    what: str = "recorded return",
    hint: str = "corrupt or mis-assembled file",
) -> None:
    """Checks recorded per-episode returns against the sums of the dense rewards.

    The tolerance is ``RETURNS_ATOL + RETURNS_RTOL * sum(|rewards|)`` per episode: the
    recorders sum float64 rewards that are then stored as float32.

    Args:
        recorded: one return per episode.
        rewards: the ``N`` dense rewards, episodes concatenated.
        lengths: the episode lengths (summing to ``N``).
        where (str): the file, first in the message.

    Keyword Args:
        what (str): what the recorded returns are called in the message.
        hint (str): the likely cause, last in the message.

    Raises:
        ValueError: a return differs from its episode's sum, or is not finite.

    Examples:
        >>> from torchrl_sail.data.episodes import check_returns
        >>> check_returns([3.0, 2.0], [1.0] * 5, [3, 2], "demo.npz")
        >>> try:
        ...     check_returns([3.0, 5.0], [1.0] * 5, [3, 2], "demo.npz")
        ... except ValueError as err:
        ...     print(err)
        demo.npz: episode 1 has recorded return 5.000000 but its rewards sum to 2.000000
        (corrupt or mis-assembled file).
    """
    recorded = np.asarray(recorded, dtype=np.float64).reshape(-1)
    check_finite({what: recorded}, where, row_name="episode")
    rewards = np.asarray(rewards, dtype=np.float64).reshape(-1)
    starts = np.cumsum([0, *list(lengths)[:-1]]).astype(np.int64)
    sums = np.add.reduceat(rewards, starts)
    scale = np.add.reduceat(np.abs(rewards), starts)
    bad = np.abs(recorded - sums) > RETURNS_ATOL + RETURNS_RTOL * scale
    if bad.any():
        ep = int(bad.argmax())
        raise ValueError(
            f"{where}: episode {ep} has {what} {recorded[ep]:.6f} but its rewards sum to {sums[ep]:.6f} ({hint})."
        )


def check_action_bounds(
    actions: np.ndarray, low: np.ndarray | float, high: np.ndarray | float, where: str, *, space: str, hint: str = ""
) -> None:
    """Checks ``low <= actions <= high`` to ``ACTION_ROUNDING`` (float32 rounding of the recorders).

    Raises:
        ValueError: names ``where``, the space, the excess and the row.

    Examples:
        >>> import numpy as np
        >>> from torchrl_sail.data.episodes import check_action_bounds
        >>> try:
        ...     check_action_bounds(np.array([[0.5], [1.5]]), -1.0, 1.0, "demo.npz", space="[-1, 1]")
        ... except ValueError as err:
        ...     print(err)
        demo.npz: actions leave the action space [-1, 1] by 0.5 at row 1.
    """
    outside = np.maximum(actions - high, low - actions).reshape(len(actions), -1).max(-1)
    if len(outside) and outside.max() > ACTION_ROUNDING:
        raise ValueError(
            f"{where}: actions leave the action space {space} by {outside.max():.3g} at row "
            f"{int(outside.argmax())}{hint}."
        )


def check_transitions(data: TensorDictBase, where: str) -> None:
    """Checks the README's transition layout; the error names ``where``, the entry (and row).

    Flat, non-empty ``[N]``; the ``TRANSITION_KEYS`` of :mod:`torchrl_sail.data.keys`; bool
    ``[N, 1]`` flags with ``done == terminated | truncated``; ``[N, 1]`` rewards; observations
    and next observations of one shape; a done last row (complete episodes only); finite
    floating-point entries.

    Raises:
        ValueError: the first problem found.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail.data.episodes import check_transitions
        >>> done = torch.tensor([[False], [True]])
        >>> td = TensorDict({"observation": torch.zeros(2, 3), "action": torch.zeros(2, 1),
        ...     ("next", "observation"): torch.zeros(2, 3), ("next", "reward"): torch.ones(2, 1),
        ...     ("next", "done"): done, ("next", "terminated"): done,
        ...     ("next", "truncated"): torch.zeros_like(done)}, batch_size=[2])
        >>> check_transitions(td, "demos")  # fine
        >>> td["next", "reward"][0] = float("nan")
        >>> try:
        ...     check_transitions(td, "demos")
        ... except ValueError as err:
        ...     print(str(err).split(";")[0])
        demos: ('next', 'reward') has a non-finite value (nan) at row 0, column 0
    """
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
        check_finite({key: data[key] for key in sorted(keys, key=str)}, where)
        return
    raise ValueError(f"{where}: {problem}.")


# ---------------------------------------------------------------------------------------------
# Episodes -> transitions, and the time feature.


def steps_from_done(done: torch.Tensor | np.ndarray) -> np.ndarray:
    """The in-episode index ``t`` of each row, episodes starting at row 0 and after each done.

    Examples:
        >>> from torchrl_sail.data.episodes import steps_from_done
        >>> steps_from_done([False, False, True, False, True]).tolist()
        [0, 1, 2, 0, 1]
    """
    done = np.asarray(done, dtype=bool).reshape(-1)
    starts = np.flatnonzero(np.r_[True, done[:-1]])
    lengths = np.diff(np.append(starts, len(done)))
    return np.arange(len(done)) - np.repeat(starts, lengths)


def episodes_to_transitions(
    observations: np.ndarray,
    actions: np.ndarray,
    rewards: np.ndarray,
    terminated: np.ndarray,
    truncated: np.ndarray,
    lengths: Sequence[int] | np.ndarray,
) -> TensorDict:
    """Whole episodes, as Minari stores them, to the flat ``[N]`` transitions of the README.

    An episode of ``T`` steps has ``T + 1`` observations (its reset observation first, the
    observation after its last step last) and ``T`` actions, rewards and flags. It gives ``T``
    rows: ``"observation"`` its observations ``0..T-1``, ``("next", "observation")``
    ``1..T``, ``"step_count"`` ``[N, 1]`` int64 the in-episode index ``t``, ``("next",
    "reward")`` ``[N, 1]`` float32, the flags ``[N, 1]`` bool with ``done = terminated |
    truncated``. Observations and actions become float32. Shapes are the caller's to check.

    Args:
        observations: ``(sum(T_i + 1), obs_dim)``, the episodes' observation sequences in order.
        actions: ``(N, action_dim)``.
        rewards, terminated, truncated: ``(N,)`` (or ``(N, 1)``).
        lengths: the ``T_i``, summing to ``N``.

    Examples:
        >>> import numpy as np
        >>> from torchrl_sail.data.episodes import episodes_to_transitions
        >>> obs = np.arange(5, dtype="float32")[:, None]  # episodes of 2 and 1 steps: 3 + 2 observations
        >>> td = episodes_to_transitions(obs, np.zeros((3, 1)), np.ones(3), np.array([0, 1, 0]),
        ...                              np.array([0, 0, 1]), [2, 1])
        >>> td["observation"].squeeze(-1).tolist(), td["next", "observation"].squeeze(-1).tolist()
        ([0.0, 1.0, 3.0], [1.0, 2.0, 4.0])
        >>> td["step_count"].squeeze(-1).tolist(), td["next", "done"].squeeze(-1).tolist()
        ([0, 1, 0], [False, True, True])
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    is_obs = np.ones(len(observations), dtype=bool)
    is_obs[np.cumsum(lengths + 1) - 1] = False  # the final observations
    is_next = np.roll(is_obs, 1)
    obs = torch.as_tensor(np.asarray(observations, dtype=np.float32))
    step = np.concatenate([np.arange(T) for T in lengths])
    terminated = torch.as_tensor(np.asarray(terminated, dtype=bool).reshape(-1, 1))
    truncated = torch.as_tensor(np.asarray(truncated, dtype=bool).reshape(-1, 1))
    n = int(lengths.sum())
    return TensorDict(
        {
            "observation": obs[torch.as_tensor(is_obs)],
            "action": torch.as_tensor(np.asarray(actions, dtype=np.float32).reshape(n, -1)),
            "step_count": torch.as_tensor(step, dtype=torch.int64).unsqueeze(-1),
            ("next", "observation"): obs[torch.as_tensor(is_next)],
            ("next", "reward"): torch.as_tensor(np.asarray(rewards, dtype=np.float32).reshape(n, 1)),
            ("next", "done"): terminated | truncated,
            ("next", "terminated"): terminated,
            ("next", "truncated"): truncated,
        },
        batch_size=[n],
    )


def time_limit_of(column: np.ndarray, step: np.ndarray) -> int | None:
    """``T`` if ``column`` is the time feature ``1 - t/T`` of some integer ``T``, else ``None``.

    Examples:
        >>> import numpy as np
        >>> from torchrl_sail.data.episodes import time_limit_of
        >>> step = np.array([0, 1, 2, 0, 1])
        >>> time_limit_of(1 - step / 50, step), time_limit_of(np.full(5, 0.3), step)
        (50, None)
    """
    column, step = np.asarray(column, dtype=np.float64), np.asarray(step)
    later = step > 0
    if not later.any() or np.abs(column[~later] - 1.0).max() > TIME_FEATURE_ATOL:
        return None
    slope = (1.0 - column[later]) / step[later]
    if slope.min() <= 0:
        return None
    limit = int(round(1.0 / float(np.median(slope))))
    error = np.abs(column - (1.0 - step / max(limit, 1))).max()
    return limit if error <= TIME_FEATURE_ATOL else None


def resolve_time_feature(
    data: TensorDictBase,
    *,
    max_episode_steps: int,
    time_feature: bool | None,
    where: str,
    step: np.ndarray | None = None,
) -> tuple[TensorDictBase, bool, bool]:
    """Detects, verifies or appends the remaining-time column ``1 - t/T`` of the observations.

    The rule, the same for every format: the last ``"observation"`` column *is* the time
    feature when it equals ``1 - t/T`` (``T = max_episode_steps``, ``t`` the in-episode step)
    to ``TIME_FEATURE_ATOL`` on every row. Then:

    - ``time_feature=False``: the data is returned untouched (``(data, False, False)``);
    - ``None``: detected, never changed (``(data, is_feature, False)``);
    - ``True``: kept if present, else computed and appended: ``1 - t/T`` to
      ``"observation"``, ``1 - (t + 1)/T`` to ``("next", "observation")``, exactly as
      :class:`~torchrl_sail.TimeFeature` does on the env (``(new data, True, True)``).

    In the ``None`` and ``True`` modes, a last column that is the time feature of *another*
    ``T`` is an error (appending a second column would hide a wrong ``max_episode_steps``).

    Args:
        data: flat ``[N]`` transitions.

    Keyword Args:
        max_episode_steps (int): ``T``.
        time_feature (bool or None): the mode.
        where (str): the file, first in error messages.
        step (array, optional): ``t`` per row. Defaults to ``data["step_count"]``, else the
            steps counted from the done flags (:func:`steps_from_done`).

    Returns:
        ``(data, has_time_feature, appended)``; ``data`` is a new tensordict when appended.

    Raises:
        ValueError: the last column is the time feature of ``T != max_episode_steps``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail.data.episodes import resolve_time_feature
        >>> done = torch.tensor([[False], [True]])
        >>> td = TensorDict({"observation": torch.zeros(2, 3), ("next", "observation"): torch.zeros(2, 3),
        ...                  ("next", "done"): done}, batch_size=[2])
        >>> out, has, appended = resolve_time_feature(td, max_episode_steps=10, time_feature=True, where="x")
        >>> has, appended, out["observation"][:, -1].tolist(), out["next", "observation"][:, -1].tolist()
        (True, True, [1.0, 0.8999999761581421], [0.8999999761581421, 0.800000011920929])
        >>> resolve_time_feature(out, max_episode_steps=10, time_feature=True, where="x")[1:]  # kept as is
        (True, False)
    """
    if time_feature is False:
        return data, False, False
    if data["observation"].ndim != 2:
        if time_feature is None:
            return data, False, False
        raise ValueError(
            f"{where}: 'observation' has shape {tuple(data['observation'].shape)}; the time feature "
            f"needs [N, dim] vector observations."
        )
    if step is None:
        step = (
            data["step_count"].reshape(-1).cpu().numpy()
            if "step_count" in data.keys()
            else steps_from_done(data["next", "done"].cpu())
        )
    step = np.asarray(step, dtype=np.float64).reshape(-1)
    column = data["observation"][:, -1].detach().cpu().double().numpy()
    matches = bool(np.abs(column - (1.0 - step / max_episode_steps)).max() <= TIME_FEATURE_ATOL)
    if not matches:
        other = time_limit_of(column, step)
        if other is not None:
            raise ValueError(
                f"{where}: the last observation column is the time feature 1 - t/T with T={other}, "
                f"not max_episode_steps={max_episode_steps}: pass max_episode_steps={other} (the time "
                f"limit of the recording)."
            )
    if matches or not time_feature:
        return data, matches, False
    data = data.clone(recurse=False)
    data["next"] = data["next"].clone(recurse=False)
    for key, t in (("observation", step), (("next", "observation"), step + 1)):
        obs = data[key]
        feature = torch.as_tensor(1.0 - t / max_episode_steps, dtype=obs.dtype, device=obs.device)
        data[key] = torch.cat([obs, feature.unsqueeze(-1)], dim=-1)
    return data, True, True


# ---------------------------------------------------------------------------------------------
# Writing.


def json_default(what: str) -> Callable[[Any], Any]:
    """``json.dumps(default=...)`` for metadata: arrays and tensors as lists, paths as strings, sets sorted.

    Examples:
        >>> import json, numpy as np
        >>> from torchrl_sail.data.episodes import json_default
        >>> json.dumps({"x": np.float32(0.5), "s": {"b", "a"}}, default=json_default("metadata"))
        '{"x": 0.5, "s": ["a", "b"]}'
    """

    def default(obj: Any) -> Any:
        if isinstance(obj, (np.ndarray, np.generic, torch.Tensor)):
            return obj.tolist()
        if isinstance(obj, os.PathLike):
            return os.fspath(obj)
        if isinstance(obj, set):
            return sorted(obj)
        raise TypeError(f"{what} must be JSON-able; got {obj!r}.")

    return default


def publish_directory(path: Path, write: Callable[[Path], None]) -> None:
    """Builds a directory with ``write(staging)`` and swaps it in for ``path``.

    Staging and backup sit beside ``path``, on its filesystem, so ``os.replace`` is a
    rename. An existing ``path`` is moved aside first (a non-empty directory cannot be
    replaced in one rename) and comes back if the swap fails; a failed ``write`` leaves
    ``path`` as it was and nothing else behind.

    Args:
        path (Path): the destination directory.
        write (callable): ``write(staging)`` creates the directory ``staging`` (which does not
            exist yet) with the content of ``path``.
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
