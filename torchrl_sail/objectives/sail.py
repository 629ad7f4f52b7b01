"""SAIL's actor-critic objective: TD3 on a batch that mixes teacher and agent transitions.

SAIL trains a TD3 critic and actor on transitions from the teacher buffer and from the
agent's replay, mixed with a teacher share ``alpha`` (``d_mix = alpha d_T +
(1 - alpha) d_B``). ``alpha`` can take effect in two ways, and exactly one is used:

- through the batch composition (the authors' code): the batch holds ``round(alpha * B)``
  teacher rows and the loss is TD3's plain mean;
- through per-row weights (Algorithm 1's form, ``N`` agent + ``N`` teacher rows):

.. math::

    J(Q) = \\frac{1-\\alpha}{N_{agent}} \\sum_{agent} (Q - y)^2
         + \\frac{\\alpha}{N_{teacher}} \\sum_{teacher} (Q - y')^2

  and the same weighting of the actor objective ``-Q_1(s, \\pi(s))``.

Everything TD3 (twin critics, target policy smoothing, clipped double-Q, delayed targets)
is inherited from :class:`~torchrl.objectives.TD3Loss`; the weights enter through the hook
that ``TD3Loss`` already reads for prioritized-replay weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential, dispatch
from tensordict.utils import NestedKey
from torchrl.data.tensor_specs import TensorSpec
from torchrl.modules import TanhModule
from torchrl.objectives import TD3Loss

__all__ = ["SAILLoss"]


class SAILLoss(TD3Loss):
    """TD3 loss with SAIL's teacher share ``alpha``.

    ``alpha`` is a schedulable buffer (``loss.alpha = 0.0`` updates it in place, as
    :class:`~torchrl_sail.AlphaScheduler` does), saved with ``loss.state_dict()``: the one
    place the current share is kept. ``mixing`` says where it takes effect:

    - ``"batch"`` (default, the authors' code): the caller samples ``round(alpha * B)``
      teacher rows, e.g. ``MixedReplayBuffer.sample(B, teacher_fraction=float(loss.alpha))``,
      and the loss is exactly :class:`~torchrl.objectives.TD3Loss` on that batch (no tag is
      read, no weight applied).
    - ``"weights"`` (Algorithm 1): the batch holds teacher and agent rows in any proportion
      (``N + N`` in the paper), tagged by the bool entry ``"is_teacher"``, and each group is
      averaged on its own: teacher rows weigh ``alpha / N_teacher``, agent rows
      ``(1 - alpha) / N_agent``. With valid rows in both groups the weights average 1, so
      ``reduction="sum"`` is ``B`` times the objective and ``"none"`` returns weighted
      per-row terms. A group with no (valid) row contributes nothing. Prioritized-replay
      weights, when present, are normalised within each group; rows removed by the loss
      mask (``loss_mask_key``) leave the counts.

    The TD targets use ``("next", "reward")`` for both groups; in SAIL this is the
    discriminator reward written at sample time by :class:`~torchrl_sail.DiscriminatorReward`.

    Args:
        actor_network (TensorDictModule): the deterministic policy.
        qvalue_network (TensorDictModule or list of TensorDictModule): the Q-value network
            (``"observation"``, ``"action"`` -> ``"state_action_value"``), duplicated
            ``num_qvalue_nets`` times as in :class:`~torchrl.objectives.TD3Loss`.

    Keyword Args:
        alpha (float, optional): the teacher share, in ``[0, 1]``. Defaults to ``0.5``.
        mixing (str, optional): ``"batch"`` or ``"weights"``, see above. Defaults to
            ``"batch"``.
        loss_function (str, optional): ``"l2"``, ``"l1"`` or ``"smooth_l1"``. Defaults to
            ``"l2"`` (the authors' MSE; ``TD3Loss`` defaults to ``"smooth_l1"``).
        preactivation_coef (float, optional): adds ``preactivation_coef * sum_j x_j^2`` to the
            actor objective, ``x`` the actor's pre-tanh output (the ``in_key`` of its final
            :class:`~torchrl.modules.TanhModule`), reduced over rows as ``-Q`` is (rlkit's
            ``policy_pre_activation_weight``). It keeps the tanh out of saturation, where the
            actor's gradient ``dQ/da (1 - tanh(x)^2)`` vanishes and the actor stops moving.
            ``> 0`` needs a ``TensorDictSequential`` actor with a ``TanhModule`` that writes
            the action under another key than its input. Set at construction. Defaults to
            ``0.0`` (TD3's objective).
        weight_normalization (str, optional): what ``reduction="mean"`` divides the weighted
            sum ``sum_i w_i l_i`` by when the batch carries prioritized-replay weights ``w``
            (``tensor_keys.priority_weight``): ``"sum"`` (TorchRL's losses), their sum
            ``sum_i w_i``, a weighted mean on which scaling every weight has no effect;
            ``"count"`` (prioritized replay as Schaul et al. 2016 and DDPGfD's public code
            step), the number of rows, ``mean_i(w_i l_i)``, so weights normalised to at most 1
            also shrink the step by their batch mean. Either way ``"sum"`` and ``"none"``
            reductions are unchanged, and with ``mixing="weights"`` on a batch with rows of both
            groups (whose weights then average 1), the two agree. Defaults to ``"sum"``.
        **kwargs: the other :class:`~torchrl.objectives.TD3Loss` keyword arguments
            (``action_spec`` or ``bounds``, ``num_qvalue_nets``, ``policy_noise``,
            ``noise_clip``, ``delay_actor``, ``delay_qvalue``, ``separate_losses``,
            ``reduction``, ``deactivate_vmap``, ``use_prioritized_weights``).

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from tensordict.nn import TensorDictModule, TensorDictSequential
        >>> from torchrl.data import Bounded
        >>> from torchrl.modules import MLP, TanhModule, ValueOperator
        >>> from torchrl.objectives import SoftUpdate
        >>> from torchrl_sail import SAILLoss
        >>> _ = torch.manual_seed(0)
        >>> obs_dim, act_dim, B = 3, 2, 6
        >>> spec = Bounded(-torch.ones(act_dim), torch.ones(act_dim), (act_dim,))
        >>> actor = TensorDictSequential(
        ...     TensorDictModule(
        ...         MLP(in_features=obs_dim, out_features=act_dim, num_cells=[16]),
        ...         ["observation"], ["param"]),
        ...     TanhModule(["param"], ["action"], spec=spec))
        >>> critic = ValueOperator(
        ...     MLP(in_features=obs_dim + act_dim, out_features=1, num_cells=[16]),
        ...     in_keys=["action", "observation"])
        >>> loss = SAILLoss(actor, critic, action_spec=spec, alpha=0.5, mixing="weights")
        >>> loss.make_value_estimator(gamma=0.99)
        >>> updater = SoftUpdate(loss, tau=0.005)
        >>> batch = TensorDict({
        ...     "observation": torch.randn(B, obs_dim),
        ...     "action": spec.rand((B,)),
        ...     "is_teacher": torch.tensor([True, True, False, False, False, False]),
        ...     ("next", "observation"): torch.randn(B, obs_dim),
        ...     ("next", "reward"): torch.randn(B, 1),
        ...     ("next", "done"): torch.zeros(B, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(B, 1, dtype=torch.bool),
        ... }, [B])
        >>> out = loss(batch)
        >>> out["loss_qvalue"].shape, float(out["alpha"])
        (torch.Size([]), 0.5)
        >>> loss.alpha = 0.0  # e.g. after the first promoted trajectory
        >>> float(loss(batch)["alpha"])
        0.0

        The pre-tanh penalty adds its term to ``loss_actor`` and reports it on its own:

        >>> penalised = SAILLoss(actor, critic, action_spec=spec, preactivation_coef=1e-3)
        >>> out = penalised(batch)
        >>> bool(out["preactivation_penalty"] > 0)
        True
    """

    @dataclass
    class _AcceptedKeys(TD3Loss._AcceptedKeys):
        """Maintains default values for all configurable tensordict keys.

        This class defines which tensordict keys can be set using
        ``.set_keys(key_name=key_value)`` and their default values.

        Attributes:
            action (NestedKey): The input tensordict key where the action is expected.
                Defaults to ``"action"``.
            state_action_value (NestedKey): The key the Q-networks write to.
                Defaults to ``"state_action_value"``.
            priority (NestedKey): The input tensordict key where the target priority is
                written to. Defaults to ``"td_error"``.
            reward (NestedKey): The reward key (read under ``"next"``).
                Defaults to ``"reward"``.
            done (NestedKey): The done key (read under ``"next"``). Defaults to ``"done"``.
            terminated (NestedKey): The terminated key (read under ``"next"``); TD targets
                bootstrap unless terminated. Defaults to ``"terminated"``.
            priority_weight (NestedKey): Prioritized-replay importance weights.
                Defaults to ``"priority_weight"``.
            is_teacher (NestedKey): Bool tag of the batch shape, ``True`` on teacher rows
                (written by :class:`~torchrl_sail.MixedReplayBuffer`); read with
                ``mixing="weights"``. Defaults to ``"is_teacher"``.
        """

        is_teacher: NestedKey = "is_teacher"

    tensor_keys: _AcceptedKeys
    default_keys = _AcceptedKeys
    _schedulable_buffers = frozenset({"alpha"})
    # Spelled out: TensorDictModuleBase turns TD3Loss.out_keys into a property at the first
    # TD3Loss instantiation, so reading it here would depend on import order.
    out_keys = [
        "loss_actor",
        "loss_qvalue",
        "pred_value",
        "state_action_value_actor",
        "next_state_value",
        "target_value",
        "alpha",
    ]

    alpha: torch.Tensor

    def __init__(
        self,
        actor_network: TensorDictModule,
        qvalue_network: TensorDictModule | list[TensorDictModule],
        *,
        alpha: float = 0.5,
        mixing: Literal["batch", "weights"] = "batch",
        action_spec: TensorSpec | None = None,
        loss_function: str = "l2",
        preactivation_coef: float = 0.0,
        weight_normalization: Literal["sum", "count"] = "sum",
        **kwargs,
    ) -> None:
        if weight_normalization not in ("sum", "count"):
            raise ValueError(f"weight_normalization must be 'sum' or 'count', got {weight_normalization!r}.")
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f"alpha must be in [0, 1] (the teacher share), got {alpha}.")
        if mixing not in ("batch", "weights"):
            raise ValueError(f"mixing must be 'batch' or 'weights', got {mixing!r}.")
        if not (
            isinstance(preactivation_coef, (int, float))
            and not isinstance(preactivation_coef, bool)
            and 0.0 <= preactivation_coef < math.inf
        ):
            raise ValueError(f"preactivation_coef must be a finite number >= 0, got {preactivation_coef!r}.")
        self.preactivation_key = None
        if preactivation_coef > 0:
            modules = actor_network.module if isinstance(actor_network, TensorDictSequential) else ()
            tanh = [module for module in modules if isinstance(module, TanhModule)]
            if not tanh:
                raise ValueError(
                    "preactivation_coef > 0 penalises the pre-tanh output of the actor's TanhModule; "
                    f"this actor is a {type(actor_network).__name__} without one."
                )
            if tanh[-1].in_keys[0] in tanh[-1].out_keys:
                raise ValueError(
                    f"preactivation_coef > 0 reads the pre-tanh output at the TanhModule's in_key "
                    f"{tanh[-1].in_keys[0]!r}, which the module overwrites with the action: give it another out_key."
                )
            self.preactivation_key = tanh[-1].in_keys[0]
        self.preactivation_coef = float(preactivation_coef)
        self.mixing = mixing
        self.weight_normalization = weight_normalization
        super().__init__(
            actor_network,
            qvalue_network,
            action_spec=action_spec,
            loss_function=loss_function,
            **kwargs,
        )
        # float dtype: an int alpha (0 or 1) would make an int buffer that in-place
        # scheduling to 0.5 would truncate
        self.register_coeff_buffer("alpha", alpha, device=self.max_action.device, dtype=torch.get_default_dtype())
        if self.preactivation_coef:
            self.out_keys = [*self.out_keys, "preactivation_penalty"]

    # TD3Loss's private hooks overridden or called here: listed in torchrl_sail._compat.SUBCLASS_HOOKS
    def _set_in_keys(self):
        super()._set_in_keys()
        if self.mixing == "weights":
            self._in_keys = [*self._in_keys, self.tensor_keys.is_teacher]

    def _groups(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor]:
        """Valid teacher rows and valid agent rows (bool, batch shape)."""
        tag = tensordict[self.tensor_keys.is_teacher].reshape(tensordict.batch_size)
        valid = torch.ones_like(tag)
        for mask_key in self._loss_mask_keys():
            mask = tensordict.get(mask_key, default=None)
            if mask is not None:
                valid = valid & self._expand_loss_mask(mask.bool(), valid)
        return tag & valid, ~tag & valid

    def _maybe_get_priority_weight(self, tensordict: TensorDictBase) -> torch.Tensor | None:
        # TD3Loss reads this in actor_loss and value_loss and reduces with
        # (loss * w).sum() / w.sum(). No host sync: the counts stay tensors.
        prb_weights = super()._maybe_get_priority_weight(tensordict)
        if self.mixing == "batch":
            return prb_weights
        teacher, agent = self._groups(tensordict)
        dtype = self.alpha.dtype
        base = (teacher | agent).to(dtype)
        if prb_weights is not None:
            base = base * self._expand_loss_mask(prb_weights, teacher).to(dtype)
        # per-group normalisation keeps each group's total share exactly alpha / 1 - alpha
        tiny = torch.finfo(dtype).tiny
        teacher_share = self.alpha / (base * teacher).sum().clamp_min(tiny)
        agent_share = (1.0 - self.alpha) / (base * agent).sum().clamp_min(tiny)
        weights = base * torch.where(teacher, teacher_share, agent_share)
        # average weight 1 instead of sum 1: same "mean", and "sum"/"none" keep TD3's scale
        return weights * (teacher | agent).sum()

    def _reduce_loss(
        self,
        loss: torch.Tensor,
        tensordict: TensorDictBase | None = None,
        *,
        mask: torch.Tensor | None = None,
        reduction: str | None = None,
        weights: torch.Tensor | None = None,
    ) -> torch.Tensor:
        if weights is not None and self.weight_normalization == "count":
            # the weights enter the per-row terms, so "mean" divides by the (valid) rows, not by the weights' sum
            loss, weights = loss * self._expand_loss_mask(weights, loss), None
        return super()._reduce_loss(loss, tensordict, mask=mask, reduction=reduction, weights=weights)

    def actor_loss(self, tensordict: TensorDictBase) -> tuple[torch.Tensor, dict]:
        """TD3's actor loss, plus ``preactivation_coef`` times the pre-tanh penalty when it is > 0.

        The metadata then holds ``preactivation_penalty``, the penalty before the coefficient.
        """
        loss_actor, metadata = super().actor_loss(tensordict)
        if not self.preactivation_coef:
            return loss_actor, metadata
        # a second actor forward (TD3Loss.actor_loss keeps no intermediate output); the fused
        # TD3Update step shares one
        actor_in = tensordict.select(*self.actor_network.in_keys, strict=False)
        with self.actor_network_params.to_module(self.actor_network, preserve_module_state=False):
            x = self.actor_network(actor_in).get(self.preactivation_key)
        penalty = self._reduce_loss(
            x.pow(2).sum(-1), tensordict=tensordict, weights=self._maybe_get_priority_weight(tensordict)
        )
        metadata["preactivation_penalty"] = penalty.detach()
        return loss_actor + self.preactivation_coef * penalty, metadata

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """TD3Loss's losses and metadata, plus ``alpha``; also writes ``td_error`` in place.

        With ``mixing="weights"`` it adds the mean predicted Q over the teacher rows
        (``pred_value_teacher``) and over the agent rows (``pred_value_agent``), NaN for a
        group with no row.
        """
        td_out = super().forward(tensordict)
        # clone: schedulers update the buffer in place, a logged view would change
        td_out.set("alpha", self.alpha.detach().clone())
        if self.mixing == "weights":
            pred = td_out.get("pred_value").mean(0)
            for name, rows in zip(("teacher", "agent"), self._groups(tensordict), strict=True):
                td_out.set(f"pred_value_{name}", (pred * rows).sum() / rows.sum())
        return td_out
