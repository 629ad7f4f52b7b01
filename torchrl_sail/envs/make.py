"""The SAIL environment stack: a gymnasium task in the paper's delayed-reward setting.

One factory so that the training example, the teacher recorder, the evaluation env and
users' pipelines build exactly the same observation layout (with the time feature the
paper's teacher files carry) and the same trajectory-wise reward.
"""

from __future__ import annotations

import difflib
from functools import partial

import gymnasium as gym
import numpy as np
from tensordict.utils import NestedKey
from torchrl.envs import (
    ClipTransform,
    Compose,
    DoubleToFloat,
    GymEnv,
    GymWrapper,
    InitTracker,
    StepCounter,
    TransformedEnv,
    VecNormV2,
)
from torchrl.record.recorder import PixelRenderTransform

from torchrl_sail.envs.absorbing import AbsorbingStateTransform
from torchrl_sail.envs.delayed_reward import DelayedRewardTransform
from torchrl_sail.envs.time_feature import TimeFeature

__all__ = ["SEED_STRIDE", "make_sail_env", "observation_normalizer"]

#: A batched env's env ``i`` is seeded ``seed + i * SEED_STRIDE``: far apart, so that the envs of the
#: runs of neighbouring seeds (``seed + 1``, ...) do not replay each other's start states.
SEED_STRIDE = 1_000_003


class SpacedSeedsVectorEnv(gym.vector.SyncVectorEnv):
    """gymnasium's ``SyncVectorEnv`` whose ``reset(seed=s)`` seeds env ``i`` with
    ``s + i * SEED_STRIDE`` (gymnasium's own: ``s + i``)."""

    def reset(self, *, seed=None, options=None):
        if isinstance(seed, int):
            seed = [seed + i * SEED_STRIDE for i in range(self.num_envs)]
        return super().reset(seed=seed, options=options)


def _check_env_name(name: str) -> None:
    if name in gym.registry:
        return
    close = difflib.get_close_matches(name, list(gym.registry), n=3)
    hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
    raise ValueError(
        f"Unknown gymnasium env {name!r}.{hint} SAIL's MuJoCo tasks are e.g. "
        f"'Hopper-v4', 'Walker2d-v4', 'HalfCheetah-v4', 'Swimmer-v4' (and their -v5)."
    )


