"""SAIL's actor-critic objective: TD3 on a teacher/self mixed batch, weighted by ``alpha``.

Algorithm 1 of the SAIL paper trains a TD3 critic and actor on ``N`` self-generated
transitions and ``N`` teacher transitions, and mixes the two halves with a coefficient
``alpha`` (the teacher share of the sampling distribution ``d_mix = alpha d_T +
(1 - alpha) d_B``):

.. math::

    J(Q) = \\frac{1-\\alpha}{N_{self}} \\sum_{self} (Q - y)^2
         + \\frac{\\alpha}{N_{teacher}} \\sum_{teacher} (Q - y')^2

and the same weighting for the actor objective ``-Q_1(s, \\pi(s))``. In the authors'
code the mixing is done by the batch composition alone (128 teacher + 128 self rows,
plain mean), which is the ``alpha = 0.5`` special case of this objective.

Everything TD3 (twin critics, target policy smoothing, clipped double-Q, delayed targets)
is inherited from :class:`~torchrl.objectives.TD3Loss` unchanged. The only hook used is
the per-row weight that ``TD3Loss.actor_loss`` / ``value_loss`` already read through
``_maybe_get_priority_weight`` and hand to ``_reduce_loss(..., weights=w)``, which computes
``(loss * w).sum() / w.sum()``: returning the mixing weights there turns TD3's mean into the
SAIL objective without touching the TD3 math.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import dispatch, TensorDictModule
from tensordict.utils import NestedKey

from torchrl.data.tensor_specs import TensorSpec
from torchrl.objectives import TD3Loss

__all__ = ["SAILLoss"]


def _check_alpha(value, *, where: str) -> float:
    """Validate a mixing coefficient and return it as a Python float."""
    if isinstance(value, torch.Tensor):
        if value.numel() != 1:
            raise ValueError(
                f"{where}: alpha must be a scalar, got a tensor of shape "
                f"{tuple(value.shape)}."
            )
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(
            f"{where}: alpha must be a float in [0, 1], got {value!r} "
            f"({type(value).__name__})."
        )
    value = float(value)
    if not 0.0 <= value <= 1.0:  # also rejects NaN
        raise ValueError(
            f"{where}: alpha must be in [0, 1] (the teacher share of the batch), "
            f"got {value}."
        )
    return value


class SAILLoss(TD3Loss):
    """TD3 loss on a teacher/self mixed batch, with SAIL's ``alpha`` weighting.

    Each batch row is tagged by the boolean entry ``"is_teacher"`` (shape = batch shape,
    written by :class:`~torchrl_sail.MixedReplayBuffer`). With ``N_teacher`` valid teacher
    rows and ``N_self`` valid self rows in the batch, the critic loss (per Q-net, summed
    over the twin nets as in :class:`~torchrl.objectives.TD3Loss`) is

    ``(1 - alpha) / N_self * sum_self (Q - y)^2 + alpha / N_teacher * sum_teacher (Q - y')^2``

    and the actor loss is ``-((1 - alpha) / N_self * sum_self Q1(s, pi(s))
    + alpha / N_teacher * sum_teacher Q1(s, pi(s)))``.
    The split is exact for every batch (whatever rows the batch holds), not a stochastic
    mixture. The TD targets ``y`` use whatever reward is stored in ``("next", "reward")``
    for both halves; in SAIL this is the discriminator reward written at sample time by
    :class:`~torchrl_sail.DiscriminatorReward`.

    Implementation: the mixing enters as per-row weights ``w`` through the hook that
    ``TD3Loss`` already uses for prioritized-replay weights, and TD3 reduces with
    ``(loss * w).sum() / w.sum()``. The weights are scaled to average 1 over the valid
    rows (teacher rows ``B * alpha / N_teacher``, self rows ``B * (1 - alpha) / N_self``,
    ``B = N_teacher + N_self``), so the ``"mean"`` reduction is exactly the objective above,
    ``"sum"`` is ``B`` times it (TD3's convention), ``"none"`` returns the weighted per-row
    terms, and a batch with ``alpha = N_teacher / B`` (the authors' 128 + 128 with
    ``alpha = 0.5``) gets all weights 1, i.e. the plain :class:`~torchrl.objectives.TD3Loss`.

    If prioritized-replay weights (``"priority_weight"``) are present and
    ``use_prioritized_weights`` allows them, they are kept as a separate entry and
    multiplied in *within* each group (self-normalised per group), so the teacher group
    keeps its total share ``alpha`` exactly. Masks found by ``loss_mask_key`` (e.g.
    ``("collector", "mask")``) remove rows from the counts ``N_teacher``/``N_self``.

    If the tag is missing and ``alpha == 0``, every row is a self row and the loss is plain
    TD3. ``alpha > 0`` without the tag raises a ``KeyError``; ``alpha > 0`` with no teacher
    row, or ``alpha < 1`` with no self row, raises a ``ValueError``.

    ``alpha`` is a registered buffer listed in ``_schedulable_buffers``: ``loss.alpha = 0.0``
    updates it in place (this is what :class:`~torchrl_sail.AlphaScheduler` does), and values
    outside ``[0, 1]`` are rejected on assignment too.

    Args:
        actor_network (TensorDictModule): the deterministic policy, e.g.
            ``TensorDictSequential(TensorDictModule(MLP, ["observation"], ["param"]),
            TanhModule(["param"], ["action"], spec=action_spec))``.
        qvalue_network (TensorDictModule or list of TensorDictModule): the Q-value
            network (reading ``"observation"`` and ``"action"``, writing
            ``"state_action_value"``); duplicated ``num_qvalue_nets`` times as in
            :class:`~torchrl.objectives.TD3Loss` (with re-sampled parameters).

    Keyword Args:
        alpha (float, optional): the teacher share of the objective, in ``[0, 1]``.
            Defaults to ``0.5`` (paper and authors' code).
        action_spec (TensorSpec, optional): the (bounded) action spec. Exactly one of
            ``action_spec`` and ``bounds`` must be given.
        bounds (tuple of float, optional): ``(low, high)`` action bounds, instead of
            ``action_spec``.
        num_qvalue_nets (int, optional): number of Q-nets. Defaults to ``2``.
        policy_noise (float, optional): std of the target policy smoothing noise.
            Defaults to ``0.2``.
        noise_clip (float, optional): clip of the target policy smoothing noise.
            Defaults to ``0.5``.
        loss_function (str, optional): ``"l2"``, ``"l1"`` or ``"smooth_l1"``. Defaults to
            ``"l2"`` (the authors use a plain MSE critic loss; note that
            :class:`~torchrl.objectives.TD3Loss` defaults to ``"smooth_l1"``).
        delay_actor (bool, optional): keep a target actor. Defaults to ``True``.
        delay_qvalue (bool, optional): keep target Q-nets. Defaults to ``True``.
        gamma (float, optional): not supported, as in TD3Loss: use
            ``loss.make_value_estimator(gamma=...)``. Passing it raises a ``TypeError``.
        priority_key (str, optional): deprecated, use ``set_keys(priority=...)``.
        separate_losses (bool, optional): train parameters shared by actor and critic
            only through the actor loss. Defaults to ``False``.
        reduction (str, optional): ``"mean"`` (default), ``"sum"`` or ``"none"``, see above.
        deactivate_vmap (bool, optional): replace vmap by a Python loop over Q-nets.
            Defaults to ``False``.
        use_prioritized_weights (str or bool, optional): ``"auto"`` (default) uses
            ``"priority_weight"`` when present, ``True`` likewise, ``False`` ignores it.
            The mixing weights are always applied.

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
        >>> loss = SAILLoss(actor, critic, action_spec=spec, alpha=0.5)
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
        >>> sorted(k for k in out.keys() if k.startswith("loss_"))
        ['loss_actor', 'loss_qvalue']
        >>> loss.alpha = 0.0  # e.g. after the first promoted trajectory
        >>> float(loss(batch)["alpha"])
        0.0
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
            priority_weight (NestedKey): Prioritized-replay importance weights, multiplied
                into the mixing weights within each group. Defaults to
                ``"priority_weight"``.
            is_teacher (NestedKey): Boolean tag, shape = batch shape, ``True`` for rows
                that come from the teacher buffer (written by
                :class:`~torchrl_sail.MixedReplayBuffer`). Defaults to ``"is_teacher"``.
        """

        is_teacher: NestedKey = "is_teacher"

    tensor_keys: _AcceptedKeys
    default_keys = _AcceptedKeys
    _schedulable_buffers = frozenset({"alpha"})
    # Spelled out rather than ``TD3Loss.out_keys + [...]``: TensorDictModuleBase turns the
    # class attribute into a property at the first TD3Loss instantiation, so reading it
    # here would break if a TD3Loss was built before this module is imported.
    out_keys = [
        "loss_actor",
        "loss_qvalue",
        "pred_value",
        "state_action_value_actor",
        "next_state_value",
        "target_value",
        "alpha",
        "pred_value_teacher",
        "pred_value_self",
    ]

    alpha: torch.Tensor

    def __init__(
        self,
        actor_network: TensorDictModule,
        qvalue_network: TensorDictModule | list[TensorDictModule],
        *,
        alpha: float = 0.5,
        action_spec: TensorSpec | None = None,
        bounds: tuple[float, float] | None = None,
        num_qvalue_nets: int = 2,
        policy_noise: float = 0.2,
        noise_clip: float = 0.5,
        loss_function: str = "l2",
        delay_actor: bool = True,
        delay_qvalue: bool = True,
        gamma: float | None = None,
        priority_key: str | None = None,
        separate_losses: bool = False,
        reduction: str | None = None,
        deactivate_vmap: bool = False,
        use_prioritized_weights: str | bool = "auto",
    ) -> None:
        # Validate before building anything, so a bad alpha fails fast and clearly.
        alpha = _check_alpha(alpha, where="SAILLoss(alpha=...)")
        super().__init__(
            actor_network,
            qvalue_network,
            action_spec=action_spec,
            bounds=bounds,
            num_qvalue_nets=num_qvalue_nets,
            policy_noise=policy_noise,
            noise_clip=noise_clip,
            loss_function=loss_function,
            delay_actor=delay_actor,
            delay_qvalue=delay_qvalue,
            gamma=gamma,
            priority_key=priority_key,
            separate_losses=separate_losses,
            reduction=reduction,
            deactivate_vmap=deactivate_vmap,
            use_prioritized_weights=use_prioritized_weights,
        )
        # A float dtype is forced: an int alpha (0 or 1) would otherwise create an int64
        # buffer and in-place scheduling to 0.5 would silently truncate.
        self.register_coeff_buffer(
            "alpha",
            alpha,
            device=self.max_action.device,
            dtype=torch.get_default_dtype(),
        )

    def __setattr__(self, name: str, value) -> None:
        # LossModule turns scalar assignment into an in-place buffer update; validate
        # first so a scheduler cannot push alpha outside [0, 1].
        if name == "alpha" and "alpha" in self.__dict__.get("_buffers", {}):
            value = _check_alpha(value, where="SAILLoss.alpha = ...")
        super().__setattr__(name, value)

    def _set_in_keys(self):
        super()._set_in_keys()
        # Listed so that batches built with ``select(*loss.in_keys)`` keep the tag and the
        # keyword-argument (dispatch) call mode accepts ``is_teacher=``.
        # dict.fromkeys dedups in insertion order: a set would make the order of
        # loss.in_keys depend on PYTHONHASHSEED.
        self._in_keys = list(dict.fromkeys([*self._in_keys, self.tensor_keys.is_teacher]))

    # ------------------------------------------------------------------ weights

    def _valid_rows(
        self, tensordict: TensorDictBase, like: torch.Tensor
    ) -> torch.Tensor:
        """Rows kept by the loss mask(s) (``loss_mask_key``), shaped like ``like``."""
        valid = torch.ones_like(like, dtype=torch.bool)
        for mask_key in self._loss_mask_keys():
            mask = tensordict.get(mask_key, default=None)
            if mask is not None:
                valid = valid & self._expand_loss_mask(mask.bool(), valid)
        return valid

    def _get_tag(self, tensordict: TensorDictBase) -> torch.Tensor | None:
        key = self.tensor_keys.is_teacher
        tag = tensordict.get(key, default=None)
        if tag is None:
            return None
        if tag.dtype != torch.bool:
            raise TypeError(
                f"SAILLoss: the teacher tag {key!r} must be a bool tensor, got dtype "
                f"{tag.dtype}; convert it with .bool()."
            )
        batch_shape = tensordict.batch_size
        if tag.shape == batch_shape + (1,):
            tag = tag.squeeze(-1)
        if tag.shape != batch_shape:
            raise ValueError(
                f"SAILLoss: the teacher tag {key!r} must have the batch shape "
                f"{tuple(batch_shape)}, got {tuple(tag.shape)}."
            )
        return tag

    def _maybe_get_priority_weight(
        self, tensordict: TensorDictBase
    ) -> torch.Tensor | None:
        """Per-row weights: SAIL's teacher/self mixing times optional PRB weights.

        TD3Loss calls this in both ``actor_loss`` and ``value_loss`` and reduces with
        ``(loss * w).sum() / w.sum()``.
        """
        prb_weights = super()._maybe_get_priority_weight(tensordict)
        alpha = float(self.alpha)
        tag = self._get_tag(tensordict)
        if tag is None:
            if alpha > 0.0:
                key = self.tensor_keys.is_teacher
                raise KeyError(
                    f"SAILLoss: alpha={alpha} > 0 needs the boolean teacher tag {key!r} "
                    f"in the batch (shape = batch shape, True for teacher rows). Sample "
                    f"with torchrl_sail.MixedReplayBuffer, which writes it, or use "
                    f"loss.set_keys(is_teacher=<your key>); set loss.alpha = 0 for "
                    f"plain TD3 on untagged batches."
                )
            return prb_weights
        valid = self._valid_rows(tensordict, tag)
        teacher = tag & valid
        own = ~tag & valid
        n_teacher = int(teacher.sum())
        n_self = int(own.sum())
        if alpha > 0.0 and n_teacher == 0:
            raise ValueError(
                f"SAILLoss: alpha={alpha} > 0 but the batch has no (valid) teacher row "
                f"(no True in {self.tensor_keys.is_teacher!r}); sample some teacher rows "
                f"or set loss.alpha = 0."
            )
        if alpha < 1.0 and n_self == 0:
            raise ValueError(
                f"SAILLoss: alpha={alpha} < 1 but the batch has no (valid) self row "
                f"(every row has {self.tensor_keys.is_teacher!r}=True); sample some agent "
                f"rows or set loss.alpha = 1."
            )
        dtype = self.alpha.dtype
        if prb_weights is None:
            base = valid.to(dtype)
        else:
            base = self._expand_loss_mask(prb_weights, tag).to(dtype) * valid
        # Normalising per group keeps each group's total share at alpha / (1 - alpha)
        # even when importance weights differ between the two buffers.
        teacher_norm = (base * teacher).sum().clamp_min(torch.finfo(dtype).tiny)
        self_norm = (base * own).sum().clamp_min(torch.finfo(dtype).tiny)
        n_valid = n_teacher + n_self
        weights = torch.where(
            teacher, alpha * base / teacher_norm, (1.0 - alpha) * base / self_norm
        )
        # Average weight 1 instead of sum 1: same "mean" loss, but "sum"/"none" keep
        # TD3's scale, and alpha = N_teacher / B reproduces TD3Loss exactly.
        return torch.where(valid, weights * n_valid, torch.zeros_like(weights))

    # ------------------------------------------------------------------ forward

    @dispatch
    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Compute the SAIL actor and critic losses; also writes ``td_error`` in place.

        Args:
            tensordict (TensorDictBase): a batch of transitions with the teacher tag.

        Returns:
            a TensorDict with TD3Loss's entries (``loss_actor``, ``loss_qvalue``,
            ``pred_value``, ...) plus detached ``alpha`` and the mean predicted Q over
            the teacher rows (``pred_value_teacher``) and the self rows
            (``pred_value_self``); a group mean is NaN when the batch has no such row.
        """
        td_out = super().forward(tensordict)
        pred = td_out.get("pred_value")  # [num_qvalue_nets, *batch]
        tag = self._get_tag(tensordict)
        if tag is None:
            tag = torch.zeros(tensordict.batch_size, dtype=torch.bool, device=pred.device)
        valid = self._valid_rows(tensordict, tag)
        pred_rows = pred.mean(0)
        nan = torch.full((), float("nan"), dtype=pred.dtype, device=pred.device)

        def group_mean(rows: torch.Tensor) -> torch.Tensor:
            if not rows.any():
                return nan
            return pred_rows[rows].mean()

        td_out.set("pred_value_teacher", group_mean(tag & valid))
        td_out.set("pred_value_self", group_mean(~tag & valid))
        # clone: the buffer is updated in place by schedulers, a logged view would change.
        td_out.set("alpha", self.alpha.detach().clone())
        return td_out
