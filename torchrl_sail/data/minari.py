"""Demonstrations in Minari format, the gymnasium ecosystem's standard for offline datasets.

A Minari dataset is a folder ``<root>/<dataset id>/data`` (``root`` is ``MINARI_DATASETS_PATH``,
default ``~/.minari/datasets``) of whole episodes: ``T + 1`` observations and ``T`` actions,
rewards, terminations and truncations each. :func:`load_minari_demonstrations` turns one into
the flat transitions of :mod:`torchrl_sail.data.episodes` (with the checks every format gets
there), :func:`export_minari_dataset` writes any demonstrations as one. Both work on local
folders only: nothing is downloaded (``minari download <id>`` does that; TorchRL's
``MinariExperienceReplay`` downloads as well).

Minari is used through its public API: ``minari.MinariDataset`` to read,
``minari.create_dataset_from_buffers`` to write, ``minari.namespace.create_namespace`` for the
namespace folders, ``MINARI_DATASETS_PATH`` to point them at a folder. The dataset and
per-episode metadata those functions have no argument for go through the dataset's storage
object, in one function, :func:`_storage_metadata`.

This module imports only the core, :mod:`torchrl_sail.data.episodes`, and registers its reader
there (``"minari:<dataset id>"`` or a dataset folder). The ``minari`` package is optional:
``pip install -e '.[minari]'`` (it brings ``h5py``, the storage backend Minari uses by default).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

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
    json_default,
    publish_directory,
    read_demonstrations,
    register_reader,
    resolve_time_feature,
)

__all__ = ["export_minari_dataset", "load_minari_demonstrations"]

#: ``load_demonstrations("minari:<dataset id>")`` reads a Minari dataset by id.
MINARI_PREFIX = "minari:"
# Our metadata (the exported demonstrations' own) inside the dataset's metadata
_METADATA_KEY = "torchrl_sail"
_INSTALL = "pip install -e '.[minari]'"
# recomputed by the loader, not carried over from the exported metadata
_RECOMPUTED = ("episode_returns", "episode_lengths", "n_episodes", "n_transitions")
# Minari's (namespace/)name-v<version>, with the version required (Minari's own parser accepts
# none, then fails on int(None))
_DATASET_ID = re.compile(r"(?:(?P<namespace>[-_\w][-_\w/]*[-_\w]+)/)?(?P<name>[-_\w]+?)-v(?P<version>\d+)")


def _import_minari():
    try:
        import minari
    except ImportError as err:
        raise ImportError(
            f"Minari datasets need the optional minari package: {_INSTALL} (or pip install 'minari[hdf5]')."
        ) from err
    return minari


def minari_datasets_root(root: str | os.PathLike | None = None) -> Path:
    """Where Minari datasets live: ``root``, else ``MINARI_DATASETS_PATH``, else ``~/.minari/datasets``.

    Examples:
        >>> from torchrl_sail.data.minari import minari_datasets_root
        >>> str(minari_datasets_root("/data/minari"))
        '/data/minari'
    """
    if root is not None:
        return Path(root).expanduser()
    env = os.environ.get("MINARI_DATASETS_PATH")  # minari's own rule (minari.storage)
    return Path(env) if env else Path.home() / ".minari" / "datasets"


def is_minari_dataset(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a Minari dataset folder (with ``data/metadata.json``) or its ``data/``.

    Examples:
        >>> import tempfile
        >>> from torchrl_sail.data.minari import is_minari_dataset
        >>> is_minari_dataset(tempfile.mkdtemp())
        False
    """
    path = Path(path).expanduser()
    if path.name == "data" and not (path / "meta.json").exists():  # (a tensordict folder has it)
        path = path.parent
    return (path / "data" / "metadata.json").is_file()