def make_sail_env(
    env_name: str,
    *,
    max_episode_steps: int = 1000,
    time_feature: bool = True,
    delayed_reward: bool = True,
    reward_scale: float = 0.1,
    rounding: str = "floor",
    absorbing_state: bool = False,
    render_size: tuple[int, int] | None = None,
    normalized_observation_key: NestedKey | None = None,
    env_kwargs: dict | None = None,
    render_camera: str | None = "track",
    device: str | None = None,
    num_envs: int = 1,
) -> TransformedEnv:
    """Builds ``GymEnv(env_name)`` with the SAIL transforms.

    The stack is ``DoubleToFloat -> StepCounter(max_episode_steps) -> InitTracker ->
    TimeFeature(max_episode_steps) -> DelayedRewardTransform``:

    - ``StepCounter`` truncates at ``max_episode_steps`` (the gymnasium ``TimeLimit`` of
      the MuJoCo tasks is also 1000) and provides the step count the time feature reads;
    - ``TimeFeature`` appends ``1 - t/T``, the column of the paper's teacher files;
    - ``DelayedRewardTransform`` replaces the dense reward by ``floor(0.1 * R)`` at the
      end of the episode and keeps the dense running return in ``"episode_return"`` for
      logging and evaluation.

    Args:
        env_name (str): a registered gymnasium id, e.g. ``"Hopper-v4"``.

    Keyword Args:
        max_episode_steps (int, optional): episode length ``T``. Defaults to ``1000``.
        time_feature (bool, optional): append the time feature. Defaults to ``True``.
        delayed_reward (bool, optional): the delayed-reward setting; ``False`` keeps the
            dense reward (used to train teachers). Defaults to ``True``.
        reward_scale (float, optional): ``scale`` of the delayed reward. Defaults to ``0.1``.
        rounding (str, optional): ``"floor"`` or ``"none"``. Defaults to ``"floor"``.
        absorbing_state (bool, optional): append DAC's absorbing-state indicator to the
            observation (:class:`~torchrl_sail.AbsorbingStateTransform`, last in the stack).
            Defaults to ``False``.
        render_size (tuple of int, optional): ``(width, height)``: render every reset and step
            offscreen into ``"pixels"`` (uint8 ``[H, W, 3]``) with TorchRL's
            ``PixelRenderTransform``, for videos. MuJoCo needs a GL backend (``MUJOCO_GL=egl``
            on machines without a display). Defaults to ``None`` (no rendering).
        normalized_observation_key (NestedKey, optional): also write a normalised copy of the
            observation under this key, for on-policy learners (PPO), as TorchRL's PPO MuJoCo
            example normalises: TorchRL's ``VecNormV2`` running statistics (``decay=0.99999``,
            ``eps=1e-2``, computed on the float64 gymnasium observation, first in the stack)
            then ``ClipTransform`` to ``[-10, 10]``. The time feature is appended to it raw,
            after the normalisation: it is already in ``[0, 1]``, and its running statistics
            would follow the episode lengths, which grow by orders of magnitude as a policy
            learns to survive (early short episodes give it a std near 0.01, so later long
            episodes would be normalised far into the clip). ``"observation"`` stays raw: it is
            what the demonstrations hold and what a discriminator compares them with. Find the
            normaliser with :func:`observation_normalizer`. Defaults to ``None`` (none).
        env_kwargs (dict, optional): keyword arguments of ``gymnasium.make``, e.g.
            ``{"use_contact_forces": True}`` for ``Ant-v4``. Defaults to ``None`` (none).
        render_camera (str, optional): with ``render_size``, the model camera to render from.
            ``"track"``, the default, follows the body in gymnasium's MuJoCo models (Hopper,
            Walker2d, HalfCheetah, Swimmer, Ant); a model without that camera falls back to
            gymnasium's free camera. ``None``: gymnasium's default view. Ignored for non-MuJoCo
            envs. Defaults to ``"track"``.
        device (str, optional): device of the env outputs. ``None`` makes a device-less env
            whose tensors are on the CPU, where gymnasium's arrays are converted: the cheapest
            per step, as TorchRL then moves neither the step's result nor, in a ``Collector``,
            the carried tensordict (about 0.3 ms of a 1.8 ms Hopper frame,
            ``benchmarks/bench_collect.py``). Defaults to ``None``.
        num_envs (int, optional): more than 1 makes a batched env (``batch_size=[num_envs]``) over
            gymnasium's ``SyncVectorEnv`` of that many envs, with the same transforms applied to the
            batch: TorchRL's per-step work is shared by the envs, which makes deterministic
            evaluation episodes several times cheaper per env step (``benchmarks/bench_eval.py``).
            ``set_seed(s)`` seeds env ``i`` with ``s + i * SEED_STRIDE``, so env ``i``'s episodes
            start where those of a single env seeded so do (env ``0``'s: ``s``'s). The vector env
            does not reset an env by itself (``AutoresetMode.DISABLED``): TorchRL resets the done
            ones (``step_and_maybe_reset``), as it does for its own batched envs. Not with
            ``render_size``. Defaults to ``1``.

    Raises:
        ValueError: for an unknown env name (with the closest registered names),
            ``env_kwargs`` that ``gymnasium.make`` rejects (naming them), or ``num_envs`` below 1
            or above 1 with ``render_size``.

    Examples:
        >>> from torchrl_sail.envs import make_sail_env, observation_normalizer
        >>> env = make_sail_env("Hopper-v4")
        >>> td = env.rollout(3)
        >>> td["observation"].shape, td["observation"][:, -1].tolist()
        (torch.Size([3, 12]), [1.0, 0.9990000128746033, 0.9980000257492065])
        >>> env = make_sail_env("Hopper-v4", normalized_observation_key="observation_norm")
        >>> td = env.rollout(3)
        >>> td["observation_norm"].shape, td["observation_norm"][:, -1].tolist()  # the time feature, raw
        (torch.Size([3, 12]), [1.0, 0.9990000128746033, 0.9980000257492065])
        >>> observation_normalizer(env).frozen  # updated by every reset and step
        False
        >>> batch = make_sail_env("Hopper-v4", num_envs=3)
        >>> _ = batch.set_seed(0)  # env i from seed 0 + i * SEED_STRIDE
        >>> batch.rollout(2)["observation"].shape
        torch.Size([3, 2, 12])
    """
    _check_env_name(env_name)
    if num_envs < 1 or (num_envs > 1 and render_size is not None):
        raise ValueError(f"num_envs={num_envs}: must be 1 or more, and 1 with render_size={render_size}")
    transforms = [DoubleToFloat(), StepCounter(max_steps=max_episode_steps), InitTracker()]
    observation_keys = ["observation"]
    if normalized_observation_key is not None:
        observation_keys.append(normalized_observation_key)
        transforms[:0] = [
            VecNormV2(in_keys=["observation"], out_keys=[normalized_observation_key], decay=0.99999, eps=1e-2),
            ClipTransform(in_keys=[normalized_observation_key], low=-10.0, high=10.0),
        ]
    if time_feature:
        transforms.append(TimeFeature(max_steps=max_episode_steps, in_keys=observation_keys))
    if delayed_reward:
        transforms.append(DelayedRewardTransform(reward_scale, rounding=rounding))
    if absorbing_state:
        transforms.append(AbsorbingStateTransform())
    kwargs = dict(env_kwargs or {})
    if render_size is not None:
        width, height = render_size
        kwargs.update(render_mode="rgb_array", width=width, height=height)
        if render_camera is not None and "mujoco" in str(gym.spec(env_name).entry_point):
            kwargs["camera_name"] = render_camera
        # MuJoCo returns a vertically flipped view (negative strides): copy it into a plain array
        transforms.append(PixelRenderTransform(out_keys=["pixels"], preproc=np.ascontiguousarray))
    try:
        if num_envs == 1:
            base = GymEnv(env_name, device=device, **kwargs)
        else:
            vector = SpacedSeedsVectorEnv(
                [partial(gym.make, env_name, **kwargs)] * num_envs, autoreset_mode=gym.vector.AutoresetMode.DISABLED
            )
            base = GymWrapper(vector, device=device)
    except TypeError as err:  # gymnasium.make passes unknown kwargs on to the env's __init__
        raise ValueError(f"gymnasium.make({env_name!r}) rejects env_kwargs={dict(env_kwargs or {})}: {err}") from err
    return TransformedEnv(base, Compose(*transforms))


