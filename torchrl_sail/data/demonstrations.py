"""Teacher demonstrations: one loader for every format, and the check against the env's sizes.

The formats live in their own modules, each importing only the core
(:mod:`torchrl_sail.data.episodes`): the paper's ``.npz`` files
(:mod:`torchrl_sail.data.npz`), the project's folders (:mod:`torchrl_sail.data.folder`) and
Minari datasets (:mod:`torchrl_sail.data.minari`). :func:`load_demonstrations` reads any of
them into the flat transition tensordict of the README's data conventions
(``"observation"``, ``"action"``, ``("next", ...)`` entries with
``done = terminated | truncated``), with the same checks (finite values, returns, flags) and
the same time-feature rule. Rewards stay *dense*: SAIL's delayed, trajectory-wise reward is
produced after loading by :class:`~torchrl_sail.DelayedRewardTransform` (offline mode).
"""

from __future__ import annotations

import os
from typing import Any

from tensordict import TensorDictBase
from tensordict.utils import NestedKey

from torchrl_sail.data import folder as _folder  # noqa: F401
from torchrl_sail.data import minari as _minari  # noqa: F401

# The format modules register their readers with the core when imported, in this order: the
# order of the formats in the error for a path that is none of them.
from torchrl_sail.data import npz as _npz  # noqa: F401
from torchrl_sail.data.episodes import Demonstrations, read_demonstrations
from torchrl_sail.data.folder import METADATA_FILE, save_demonstrations
from torchrl_sail.data.npz import load_sb_demonstrations

__all__ = [
    "Demonstrations",
    "METADATA_FILE",
    "check_demonstration_dims",
    "load_demonstrations",
    "load_sb_demonstrations",
    "save_demonstrations",
]