def _resolve(dataset: str | os.PathLike, root: str | os.PathLike | None) -> Path:
    """The dataset folder (the one holding ``data/``) of an id, ``minari:<id>`` or a path."""
    by_id = isinstance(dataset, str) and dataset.startswith(MINARI_PREFIX)
    if by_id:
        dataset = dataset[len(MINARI_PREFIX) :]
    path = Path(dataset).expanduser()
    if isinstance(dataset, os.PathLike) or (not by_id and path.is_dir()):
        if not is_minari_dataset(path):
            raise (ValueError if path.exists() else FileNotFoundError)(
                f"{path}: not a Minari dataset folder (no {path / 'data' / 'metadata.json'})."
            )
        return path if (path / "data" / "metadata.json").is_file() else path.parent  # (given data/)
    base = minari_datasets_root(root)
    folder = base / dataset
    if not is_minari_dataset(folder):
        how = (
            "root="
            if root is not None
            else "MINARI_DATASETS_PATH"
            if os.environ.get("MINARI_DATASETS_PATH")
            else "Minari's default; set MINARI_DATASETS_PATH to look elsewhere"
        )
        raise FileNotFoundError(
            f"Minari dataset {dataset!r} not found locally: no {folder / 'data'} (ids are looked "
            f"up under {base}, from {how}; nothing is downloaded). Get it with `minari download "
            f"{dataset}`, or write one with export_minari_dataset or examples/export_minari.py."
        )
    return folder


@contextlib.contextmanager
def _datasets_path(root: Path) -> Iterator[None]:
    """Points Minari's functions at ``root``: they read the datasets folder from ``MINARI_DATASETS_PATH`` only."""
    previous = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous


def _storage_metadata(dataset: Any, update: tuple[dict, list[dict]] | None = None) -> tuple[dict, list[dict]]:
    """The dataset's metadata and per-episode metadata, after writing ``update`` if given.

    The one place this module goes below Minari's top-level functions, to the dataset's storage
    (``MinariDataset.storage``, a ``MinariStorage``): ``create_dataset_from_buffers`` has no
    argument for extra dataset metadata (the demonstrations' own, under ``"torchrl_sail"``) or
    for per-episode metadata (``rewards_sum``, the recorded float64 returns), and
    ``MinariDataset`` has no getter for either (nor for ``author`` or ``description``).

    Args:
        dataset (minari.MinariDataset): the dataset.
        update (tuple, optional): ``(dataset metadata, [per-episode metadata])`` to write first.

    Returns:
        ``(metadata, episode_metadata)``: Minari's metadata dict (spaces as gymnasium spaces,
        authors as sets) and one dict per episode.
    """
    storage = dataset.storage
    if update is not None:
        storage.update_metadata(update[0])
        storage.update_episode_metadata(update[1])
    return storage.metadata, list(storage.get_episode_metadata(dataset.episode_indices))