def observation_normalizer(env: TransformedEnv) -> VecNormV2 | None:
    """The ``VecNormV2`` of an env made with ``make_sail_env(normalized_observation_key=...)``.

    Its statistics are what a policy trained on the normalised observations needs at
    evaluation: save them with the policy (``state_dict()``), load them into the evaluation
    env's normaliser and ``freeze()`` it there. Load a copy: ``VecNormV2.load_state_dict``
    keeps the given tensors, which the training env goes on updating in place.

    Args:
        env (TransformedEnv): an env made by :func:`make_sail_env`.

    Returns:
        the normaliser, or ``None`` when the env has none.

    Examples:
        >>> import copy
        >>> from torchrl_sail import make_sail_env, observation_normalizer
        >>> train = make_sail_env("Hopper-v4", normalized_observation_key="observation_norm")
        >>> _ = train.rollout(5)
        >>> evaluation = make_sail_env("Hopper-v4", normalized_observation_key="observation_norm")
        >>> statistics = copy.deepcopy(observation_normalizer(train).state_dict())
        >>> observation_normalizer(evaluation).load_state_dict(statistics)
        <All keys matched successfully>
        >>> frozen = observation_normalizer(evaluation).freeze()
        >>> before = frozen.loc["observation"].clone()
        >>> _ = evaluation.rollout(5)
        >>> bool((frozen.loc["observation"] == before).all())
        True
        >>> observation_normalizer(make_sail_env("Hopper-v4")) is None
        True
    """
    found = [t for t in env.transform if isinstance(t, VecNormV2)] if isinstance(env.transform, Compose) else []
    return found[0] if found else None