def load_demonstrations(
    path: str | os.PathLike,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool | None = None,
) -> Demonstrations:
    """Loads a stable-baselines ``.npz``, a :func:`save_demonstrations` directory, a Minari dataset.

    A ``.npz`` file goes to :func:`load_sb_demonstrations`; ``"minari:<dataset id>"`` or a
    Minari dataset folder to :func:`~torchrl_sail.load_minari_demonstrations` (it needs the
    optional ``minari`` package: ``pip install -e '.[minari]'``); a directory with
    ``metadata.json`` to :func:`~torchrl_sail.data.folder.load_demonstration_folder`, which
    reads it with :meth:`~tensordict.TensorDict.load_memmap` (pickled objects refused) into an
    ordinary in-memory tensordict. Every format is checked the same way: flat ``[N]``, the
    ``TRANSITION_KEYS`` of :mod:`torchrl_sail.data.keys`, bool ``[N, 1]`` flags with
    ``done == terminated | truncated``, a done last row (complete episodes only), finite values
    (a NaN or infinity is an error naming the file, the entry and the row), and recorded
    returns that are the sums of the rewards.

    Time feature, the same rule for every format: the last observation column is the
    remaining-time feature when it equals ``1 - t/T`` (``T = max_episode_steps``, ``t`` the
    in-episode step) on every row. ``time_feature=True`` asks for observations *with* it:
    kept if present, else computed from the episode steps and appended (so a teacher recorded on
    the plain env, e.g. a ``.npz`` whose observations are as wide as the env's, fits an env with
    :class:`~torchrl_sail.TimeFeature`). ``None`` detects it and changes nothing (a folder
    loads as saved: its metadata says whether it has the column); ``False`` never looks. A last
    column that is the time feature of another ``T`` is an error (pass that ``T`` as
    ``max_episode_steps``).

    Args:
        path: a ``.npz`` file, a directory written by :func:`save_demonstrations`, or a
            Minari dataset: ``"minari:<dataset id>"`` (looked up under
            ``MINARI_DATASETS_PATH``, default ``~/.minari/datasets``) or its folder.

    Keyword Args:
        max_episode_steps (int): the time limit ``T`` of the recording: longer episodes are
            refused (``.npz``, Minari), and the time feature is ``1 - t/T``. Defaults to ``1000``.
        time_feature (bool, optional): see above. Defaults to ``None``.

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
    return read_demonstrations(path, max_episode_steps=max_episode_steps, time_feature=time_feature)


# Observation-size changes of gymnasium.make kwargs of the MuJoCo tasks (gymnasium 1.x, measured
# with gym.make): (kwarg, the non-default value, observation dims it adds). Keyed by env id, or
# by the name before "-v" when every version agrees.
_SIZE_KWARGS: dict[str, tuple[tuple[str, Any, int], ...]] = {
    "Ant-v4": (("use_contact_forces", True, 84), ("exclude_current_positions_from_observation", False, 2)),
    "Ant-v5": (
        ("include_cfrc_ext_in_observation", False, -78),
        ("exclude_current_positions_from_observation", False, 2),
    ),
    "HalfCheetah": (("exclude_current_positions_from_observation", False, 1),),
    "Hopper": (("exclude_current_positions_from_observation", False, 1),),
    "Walker2d": (("exclude_current_positions_from_observation", False, 1),),
    "Swimmer": (("exclude_current_positions_from_observation", False, 2),),
    "Humanoid-v4": (("exclude_current_positions_from_observation", False, 2),),
    **{
        f"{name}-v5": (
            ("exclude_current_positions_from_observation", False, 2),
            ("include_cinert_in_observation", False, -130),
            ("include_cvel_in_observation", False, -78),
            ("include_qfrc_actuator_in_observation", False, -17),
            ("include_cfrc_ext_in_observation", False, -78),
        )
        for name in ("Humanoid", "HumanoidStandup")
    },
}


def _has_time_feature(env: Any) -> bool | None:
    """Whether a TorchRL env appends the time feature (a ``TimeFeature`` transform); ``None`` if unknown."""
    if env is None or not hasattr(env, "transform"):
        return None
    transform = env.transform
    transforms = list(transform.transforms) if hasattr(transform, "transforms") else [transform]
    # by class name: torchrl_sail.data does not import torchrl_sail.envs
    return any(cls.__name__ == "TimeFeature" for t in transforms for cls in type(t).__mro__)


def _env_id(env: Any) -> str | None:
    """The gymnasium id of a TorchRL env (``GymEnv.env_name``, also under transforms), if any."""
    for obj in (env, getattr(env, "base_env", None)):
        name = getattr(obj, "env_name", None)
        if isinstance(name, str):
            return name
    return None


def _kwarg_hints(env_name: str | None, extra_dims: int) -> list[str]:
    """The known env kwargs whose value would explain ``extra_dims`` more teacher dims."""
    if env_name is None:
        return []
    table = _SIZE_KWARGS.get(env_name) or _SIZE_KWARGS.get(env_name.split("-v")[0], ())
    hints = []
    for kwarg, value, dims in table:
        setting = f"env.kwargs.{kwarg}={str(value).lower()}"
        if dims == extra_dims:  # the teacher's env had the setting, this env does not
            hints.append(
                f"{env_name} made with {kwarg}={value} has {dims:+d} observation dims: the teacher was "
                f"probably recorded with it; make the env the same way (config key env.kwargs: {setting})"
            )
        elif dims == -extra_dims:  # this env has the setting, the teacher's did not
            hints.append(
                f"{env_name} made with {kwarg}={value} has {dims:+d} observation dims: the env probably "
                f"has it and the teacher did not; make the env without it (config key env.kwargs: "
                f"env.kwargs.{kwarg}={str(not value).lower()})"
            )
    return hints


def check_demonstration_dims(
    data: Demonstrations | TensorDictBase,
    *,
    observation_dim: int | None = None,
    action_dim: int | None = None,
    env: Any = None,
    observation_key: NestedKey = "observation",
    action_key: NestedKey = "action",
    source: str | os.PathLike | None = None,
    env_name: str | None = None,
) -> None:
    """Checks that demonstrations fit the env's observation and action sizes.

    The paper's teacher files have one more observation column than the plain MuJoCo env
    (the remaining-time feature), so the commonest mistake is a missing or extra
    :class:`~torchrl_sail.TimeFeature` (the error says which, knowing from a TorchRL ``env``
    whether it appends the feature). The next commonest is an env made
    with other ``gymnasium.make`` kwargs than the teacher's (the config key ``env.kwargs``):
    e.g. ``Ant-v4`` with ``use_contact_forces=True`` has 84 more observation dims, the MuJoCo
    tasks with ``exclude_current_positions_from_observation=False`` 1 or 2 more. When the
    difference is what such a kwarg of the env (``env_name``, or the id of a TorchRL ``env``)
    would make, the error names the kwarg and the ``env.kwargs`` setting; otherwise it
    mentions ``env.kwargs`` as a possible cause.

    Args:
        data: a :class:`Demonstrations` or a transition tensordict.

    Keyword Args:
        observation_dim (int, optional): the env's observation size (last dim).
        action_dim (int, optional): the env's action size.
        env (EnvBase, optional): a TorchRL env to read the sizes from
            (``env.observation_spec[observation_key]``, ``env.action_spec``) where they
            are not given, and its gymnasium id (``GymEnv.env_name``).
        observation_key (NestedKey): the observation entry. Defaults to ``"observation"``.
        action_key (NestedKey): the action entry. Defaults to ``"action"``.
        source (str or path, optional): named in errors; defaults to the ``source`` of a
            :class:`Demonstrations`.
        env_name (str, optional): the gymnasium id of the env, for the kwarg hints. Defaults to
            the id of ``env``.

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
        >>> ant = TensorDict({"observation": torch.zeros(5, 112), "action": torch.zeros(5, 8)}, [5])
        >>> try:  # recorded on Ant-v4 with use_contact_forces=True (111 dims + the time feature)
        ...     check_demonstration_dims(ant, observation_dim=28, env_name="Ant-v4")
        ... except ValueError as err:
        ...     print("env.kwargs.use_contact_forces=true" in str(err))
        True
    """
    if isinstance(data, Demonstrations):
        data, source = data.data, data.metadata.get("source") if source is None else source
    if env is not None:
        if observation_dim is None:
            observation_dim = int(env.observation_spec[observation_key].shape[-1])
        if action_dim is None:
            action_dim = int(env.action_spec.shape[-1])
        if env_name is None:
            env_name = _env_id(env)
    if observation_dim is None and action_dim is None:
        raise TypeError("check_demonstration_dims needs observation_dim/action_dim or env=.")
    name = f"teacher data ({source})" if source is not None else "teacher data"
    teacher_obs = data.get(observation_key).shape[-1] if observation_dim is not None else None
    if teacher_obs != observation_dim:
        extra = teacher_obs - observation_dim
        kwarg_hints = _kwarg_hints(env_name, extra)
        time_feature = _has_time_feature(env)  # None: unknown (no TorchRL env given)
        if extra == 1 and not time_feature:
            hint = "enable TimeFeature (the paper's teacher files end with the feature 1 - t/T)"
        elif extra == -1 and time_feature is not False:
            hint = (
                "disable TimeFeature (the env appends it; these demonstrations do not have it), or load "
                "them with time_feature=True, which appends it to them"
            )
        elif kwarg_hints:
            hint = "an env kwarg is the likely cause: " + "; or ".join(kwarg_hints)
            kwarg_hints = []
        else:
            hint = (
                "the demonstrations were probably recorded on a different env, or on this env made "
                "with other gymnasium.make kwargs (config key env.kwargs; e.g. Ant-v4 with "
                "use_contact_forces=True has 84 more observation dims)"
            )
        if kwarg_hints:  # a +-1 difference that a kwarg explains as well as the time feature
            hint += "; or, if the time feature is right, " + "; or ".join(kwarg_hints)
        raise ValueError(f"{name}: {observation_key!r} has {teacher_obs} dims, env has {observation_dim}: {hint}.")
    if action_dim is not None and data.get(action_key).shape[-1] != action_dim:
        raise ValueError(
            f"{name}: {action_key!r} has {data.get(action_key).shape[-1]} dims, env action has "
            f"{action_dim}: the demonstrations were recorded on a different env or action space."
        )