def load_minari_demonstrations(
    dataset: str | os.PathLike,
    *,
    root: str | os.PathLike | None = None,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a local Minari dataset as flat transitions, with the checks of the other loaders.

    Each episode of ``T`` steps gives ``T`` rows: ``"observation"`` its observations ``0..T-1``,
    ``("next", "observation")`` ``1..T`` (the recorded final observation included: unlike the
    ``.npz`` files, nothing is approximated), ``"action"``, ``("next", "reward")`` (dense,
    float32, ``[N, 1]``), ``("next", "terminated")`` and ``("next", "truncated")`` as
    recorded, ``("next", "done")`` their union, and ``"step_count"`` the in-episode index ``t``
    (a Minari episode starts at a reset). Observations and actions become float32.

    Time feature: the project's envs append ``1 - t/T`` to the observation
    (:class:`~torchrl_sail.TimeFeature`); datasets exported from this project have the column,
    datasets recorded on a plain gymnasium env (e.g. the D4RL MuJoCo ones) do not. As in
    :func:`~torchrl_sail.load_sb_demonstrations`, ``time_feature=None`` detects the column and
    ``False`` leaves the observations alone. ``True`` asks for observations *with* the column:
    kept if the dataset has it, else appended, exactly (``t`` is known). So a D4RL-style dataset
    loads as recorded by default (and :func:`~torchrl_sail.check_demonstration_dims` then flags the
    env's extra column), and with ``True`` fits the project's env, as in ``examples/``. A last
    column that is the time feature of another ``T`` is an error in both ``None`` and ``True`` modes.
    The rule is :func:`~torchrl_sail.data.episodes.resolve_time_feature`'s, the same for every format.

    Args:
        dataset: a dataset id (``"sail/Hopper-v4/teacher-v0"``, or ``"minari:<id>"``) looked up
            under ``root``, or a path to a dataset folder (the one holding ``data/``).

    Keyword Args:
        root (str or path, optional): where ids are looked up. Defaults to
            ``MINARI_DATASETS_PATH``, else ``~/.minari/datasets`` (Minari's own rule).
        max_episode_steps (int): the time limit ``T``: longer episodes are refused, and the
            time feature is ``1 - t/T``. Defaults to ``1000`` (the MuJoCo tasks).
        time_feature (bool, optional): see above. Defaults to ``None`` (detect).

    Returns:
        Demonstrations: ``(data, metadata)``. The metadata has ``episode_returns`` (the episodes'
        ``rewards_sum`` where the dataset records it, checked against the rewards, else their
        sums), ``episode_lengths``, ``source`` (the dataset folder), ``dataset_id``, ``env_id``
        (of the dataset's env spec, if any), ``time_feature``, ``time_feature_appended``, the
        metadata the demonstrations had when they were exported by :func:`export_minari_dataset`
        (their first ``source`` as ``exported_from``), and Minari's ``algorithm_name``, ``author``,
        ``description`` where present.

    Raises:
        ImportError: ``minari`` is not installed.
        FileNotFoundError: no such local dataset; the message names the id and the folder.
        ValueError: unreadable dataset, a non-vector (dict, tuple, discrete, image) space,
            inconsistent shapes, a NaN or infinity (naming the episode, entry and step), an
            episode that does not end (or ends early) with
            terminated/truncated, an episode longer than ``max_episode_steps``, actions outside
            the action space, ``rewards_sum`` that are not the sums of the rewards.

    Examples:
        >>> import tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import export_minari_dataset, load_minari_demonstrations
        >>> def episode(T, terminated):  # T steps of 3-dim observations, reward 1
        ...     obs, done = torch.randn(T + 1, 3), torch.arange(T)[:, None] == T - 1
        ...     return TensorDict({"observation": obs[:-1], "action": torch.zeros(T, 2),
        ...         ("next", "observation"): obs[1:], ("next", "reward"): torch.ones(T, 1),
        ...         ("next", "done"): done, ("next", "terminated"): done & terminated,
        ...         ("next", "truncated"): done & (not terminated)}, batch_size=[T])
        >>> td = torch.cat([episode(2, terminated=True), episode(3, terminated=False)])
        >>> root = tempfile.mkdtemp()
        >>> export_minari_dataset(td, "demo/toy-v0", root=root).name
        'toy-v0'
        >>> data, meta = load_minari_demonstrations("demo/toy-v0", root=root)
        >>> meta["episode_lengths"], meta["episode_returns"], meta["time_feature"]
        ([2, 3], [2.0, 3.0], False)
        >>> bool((data.exclude("step_count") == td).all())  # the same transitions
        True
        >>> data["step_count"].squeeze(-1).tolist()
        [0, 1, 0, 1, 2]
        >>> data, meta = load_minari_demonstrations("minari:demo/toy-v0", root=root,
        ...                                         time_feature=True)  # appends 1 - t/1000
        >>> data["observation"].shape, data["next", "observation"][-1, -1].item()
        (torch.Size([5, 4]), 0.996999979019165)
    """
    if max_episode_steps < 1:
        raise ValueError(f"max_episode_steps must be >= 1, got {max_episode_steps}.")
    minari = _import_minari()
    import gymnasium as gym

    folder = _resolve(dataset, root)
    where = str(folder)
    try:
        minari_dataset = minari.MinariDataset(folder / "data")
        raw, episode_metadata = _storage_metadata(minari_dataset)
    except Exception as err:  # a damaged folder, an unknown storage format, a missing backend
        if isinstance(err, ImportError):
            raise
        raise ValueError(f"{where}: not a readable Minari dataset: {type(err).__name__}: {err}") from err
    spaces = {"observation": minari_dataset.observation_space, "action": minari_dataset.action_space}
    for name, space in spaces.items():
        if not (isinstance(space, gym.spaces.Box) and len(space.shape) == 1):
            raise ValueError(
                f"{where}: the {name} space is {space}: only flat Box (vector) spaces are "
                f"supported, not dict, tuple, discrete or image spaces (flatten them, e.g. with "
                f"gymnasium's FlattenObservation, before recording)."
            )
    obs_dim, act_dim = spaces["observation"].shape[0], spaces["action"].shape[0]

    observations, actions, rewards, terminations, truncations, lengths = [], [], [], [], [], []
    for i, episode in enumerate(minari_dataset.iterate_episodes()):
        obs, act = np.asarray(episode.observations), np.asarray(episode.actions)
        rew, term, trunc = map(np.asarray, (episode.rewards, episode.terminations, episode.truncations))
        T = rew.shape[0] if rew.ndim == 1 else -1
        shapes = (obs.shape, act.shape, term.shape, trunc.shape)
        if T < 1 or shapes != ((T + 1, obs_dim), (T, act_dim), (T,), (T,)):
            raise ValueError(
                f"{where}: episode {i}: observations {obs.shape}, actions {act.shape}, rewards "
                f"{rew.shape}, terminations {term.shape}, truncations {trunc.shape}; expected "
                f"(T + 1, {obs_dim}), (T, {act_dim}), (T,), (T,), (T,) with T >= 1 (the dims of "
                f"the dataset's spaces)."
            )
        check_finite({"observations": obs, "actions": act, "rewards": rew}, f"{where}: episode {i}", row_name="step")
        done = term.astype(bool) | trunc.astype(bool)
        if not done[-1]:
            raise ValueError(
                f"{where}: episode {i} does not end with terminated or truncated: demonstrations "
                f"must be whole episodes."
            )
        if done[:-1].any():
            raise ValueError(
                f"{where}: episode {i} is done at step {int(done.argmax())}, before its last step "
                f"{T - 1}: one episode per Minari episode."
            )
        if T > max_episode_steps:
            raise ValueError(
                f"{where}: episode {i} has {T} steps, more than max_episode_steps={max_episode_steps} "
                f"(the time limit of the recording)."
            )
        observations.append(obs)
        actions.append(act)
        rewards.append(rew)
        terminations.append(term.astype(bool))
        truncations.append(trunc.astype(bool))
        lengths.append(T)
    if not lengths:
        raise ValueError(f"{where}: the dataset has no episodes.")

    action, reward = np.concatenate(actions), np.concatenate(rewards).astype(np.float32)
    space = spaces["action"]
    check_action_bounds(action, space.low, space.high, where, space=str(space))
    returns = np.add.reduceat(reward.astype(np.float64), np.cumsum([0, *lengths[:-1]]))
    recorded = [m.get("rewards_sum") for m in episode_metadata]
    if recorded and all(r is not None for r in recorded):
        check_returns(recorded, reward, lengths, where, what="rewards_sum", hint="corrupt or mis-assembled dataset")
        returns = np.asarray(recorded, dtype=np.float64)

    data = episodes_to_transitions(
        np.concatenate(observations),
        action,
        reward,
        np.concatenate(terminations),
        np.concatenate(truncations),
        lengths,
    )
    data, has_feature, appended = resolve_time_feature(
        data, max_episode_steps=max_episode_steps, time_feature=time_feature, where=where
    )
    check_transitions(data, where)

    exported = raw.get(_METADATA_KEY, {})
    metadata = {key: value for key, value in exported.items() if key not in _RECOMPUTED}
    if "source" in exported:
        metadata["exported_from"] = exported["source"]
    env_spec = minari_dataset.spec.env_spec
    extra = {key: raw[key] for key in ("algorithm_name", "description") if key in raw}
    if "author" in raw:
        extra["author"] = sorted(raw["author"])
    metadata.update(
        format="minari",
        source=where,
        dataset_id=minari_dataset.spec.dataset_id,
        **({"env_id": env_spec.id} if env_spec is not None else {}),
        minari_version=minari_dataset.spec.minari_version,
        data_format=raw.get("data_format"),
        n_episodes=len(lengths),
        n_transitions=int(data.batch_size[0]),
        episode_returns=[float(r) for r in returns],
        episode_lengths=lengths,
        observation_dim=int(data["observation"].shape[1]),
        action_dim=act_dim,
        max_episode_steps=int(max_episode_steps),
        time_feature=has_feature,
        time_feature_appended=appended,
        **extra,
    )
    return Demonstrations(data, metadata)


def export_minari_dataset(
    demonstrations: Demonstrations | TensorDictBase | str | os.PathLike,
    dataset_id: str,
    *,
    env: Any = None,
    root: str | os.PathLike | None = None,
    algorithm_name: str | None = None,
    author: str | None = None,
    author_email: str | None = None,
    code_permalink: str | None = None,
    description: str | None = None,
    data_format: str = "hdf5",
    overwrite: bool = False,
    max_episode_steps: int = 1000,
) -> Path:
    """Writes demonstrations as a local Minari dataset ``<root>/<dataset_id>``.

    The transitions are split after every ``("next", "done")``; an episode is stored as its
    ``"observation"`` rows plus its last ``("next", "observation")`` (so each step's next
    observation must be the following step's observation, as in any recorded episode), its
    actions, dense rewards, and terminations and truncations as they are. Other entries
    (``"step_count"``, collector keys) are not stored; the loader rebuilds ``"step_count"``.
    Each episode's return goes into Minari's per-episode ``rewards_sum`` (the recorded
    ``episode_returns`` of a :class:`~torchrl_sail.Demonstrations`, else the sum of the
    rewards), the demonstrations' metadata into the dataset metadata under ``"torchrl_sail"``.
    Observations (the time feature column included, if any) and actions are stored as float32.

    The dataset is created by Minari's ``create_dataset_from_buffers`` in a hidden staging
    folder beside its destination and renamed into place, so a failure leaves nothing
    half-written (and an overwritten dataset intact); the namespace folders get Minari's
    ``namespace_metadata.json`` through ``minari.namespace.create_namespace``.

    Args:
        demonstrations: a :class:`~torchrl_sail.Demonstrations`, a flat ``[N]`` transition
            tensordict (whole episodes, dense rewards), or anything
            :func:`~torchrl_sail.load_demonstrations` reads (a ``.npz`` file, a
            :func:`~torchrl_sail.save_demonstrations` folder, ``"minari:<id>"``).
        dataset_id (str): ``(namespace/)name-v<version>``, e.g. ``"sail/Hopper-v4/teacher-v0"``.

    Keyword Args:
        env (str or gymnasium.envs.registration.EnvSpec, optional): the gymnasium env the
            demonstrations come from, stored as the dataset's env spec; its action space becomes
            the dataset's (checked against the actions' size, and the observation size must be the
            env's, or one more with the time feature). Defaults to the metadata's ``env_id`` (the
            shipped teachers have one), else none: then the action space is an unbounded ``Box``.
        root (str or path, optional): the datasets folder. Defaults to ``MINARI_DATASETS_PATH``,
            else ``~/.minari/datasets``.
        algorithm_name, author, author_email, code_permalink, description (str, optional):
            Minari's dataset metadata. ``description`` defaults to one naming the source.
        data_format (str): Minari's storage, ``"hdf5"`` (default, needs ``h5py``) or ``"arrow"``
            (needs ``pyarrow``).
        overwrite (bool): replace an existing dataset of that id. Defaults to ``False``.
        max_episode_steps (int): passed to :func:`~torchrl_sail.load_demonstrations` when
            ``demonstrations`` is a path. Defaults to ``1000``.

    Returns:
        Path: the dataset folder (it holds ``data/``).

    Raises:
        ImportError: ``minari`` is not installed.
        FileExistsError: the dataset exists and ``overwrite`` is ``False``.
        ValueError: a malformed ``dataset_id``, invalid transitions (the message names the key),
            an episode whose next observations are not its observations, one that does not start
            at ``step_count`` 0, recorded returns that are not the sums of the rewards, or an
            ``env`` whose sizes differ from the data's.

    Examples:
        >>> import tempfile, torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail import Demonstrations, export_minari_dataset, load_demonstrations
        >>> T, obs = 4, torch.randn(5, 12)  # one Hopper episode (time feature included), truncated
        >>> done = torch.arange(T)[:, None] == T - 1
        >>> td = TensorDict({"observation": obs[:-1], "action": torch.rand(T, 3) * 2 - 1,
        ...     ("next", "observation"): obs[1:], ("next", "reward"): torch.ones(T, 1),
        ...     ("next", "done"): done, ("next", "terminated"): torch.zeros_like(done),
        ...     ("next", "truncated"): done}, batch_size=[T])
        >>> root = tempfile.mkdtemp()
        >>> demos = Demonstrations(td, {"env_id": "Hopper-v4", "source": "toy.npz"})
        >>> path = export_minari_dataset(demos, "sail/Hopper-v4/toy-v0", root=root, author="me")
        >>> path.relative_to(root).as_posix(), sorted(p.name for p in (path / "data").iterdir())
        ('sail/Hopper-v4/toy-v0', ['main_data.hdf5', 'metadata.json'])
        >>> data, meta = load_demonstrations(path)  # a Minari dataset folder
        >>> meta["env_id"], meta["exported_from"], meta["episode_returns"], meta["author"]
        ('Hopper-v4', 'toy.npz', [4.0], ['me'])
        >>> try:
        ...     export_minari_dataset(demos, "sail/Hopper-v4/toy-v0", root=root)
        ... except FileExistsError as err:
        ...     print("overwrite=True" in str(err))
        True
    """
    minari = _import_minari()
    import gymnasium as gym

    namespace = _dataset_namespace(dataset_id)
    data, meta = _data_and_metadata(demonstrations, max_episode_steps)
    where = f"demonstrations to export as {dataset_id!r}"
    if "source" in meta:
        where += f" (from {meta['source']})"
    check_transitions(data, where)
    data = data.detach().cpu()
    obs, next_obs, action = data["observation"], data["next", "observation"], data["action"]
    if obs.ndim != 2 or action.ndim != 2:
        raise ValueError(
            f"{where}: 'observation' {tuple(obs.shape)} and 'action' {tuple(action.shape)} must be [N, dim] vectors."
        )
    ends = (data["next", "done"].reshape(-1).nonzero().reshape(-1) + 1).tolist()
    starts = [0, *ends[:-1]]
    lengths = [e - s for s, e in zip(starts, ends, strict=True)]
    _check_episode_sequences(obs, next_obs, data.get("step_count", None), starts, ends, where)
    reward = data["next", "reward"].reshape(-1).double().numpy()
    returns = _export_returns(meta.get("episode_returns"), reward, starts, lengths, where)

    obs_dim, act_dim = obs.shape[1], action.shape[1]
    env = meta.get("env_id") if env is None else env
    env_spec, action_space = _env_spec_and_action_space(env, obs_dim, act_dim, where)

    base = minari_datasets_root(root)
    target = base / dataset_id
    if target.exists() and not overwrite:
        raise FileExistsError(
            f"Minari dataset {dataset_id!r} already exists at {target}: pass overwrite=True "
            f"(--overwrite) to replace it, or choose another id or version."
        )

    ours = json.loads(
        json.dumps({k: v for k, v in meta.items() if k not in _RECOMPUTED}, default=json_default(f"{where}: metadata"))
    )
    if description is None:
        description = (
            f"SAIL demonstrations ({len(ends)} episodes, {len(reward)} transitions) exported by "
            f"torchrl_sail" + (f" from {meta['source']}" if "source" in meta else "")
        )
    buffers = _episode_buffers(data, reward, starts, ends)

    def create() -> Any:
        return minari.create_dataset_from_buffers(
            dataset_id,
            buffers,
            env=env_spec,
            observation_space=gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float32),
            action_space=action_space,
            algorithm_name=algorithm_name,
            author=_as_set(author),
            author_email=_as_set(author_email),
            code_permalink=code_permalink,
            description=description,
            data_format=data_format,
        )

    _publish_dataset(target, dataset_id, create, ({_METADATA_KEY: ours}, [{"rewards_sum": r} for r in returns]))
    if namespace is not None:
        _add_namespace(base, namespace)
    return target


def _dataset_namespace(dataset_id: str) -> str | None:
    """The namespace of ``dataset_id`` (``None`` if it has none), once it is ``(namespace/)name-v<version>``."""
    match = _DATASET_ID.fullmatch(dataset_id) if isinstance(dataset_id, str) else None
    if match is None:
        raise ValueError(
            f"dataset_id {dataset_id!r} is not (namespace/)name-v<version>, e.g. 'sail/Hopper-v4/teacher-v0'."
        )
    return match["namespace"]


def _data_and_metadata(
    demonstrations: Demonstrations | TensorDictBase | str | os.PathLike, max_episode_steps: int
) -> tuple[TensorDictBase, dict]:
    """``(data, metadata)`` of demonstrations, a transition tensordict (no metadata) or a path read
    with :func:`~torchrl_sail.data.episodes.read_demonstrations`."""
    if isinstance(demonstrations, (str, os.PathLike)):
        demonstrations = read_demonstrations(demonstrations, max_episode_steps=max_episode_steps)
    if isinstance(demonstrations, Demonstrations):
        return demonstrations.data, dict(demonstrations.metadata)
    if isinstance(demonstrations, TensorDictBase):
        return demonstrations, {}
    raise TypeError(f"expected Demonstrations, a TensorDict or a path, got {type(demonstrations)}.")


def _check_episode_sequences(
    obs: torch.Tensor,
    next_obs: torch.Tensor,
    step_count: torch.Tensor | None,
    starts: list[int],
    ends: list[int],
    where: str,
) -> None:
    """Checks that each episode (rows ``starts[i]:ends[i]``) is one observation sequence, each next
    observation the following observation, and starts at ``step_count`` 0 (if given): the only
    episodes a Minari episode can hold."""
    for i, (start, end) in enumerate(zip(starts, ends, strict=True)):
        same = (next_obs[start : end - 1] == obs[start + 1 : end]).all(-1)
        if not same.all():
            row = start + int((~same).nonzero()[0])
            raise ValueError(
                f"{where}: episode {i}: ('next', 'observation') of row {row} is not the "
                f"'observation' of row {row + 1}; a Minari episode is one observation sequence."
            )
        if step_count is not None and int(step_count[start].reshape(-1)[0]) != 0:
            raise ValueError(
                f"{where}: episode {i} starts at step_count={int(step_count[start].reshape(-1)[0])}, "
                f"not 0: a Minari episode starts at a reset (export whole episodes)."
            )


def _export_returns(
    recorded: list[float] | None, reward: np.ndarray, starts: list[int], lengths: list[int], where: str
) -> list[float]:
    """The episodes' returns: ``recorded`` (the metadata's ``episode_returns``) if it has one per
    episode, checked against the float64 rewards, else the sums of the rewards."""
    returns = np.add.reduceat(reward, starts).tolist()
    if recorded is not None and len(recorded) == len(lengths):
        check_returns(
            recorded, reward, lengths, where, hint="are the rewards delayed? Minari datasets store dense rewards"
        )
        returns = [float(r) for r in recorded]
    return returns


def _env_spec_and_action_space(env: Any, obs_dim: int, act_dim: int, where: str) -> tuple[Any, Any]:
    """The dataset's env spec (``None`` without ``env``) and action space (``env``'s, else an unbounded
    ``Box``), once ``env``'s sizes are checked against the data's.

    Args:
        env (str or gymnasium.envs.registration.EnvSpec, optional): the env id or spec.
        obs_dim (int): the observations' size: ``env``'s, or one more with the time feature.
        act_dim (int): the actions' size.
        where (str): the start of the error messages.

    Returns:
        ``(EnvSpec or None, gymnasium.spaces.Box)``.
    """
    import gymnasium as gym
    from gymnasium.envs.registration import EnvSpec

    action_space = gym.spaces.Box(-np.inf, np.inf, (act_dim,), np.float32)
    if env is None:
        return None, action_space
    try:
        env_spec = env if isinstance(env, EnvSpec) else gym.spec(env)
        with warnings.catch_warnings():  # e.g. "Hopper-v4 is out of date"
            warnings.simplefilter("ignore")
            made = gym.make(env_spec)
        spaces = made.observation_space, made.action_space
        made.close()
    except Exception as err:
        raise ValueError(f"{where}: cannot make the env {env!r}: {type(err).__name__}: {err}") from err
    if not (isinstance(spaces[1], gym.spaces.Box) and spaces[1].shape == (act_dim,)):
        raise ValueError(
            f"{where}: 'action' has {act_dim} dims but env {env_spec.id} has the action space "
            f"{spaces[1]}: the demonstrations were recorded on another env."
        )
    env_obs = spaces[0].shape
    if len(env_obs) != 1 or obs_dim not in (env_obs[0], env_obs[0] + 1):
        raise ValueError(
            f"{where}: 'observation' has {obs_dim} dims but env {env_spec.id} has the observation "
            f"space {spaces[0]} (its size, or one more with the time feature): the demonstrations "
            f"were recorded on another env."
        )
    return env_spec, gym.spaces.Box(spaces[1].low, spaces[1].high, (act_dim,), np.float32)


def _episode_buffers(data: TensorDictBase, reward: np.ndarray, starts: list[int], ends: list[int]) -> list:
    """One ``minari.data_collector.EpisodeBuffer`` per episode of ``data``: its observations plus its
    last next observation, its actions and ``reward`` (float32 all), its terminations and truncations."""
    from minari.data_collector import EpisodeBuffer  # the buffers create_dataset_from_buffers takes

    obs_np, next_np = data["observation"].float().numpy(), data["next", "observation"].float().numpy()
    act_np, rew_np = data["action"].float().numpy(), reward.astype(np.float32)
    term_np, trunc_np = (data["next", key].reshape(-1).numpy() for key in ("terminated", "truncated"))
    return [
        EpisodeBuffer(
            observations=np.concatenate([obs_np[s:e], next_np[e - 1 : e]]),
            actions=act_np[s:e],
            rewards=rew_np[s:e],
            terminations=term_np[s:e],
            truncations=trunc_np[s:e],
        )
        for s, e in zip(starts, ends, strict=True)
    ]


def _as_set(value: str | Iterable[str] | None) -> str | set[str] | None:
    """Minari's ``author``/``author_email``: a string, or a set of strings."""
    return value if value is None or isinstance(value, str) else set(value)


def _publish_dataset(target: Path, dataset_id: str, create: Callable[[], Any], update: tuple[dict, list[dict]]) -> None:
    """Writes the dataset ``create()`` makes, with ``update`` (see :func:`_storage_metadata`), to ``target``.

    ``create`` (a ``create_dataset_from_buffers`` call) writes ``<MINARI_DATASETS_PATH>/<dataset_id>``:
    it runs with a scratch root beside ``target``, whose dataset folder becomes the staging folder
    that :func:`~torchrl_sail.data.episodes.publish_directory` swaps in, so a failure leaves
    nothing half-written.
    """

    def write(staging: Path) -> None:
        scratch = staging.with_name(staging.name + ".root")
        try:
            with _datasets_path(scratch), warnings.catch_warnings():
                # Minari warns about every optional field left out (eval_env, author, ...) and
                # gymnasium that the -v4 envs are out of date
                warnings.simplefilter("ignore")
                created = create()
            _storage_metadata(created, update=update)
            os.replace(scratch / dataset_id, staging)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)

    publish_directory(target, write)


def _add_namespace(base: Path, namespace: str) -> None:
    """Gives ``namespace`` under the datasets folder ``base`` the ``namespace_metadata.json`` files of
    Minari's namespace API, unless it has them."""
    from minari.namespace import create_namespace, list_local_namespaces

    with _datasets_path(base):
        if namespace not in list_local_namespaces():
            create_namespace(namespace)


def _is_minari(path: str | os.PathLike) -> bool:
    return os.fspath(path).startswith(MINARI_PREFIX) or is_minari_dataset(path)


def _load_any_minari(
    path: str | os.PathLike, *, max_episode_steps: int = 1000, time_feature: bool | None = None
) -> Demonstrations:
    by_id = os.fspath(path).startswith(MINARI_PREFIX)  # also from a Path("minari:<id>")
    return load_minari_demonstrations(
        os.fspath(path) if by_id else path, max_episode_steps=max_episode_steps, time_feature=time_feature
    )


register_reader("a Minari dataset ('minari:<dataset id>' or its folder)", _is_minari, _load_any_minari)
