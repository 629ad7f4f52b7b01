"""A random-network-distillation bonus that can also be computed at sample time.

SAIL's curiosity variant (the paper's Table 1) adds a random network distillation bonus
(Burda et al. 2019) to the discriminator reward. TorchRL's
:class:`~torchrl.envs.transforms.RNDTransform` computes the bonus inside an env, at collection;
an off-policy learner replays a transition long after, when the predictor has learned it, so
the bonus must be recomputed at sample time as the discriminator reward is.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.utils import NestedKey, unravel_key
from torch import nn
from torchrl.envs.transforms import RNDTransform

from torchrl_sail.envs._rows import distinct_rows

__all__ = ["RNDReward"]


class RNDReward(RNDTransform):
    """:class:`~torchrl.envs.transforms.RNDTransform` with a replay-buffer path that adds the bonus to a reward.

    **Environment** (inherited): at every step, the running observation and bonus statistics
    are updated (in training mode) and the bonus of ``("next", in_key)`` is written to
    ``out_key`` (``"intrinsic_reward"``). Keep it in the env that collects the agent's data:
    the statistics follow what the agent visits.

    .. note:: ``TransformedEnv(env, rnd)`` and ``env.append_transform(rnd)`` leave the transform
        in eval mode, where the statistics are not updated: call ``rnd.train()`` afterwards.

    **Replay buffer** (:meth:`forward`): the bonus of the *current* predictor on the sampled
    ``("next", in_key)``, normalised with the statistics as they are (never updated here),
    times ``coef``, is added to ``("next", reward_key)``. With
    :class:`~torchrl_sail.DiscriminatorReward` first, the TD target reads ``-log(1 - D) + coef *
    bonus``. Train the predictor with :class:`~torchrl.objectives.RNDLoss`, sharing the networks
    and ``obs_rms`` (available after the first env step).

    Args:
        target_network (nn.Module): the frozen random network.
        predictor_network (nn.Module): the trained network.

    Keyword Args:
        coef (float, optional): the bonus weight on the buffer path. Defaults to ``1.0``.
        reward_key (NestedKey, optional): the reward the buffer path adds to, under ``"next"``.
            Defaults to ``"reward"``.
        chunk_size (int, optional): the buffer path evaluates this many rows at a time (a block
            of batches holds a quarter of a million). Defaults to ``4096``.
        row_id_key (NestedKey, optional): buffer path: when the input holds this entry (e.g.
            written by ``MixedReplayBuffer(row_id_key=...)``), the networks run once per
            distinct id; rows with equal ids must hold equal next observations. Defaults to
            ``None`` (every row evaluated).
        **kwargs: :class:`~torchrl.envs.transforms.RNDTransform`'s ``in_keys``, ``out_keys``,
            ``normalize_obs``, ``normalize_reward``, ``obs_clip``, ``reward_clip``.

    Examples:
        >>> import torch
        >>> from torch import nn
        >>> from tensordict import TensorDict
        >>> from torchrl.envs import GymEnv, TransformedEnv
        >>> from torchrl_sail import RNDReward
        >>> rnd = RNDReward(nn.Linear(3, 8), nn.Linear(3, 8), coef=0.5)
        >>> env = TransformedEnv(GymEnv("Pendulum-v1"), rnd)
        >>> _ = rnd.train()  # the env keeps the running statistics from here on
        >>> rollout = env.rollout(5)
        >>> batch = rollout.select("observation", ("next", "observation"), ("next", "reward")).clone()
        >>> out = rnd(batch.clone())  # sample time: reward + 0.5 * bonus of the current predictor
        >>> bool((out["next", "reward"] > batch["next", "reward"]).all())
        True
    """

    def __init__(
        self,
        target_network: nn.Module,
        predictor_network: nn.Module,
        *,
        coef: float = 1.0,
        reward_key: NestedKey = "reward",
        chunk_size: int = 4096,
        row_id_key: NestedKey | None = None,
        **kwargs,
    ) -> None:
        if chunk_size < 1:
            raise ValueError(f"chunk_size must be >= 1, got {chunk_size}.")
        super().__init__(target_network, predictor_network, **kwargs)
        self.coef = coef
        self.reward_key = reward_key
        self.chunk_size = chunk_size
        self.row_id_key = row_id_key

    @torch.no_grad()
    def bonus(self, obs: torch.Tensor) -> torch.Tensor:
        """The normalised bonus ``[*, 1]`` of observations ``[*, dim]``, statistics untouched."""
        lead = obs.shape[:-1]
        obs = obs.reshape(-1, obs.shape[-1]).float()
        out = torch.empty(obs.shape[0], 1, device=obs.device)
        for start in range(0, obs.shape[0], self.chunk_size):
            x = obs[start : start + self.chunk_size]
            if self.obs_rms is not None:
                x = self.obs_rms.normalize(x).clamp(-self.obs_clip, self.obs_clip)
            error = (self.predictor_network(x) - self.target_network(x)).pow(2).mean(dim=-1, keepdim=True)
            if self.reward_rms is not None:
                error = (error / self.reward_rms.var.clamp_min(1e-8).sqrt()).clamp(-self.reward_clip, self.reward_clip)
            out[start : start + self.chunk_size] = error
        return out.reshape(*lead, 1)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Adds ``coef * bonus(("next", in_key))`` to ``("next", reward_key)`` (replay-buffer path).

        Args:
            tensordict (TensorDictBase): transitions with ``("next", in_key)`` and the reward.
        """
        key = unravel_key(("next", self.reward_key))
        obs = tensordict.get(unravel_key(("next", self.in_keys[0])))
        ids = None if self.row_id_key is None else tensordict.get(self.row_id_key, None)
        rows = None if ids is None else distinct_rows(ids)
        if rows is None:
            bonus = self.bonus(obs)
        else:
            first, inverse = rows
            bonus = self.bonus(obs.reshape(-1, obs.shape[-1])[first])[inverse].reshape(*obs.shape[:-1], 1)
        tensordict.set(key, tensordict.get(key) + self.coef * bonus.to(tensordict.get(key).dtype))
        return tensordict
