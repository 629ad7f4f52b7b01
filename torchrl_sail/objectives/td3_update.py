"""One whole TD3 gradient step (critic, then actor and targets) for a TD3Loss or SAILLoss.

:class:`~torchrl.objectives.TD3Loss` evaluates its networks through TensorDict modules,
``to_module`` parameter swaps and ``vmap``; on a CPU at SAIL's sizes ([400, 300] nets,
batch 256) that machinery and the second critic evaluated by the actor loss cost about a
quarter of a gradient step (``benchmarks/bench_update.py``). :class:`TD3Update`
runs the same step on the loss's own parameters with plain tensor operations: the twin
critics as one batched matrix product over their stacked parameters, the actor objective
on the first critic only (the only one it reads), one ``_foreach_lerp_`` for the targets.
The reference implementation (``implementation="loss"``) calls the loss's
``value_loss``/``actor_loss``, the optimizers and the target updater, as TorchRL's TD3
script does; both give the same losses, gradients and parameters (tested), also for n-step
transitions (``steps_to_next_obs``) and DDPGfD's two-loss critic step (``nstep_key``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import partial
from typing import Literal

import torch
import torch.nn.functional as F
from tensordict import TensorDictBase, unravel_key
from tensordict.nn import CudaGraphModule, TensorDictModule, TensorDictSequential
from tensordict.utils import NestedKey
from torch import nn
from torchrl.modules import TanhModule
from torchrl.objectives import SoftUpdate, TD3Loss
from torchrl.objectives.utils import distance_loss
from torchrl.objectives.value import TD0Estimator

from torchrl_sail._compat import (
    ACTOR_MLP_PATH,
    ACTOR_TANH_PATH,
    CRITIC_MLP_PATH,
    DropoutLayer,
    mlp_params,
    native_bf16_matmul,
    reduce_loss,
    soft_update_pairs,
    tanh_bounds,
    tanh_map,
)
from torchrl_sail.envs.nstep import nstep_view

__all__ = ["TD3Update"]

_PRECISIONS = {"fp32": None, "bf16": torch.bfloat16}


@dataclass(frozen=True, eq=False)  # eq=False: no field-wise == on tensors
class _LayerNorm:
    """A program's ``nn.LayerNorm`` over the last dimension, bound to its parameters: ``weight``
    ``None`` without an elementwise affine map, ``bias`` ``None`` without one or with ``bias=False``."""

    weight: torch.Tensor | None
    bias: torch.Tensor | None
    eps: float

    @property
    def tensors(self) -> tuple:
        return (self.weight, self.bias)

    def detached_first(self) -> _LayerNorm:
        return _LayerNorm(*(None if t is None else t.detach()[0] for t in self.tensors), self.eps)


def _mlp_program(mlp: nn.Module, params: TensorDictBase, what: str) -> list:
    """The layers of ``mlp`` bound to ``params``: ``(weight, bias)`` pairs, layer norms
    (:class:`_LayerNorm`) and activations."""
    if not isinstance(mlp, nn.Sequential):
        raise TypeError(
            f"TD3Update needs the {what} to be an nn.Sequential MLP (e.g. torchrl's MLP), "
            f"got {type(mlp).__name__}; use implementation='loss' for other networks."
        )
    program = []
    for name, layer in mlp.named_children():
        if isinstance(layer, nn.Linear):
            program.append((params[name, "weight"], params[name, "bias"] if layer.bias is not None else None))
        elif isinstance(layer, nn.LayerNorm) and len(layer.normalized_shape) == 1:
            affine = layer.elementwise_affine
            program.append(
                _LayerNorm(
                    params[name, "weight"] if affine else None,
                    params[name, "bias"] if affine and layer.bias is not None else None,
                    layer.eps,
                )
            )
        elif (
            isinstance(layer, DropoutLayer)
            or any(True for _ in layer.parameters(recurse=True))
            or any(True for _ in layer.buffers(recurse=True))
        ):
            raise TypeError(
                f"TD3Update runs Linear layers, LayerNorm over the features and parameter-free activations; "
                f"the {what} has {type(layer).__name__} at position {name}: use implementation='loss'."
            )
        else:
            program.append(layer)
    return program


def _layer_norm(x: torch.Tensor, norm: _LayerNorm, stacked: bool) -> torch.Tensor:
    """``nn.LayerNorm`` over the features of ``x`` (``[B, F]``, or ``[n, B, F]`` with ``[n, F]``
    parameters, one per network of a stacked ensemble).

    Under autocast a bfloat16 ``x`` is normalized, and the norm's output kept, in float32, as
    CUDA's autocast runs ``layer_norm`` (CPU's rounds the output to bfloat16): the norm divides by
    the features' spread, which magnifies the rounding of the products before it.
    """
    x = x.to(torch.promote_types(x.dtype, torch.float32))  # float64 stays float64
    with torch.autocast(x.device.type, enabled=False):
        if not stacked:
            return F.layer_norm(x, x.shape[-1:], norm.weight, norm.bias, norm.eps)
        # torch's fused norm, then each network's affine map in one broadcast op
        h = F.layer_norm(x, x.shape[-1:], eps=norm.eps)
        weight = None if norm.weight is None else norm.weight.unsqueeze(-2)
        bias = None if norm.bias is None else norm.bias.unsqueeze(-2)
        if weight is not None and bias is not None:
            return torch.addcmul(bias, h, weight)
        if weight is not None:
            return h * weight
        return h if bias is None else h + bias


# Activations applied in place to a layer's fresh output: the backward of the products, of the
# norm (its input, mean and rstd) and of its affine map (addcmul, mul, add) reads their inputs, not
# their outputs, and these activations' backward reads their own output. Not allocating a new
# [B, 400] activation per layer saves about 5% of a CPU step (measured).
_IN_PLACE = {nn.ReLU: torch.relu_, nn.Tanh: torch.tanh_}


def _linear(
    x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor | None, stacked: bool, feature_major: bool
) -> torch.Tensor:
    if not stacked:
        return F.linear(x, weight, bias)
    if feature_major:
        return torch.bmm(weight, x) if bias is None else torch.baddbmm(bias.unsqueeze(-1), weight, x)
    return torch.bmm(x, weight.mT) if bias is None else torch.baddbmm(bias.unsqueeze(-2), x, weight.mT)


def _run(program: list, x: torch.Tensor) -> torch.Tensor:
    """Evaluates an MLP program on ``x`` (``[B, in]``).

    Stacked ``[n, out, in]`` parameters give ``[n, B, out]``: every layer is one batched
    product for the whole ensemble, computed feature-major (``W @ h^T``) so that the weight
    gradients come out contiguous instead of as transposes that autograd would copy; batch-major
    (``h @ W^T``) where the program has a LayerNorm, which normalizes the last dimension: a
    feature-major norm costs more in transposes and strided activations than those copies (measured).

    The last layer runs in the parameters' own precision even under autocast: it is a thin
    product (``out`` is 1 for a critic), and its output is what the TD target, the min over
    critics and the tanh read. In bfloat16 a Q value of 100 rounds to a multiple of 0.5, the
    size of SAIL's per-step reward.
    """
    last = max(i for i, layer in enumerate(program) if isinstance(layer, tuple))
    feature_major = not any(isinstance(layer, _LayerNorm) for layer in program)
    stacked = fresh = False
    for i, layer in enumerate(program):
        if isinstance(layer, tuple):
            weight, bias = layer
            fresh = True
            if weight.dim() == 3 and not stacked:
                x = x.mT.expand(weight.shape[0], *x.mT.shape) if feature_major else x.expand(weight.shape[0], *x.shape)
                stacked = True
            if i == last and torch.is_autocast_enabled(x.device.type):
                with torch.autocast(x.device.type, enabled=False):
                    x = _linear(x.to(weight.dtype), weight, bias, stacked, feature_major)
            else:
                x = _linear(x, weight, bias, stacked, feature_major)
        elif isinstance(layer, _LayerNorm):
            x = _layer_norm(x, layer, stacked)
            fresh = True
        elif fresh and type(layer) in _IN_PLACE:
            x = _IN_PLACE[type(layer)](x)
        else:
            x = layer(x)
            fresh = False
    return x.mT if stacked and feature_major else x


def _first_detached(program: list) -> list:
    """The first network of a stacked ensemble, on detached views of its parameters.

    The views share storage with the parameters, so optimizer steps show through; no gradient
    reaches them (the actor loss trains the actor only).
    """
    return [
        layer.detached_first()
        if isinstance(layer, _LayerNorm)
        else tuple(None if t is None else t.detach()[0] for t in layer)
        if isinstance(layer, tuple)
        else layer
        for layer in program
    ]


class TD3Update:
    """One TD3 gradient step of a :class:`~torchrl.objectives.TD3Loss` (e.g. a SAILLoss).

    A call runs the critic step (``value_loss``, backward, ``critic_optimizer.step()``)
    and, when ``update_actor`` is ``True`` (every ``policy_delay``-th step in TD3), the
    actor step (``actor_loss``, backward, ``actor_optimizer.step()``) followed by the
    target update of ``target_updater``; :meth:`critic_step`, :meth:`actor_step` and
    :meth:`update_targets` run the three parts alone. The parameters, the optimizers and
    the target updater are the caller's: checkpoints and schedules are unchanged.

    Two implementations of the same step:

    - ``"fused"`` (default): plain tensor operations on the loss's parameters. The twin
      critics run as one batched product over their stacked ``[num_qvalue_nets, ...]``
      parameters; the actor objective ``-Q_1(s, \\pi(s))`` evaluates the first critic only
      (``TD3Loss`` evaluates every critic and keeps the first); the targets move with one
      ``torch._foreach_lerp_``. Reductions go through the loss's ``_reduce_loss`` and
      per-row weights through its ``_maybe_get_priority_weight`` hook
      (:func:`torchrl_sail._compat.reduce_loss`), so loss masks,
      prioritized weights and ``SAILLoss(mixing="weights")`` act as in the loss. It
      supports what SAIL uses: an actor ``TensorDictSequential(TensorDictModule(MLP),
      TanhModule)``, a critic ``TensorDictModule(MLP)`` (its ``in_keys`` concatenated in
      order, as :class:`~torchrl.modules.MLP` does; each MLP of Linear layers,
      parameter-free activations and ``nn.LayerNorm`` over the features, e.g. RLPD's
      critic, ``MLP(norm_class=nn.LayerNorm, ...)``), target networks for both, a TD(0)
      value estimator and a :class:`~torchrl.objectives.SoftUpdate`; anything else is
      refused at construction with the reason. A :class:`~torchrl_sail.SAILLoss`'s pre-tanh
      penalty (``preactivation_coef``) reuses the actor output the objective computes.
    - ``"loss"``: the reference, the loss's own ``value_loss``/``actor_loss`` and
      ``target_updater.step()``, as TorchRL's TD3 script runs them. Works for any network.

    The policy-smoothing noise is drawn at the same point of both implementations, so a
    seeded step gives the same result with either (to float rounding).

    **n-step targets.** Both implementations compute the loss's TD(0) estimator target
    ``r + gamma ** k * (1 - terminated) * min_i Q'_i(s', a')`` with ``k`` the batch's
    ``steps_to_next_obs`` entry where the estimator reads it
    (``loss.value_estimator.tensor_keys.steps_to_next_obs``, at the root; ``k = 1`` when
    absent), e.g. transitions from TorchRL's
    :class:`~torchrl.envs.transforms.MultiStepTransform`. With ``nstep_key`` (DDPGfD), the
    critic loss is ``L_1 + nstep_weight * L_n`` on the same rows: ``L_1`` the TD loss of the
    1-step transition, ``L_n`` that of the n-step one an
    :class:`~torchrl_sail.NStepTransform` stored under ``nstep_key`` (read through
    :func:`~torchrl_sail.nstep_view`); the actor step is unchanged.

    Args:
        loss (TD3Loss): the loss whose parameters are trained (a
            :class:`~torchrl_sail.SAILLoss` or any ``TD3Loss``), with its value estimator
            made (``loss.make_value_estimator(gamma=...)``).

    Keyword Args:
        critic_optimizer (torch.optim.Optimizer): optimizer of
            ``loss.qvalue_network_params``.
        actor_optimizer (torch.optim.Optimizer): optimizer of
            ``loss.actor_network_params``.
        target_updater (SoftUpdate): the target updater built on ``loss``.
        implementation (str, optional): ``"fused"`` or ``"loss"``. Defaults to ``"fused"``.
        precision (str, optional): ``"fp32"`` or ``"bf16"``: the hidden layers' products
            in bfloat16 (autocast: AMX on recent Xeons, tensor cores on CUDA); the last layer
            of every network, the min over the target critics, the TD target, the actor's tanh,
            the losses, the parameters and the optimizer states in the parameters' precision.
            ``"bf16"`` needs ``implementation="fused"``, and warns on a device without bf16
            matrix hardware (a CPU without AVX-512 or AMX), where it is far slower than fp32.
            Defaults to ``"fp32"``.
        nstep_key (NestedKey, optional): where each row's n-step transition is (an
            :class:`~torchrl_sail.NStepTransform`'s ``out_key``, e.g. ``"next_n"``): adds
            DDPGfD's n-step TD loss to the critic loss. Defaults to ``None`` (1-step only).
        nstep_weight (float, optional): DDPGfD's ``lambda_1``, the weight of the n-step
            loss (``> 0``). Defaults to ``1.0``.
        td_error (bool, optional): write each row's squared 1-step TD error, the max over the
            critics, into the batch under ``loss.tensor_keys.priority``, as ``TD3Loss.forward``
            does for prioritized replay (e.g. a
            :class:`~torchrl_sail.PrioritizedMixedReplayBuffer`'s new priorities). Not with
            ``cudagraphs``. Defaults to ``False``.
        actor_max_grad_norm (float, optional): clip the actor's gradients to this global
            norm before its step (``torch.nn.utils.clip_grad_norm_``, no host sync), as
            Kostrikov et al.'s DAC does at 40. Defaults to ``None`` (no clipping).
        cudagraphs (bool, optional): replay the fused step as CUDA graphs (TensorDict's
            :class:`~tensordict.nn.CudaGraphModule`, as TorchRL's sota scripts use it): one graph
            for critic steps and one for critic + actor + target steps, each captured after
            ``cudagraph_warmup`` eager steps (every call is one step, warm-up and capture
            included). Needs the loss on a CUDA device, ``implementation="fused"`` and both
            optimizers built with ``capturable=True``. A graph replays the step with the
            values it was captured with, so the graphs are captured again whenever the binding
            or a value the step reads as a Python number changes (the optimizers' param groups,
            e.g. a new learning rate; ``policy_noise``, ``noise_clip``, ``actor_max_grad_norm``).
            Defaults to ``False``.
        cudagraph_warmup (int, optional): eager steps before a graph is captured (the
            optimizers' states are created there). Defaults to ``3``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from tensordict.nn import TensorDictModule, TensorDictSequential
        >>> from torchrl.data import Bounded
        >>> from torchrl.modules import MLP, TanhModule, ValueOperator
        >>> from torchrl.objectives import SoftUpdate
        >>> from torchrl_sail import SAILLoss, TD3Update
        >>> _ = torch.manual_seed(0)
        >>> spec = Bounded(-1.0, 1.0, (2,))
        >>> actor = TensorDictSequential(
        ...     TensorDictModule(MLP(in_features=3, out_features=2, num_cells=[16]), ["observation"], ["param"]),
        ...     TanhModule(["param"], ["action"], spec=spec))
        >>> critic = ValueOperator(
        ...     MLP(in_features=5, out_features=1, num_cells=[16]), in_keys=["action", "observation"])
        >>> loss = SAILLoss(actor, critic, action_spec=spec)
        >>> loss.make_value_estimator(gamma=0.99)
        >>> update = TD3Update(
        ...     loss,
        ...     critic_optimizer=torch.optim.Adam(loss.qvalue_network_params.flatten_keys().values()),
        ...     actor_optimizer=torch.optim.Adam(loss.actor_network_params.flatten_keys().values()),
        ...     target_updater=SoftUpdate(loss, tau=0.005))
        >>> batch = TensorDict({
        ...     "observation": torch.randn(8, 3), "action": spec.rand((8,)),
        ...     ("next", "observation"): torch.randn(8, 3), ("next", "reward"): torch.randn(8, 1),
        ...     ("next", "done"): torch.zeros(8, 1, dtype=torch.bool),
        ...     ("next", "terminated"): torch.zeros(8, 1, dtype=torch.bool)}, [8])
        >>> metrics = update(batch, update_actor=True)
        >>> sorted(metrics)
        ['loss_actor', 'loss_qvalue', 'q_mean']

        DDPGfD's critic loss, 1-step + lambda_1 * n-step (here a 3-step view with a made-up
        window: in a run an :class:`~torchrl_sail.NStepTransform` writes it):

        >>> nstep = TD3Update(
        ...     loss, critic_optimizer=update.critic_optimizer, actor_optimizer=update.actor_optimizer,
        ...     target_updater=update.target_updater, nstep_key="next_n", nstep_weight=1.0)
        >>> batch["next_n"] = batch["next"].clone()
        >>> batch["next_n", "steps_to_next_obs"] = torch.full((8, 1), 3)
        >>> sorted(nstep(batch, update_actor=False))
        ['loss_qvalue', 'loss_qvalue_nstep', 'q_mean']
    """

    def __init__(
        self,
        loss: TD3Loss,
        *,
        critic_optimizer: torch.optim.Optimizer,
        actor_optimizer: torch.optim.Optimizer,
        target_updater: SoftUpdate,
        implementation: Literal["fused", "loss"] = "fused",
        precision: Literal["fp32", "bf16"] = "fp32",
        nstep_key: NestedKey | None = None,
        nstep_weight: float = 1.0,
        td_error: bool = False,
        actor_max_grad_norm: float | None = None,
        cudagraphs: bool = False,
        cudagraph_warmup: int = 3,
    ) -> None:
        if implementation not in ("fused", "loss"):
            raise ValueError(f"implementation must be 'fused' or 'loss', got {implementation!r}.")
        if precision not in _PRECISIONS:
            raise ValueError(f"precision must be one of {sorted(_PRECISIONS)}, got {precision!r}.")
        if precision != "fp32" and implementation != "fused":
            # TanhModule would squash in reduced precision, where its gradient vanishes early.
            raise ValueError(f"precision={precision!r} needs implementation='fused'.")
        if not isinstance(loss, TD3Loss):
            raise TypeError(f"TD3Update needs a TD3Loss (e.g. SAILLoss), got {type(loss).__name__}.")
        if nstep_key is not None and nstep_key in ("next", ("next",)):
            raise ValueError("nstep_key='next' is the 1-step transition: name where the n-step view is, e.g. 'next_n'.")
        if not (isinstance(nstep_weight, (int, float)) and 0 < nstep_weight < math.inf):
            raise ValueError(f"nstep_weight (DDPGfD's lambda_1) must be a finite number > 0, got {nstep_weight!r}.")
        self.nstep_key = nstep_key
        self.nstep_weight = float(nstep_weight)
        self.loss = loss
        self.critic_optimizer = critic_optimizer
        self.actor_optimizer = actor_optimizer
        self.target_updater = target_updater
        if actor_max_grad_norm is not None and not actor_max_grad_norm > 0:
            raise ValueError(f"actor_max_grad_norm must be > 0 or None, got {actor_max_grad_norm!r}.")
        self.actor_max_grad_norm = actor_max_grad_norm
        self._actor_params = [p for group in actor_optimizer.param_groups for p in group["params"]]
        self.implementation = implementation
        self.precision = precision
        self._device_type = loss.max_action.device.type
        if precision == "bf16" and not native_bf16_matmul(loss.max_action.device):
            warnings.warn(
                f"precision='bf16' on a {loss.max_action.device.type} without bf16 matrix hardware (on a CPU: "
                "AVX-512 or AMX): torch emulates the products, many times slower per TD3 step than fp32. "
                "Use precision='fp32' here.",
                UserWarning,
                stacklevel=2,
            )
        if td_error and cudagraphs:
            raise ValueError("td_error=True writes into the batch, which a CUDA graph's replay does not: use one.")
        self.td_error = td_error
        self.cudagraphs = cudagraphs
        if cudagraphs:
            _check_cudagraphs(implementation, loss, critic_optimizer, actor_optimizer, cudagraph_warmup)
        self.cudagraph_warmup = cudagraph_warmup
        self._graphs: dict[bool, CudaGraphModule] = {}
        self._graphed_values = None
        self._binding = None
        if implementation == "fused":
            self._bind()

    def _bind(self) -> None:
        """Checks the loss is one the fused step implements, and binds its parameters."""
        loss = self.loss
        if not (loss.delay_actor and loss.delay_qvalue):
            raise ValueError(
                "TD3Update(implementation='fused') needs target networks for the actor and the "
                "critic (TD3Loss(delay_actor=True, delay_qvalue=True), the default)."
            )
        estimator = loss.value_estimator
        if type(estimator) is not TD0Estimator:
            raise ValueError(
                f"TD3Update(implementation='fused') implements the TD(0) target; the loss has "
                f"{type(estimator).__name__}: use implementation='loss'."
            )
        # What TD0Estimator.value_estimate does besides r + gamma^k (1 - terminated) Q': refused, not approximated.
        if estimator.average_rewards:
            raise ValueError(
                "TD3Update(implementation='fused') does not standardise rewards: the loss's TD0Estimator "
                "has average_rewards=True; use implementation='loss'."
            )
        if estimator.value_network is not None:
            raise ValueError(
                "TD3Update(implementation='fused') bootstraps from the loss's target critics; the loss's "
                "TD0Estimator has its own value_network: use implementation='loss'."
            )
        if unravel_key(estimator.tensor_keys.value) != unravel_key(loss.tensor_keys.state_action_value):
            raise ValueError(
                f"TD3Update(implementation='fused'): the TD0Estimator reads the next value from "
                f"{estimator.tensor_keys.value!r}, where TD3Loss.value_loss does not write it "
                f"({loss.tensor_keys.state_action_value!r}); use implementation='loss'."
            )
        if not isinstance(self.target_updater, SoftUpdate):
            raise TypeError(
                f"TD3Update(implementation='fused') implements SoftUpdate's Polyak step, got "
                f"{type(self.target_updater).__name__}: use implementation='loss'."
            )
        actor = loss.actor_network
        if not (
            isinstance(actor, TensorDictSequential)
            and len(actor.module) == 2
            and isinstance(actor.module[0], TensorDictModule)
            and isinstance(actor.module[1], TanhModule)
        ):
            raise TypeError(
                "TD3Update(implementation='fused') needs the actor to be "
                "TensorDictSequential(TensorDictModule(MLP), TanhModule): use implementation='loss'."
            )
        body, tanh = actor.module
        if (
            list(tanh.in_keys) != list(body.out_keys)
            or len(tanh.out_keys) != 1
            or tanh.out_keys[0] != loss.tensor_keys.action
        ):
            raise TypeError(
                "TD3Update(implementation='fused') needs the TanhModule to map the MLP output to "
                f"{loss.tensor_keys.action!r}; got {tanh.in_keys} -> {tanh.out_keys}."
            )
        critic = loss.qvalue_network
        if (
            not isinstance(critic, TensorDictModule)
            or isinstance(critic, TensorDictSequential)
            or len(critic.out_keys) != 1
            or loss.tensor_keys.action not in critic.in_keys
        ):
            raise TypeError(
                "TD3Update(implementation='fused') needs the critic to be one TensorDictModule "
                f"(e.g. ValueOperator(MLP)) reading {loss.tensor_keys.action!r}."
            )
        self._actor_in_keys = list(body.in_keys)
        self._critic_in_keys = list(critic.in_keys)
        self._tanh = tanh
        self._tanh_bounds = self._loss_tanh_bounds()
        self._actor = _mlp_program(body.module, mlp_params(loss.actor_network_params, ACTOR_MLP_PATH), "actor")
        self._target_actor = _mlp_program(
            body.module, mlp_params(loss.target_actor_network_params, ACTOR_MLP_PATH), "actor"
        )
        self._critic = _mlp_program(critic.module, mlp_params(loss.qvalue_network_params, CRITIC_MLP_PATH), "critic")
        self._target_critic = _mlp_program(
            critic.module, mlp_params(loss.target_qvalue_network_params, CRITIC_MLP_PATH), "critic"
        )
        self._critic_first = _first_detached(self._critic)
        # SoftUpdate's own source/target pairing, as flat lists for one foreach call.
        self._polyak_sources, self._polyak_targets = soft_update_pairs(self.target_updater)
        self._bound_tensors = [
            tensor
            for program in (self._actor, self._target_actor, self._critic, self._target_critic)
            for layer in program
            if isinstance(layer, (tuple, _LayerNorm))
            for tensor in (layer.tensors if isinstance(layer, _LayerNorm) else layer)
            if tensor is not None
        ]
        self._device_type = self._bound_tensors[0].device.type
        self._binding = self._binding_state()
        self._graphs.clear()  # captured on the tensors bound before

    def _binding_state(self) -> tuple:
        """What the bound views depend on, cheap to read before every step (a few microseconds).

        ``loss.to(dtype or device)`` and ``torch.utils.swap_tensors`` give the loss's parameters
        new storage (the parameter objects stay) and replace the TanhModule's bound buffers;
        ``make_value_estimator`` and ``set_keys`` replace or rename what the target reads.
        In-place changes (optimizer steps, ``load_state_dict``) keep all of it.
        """
        loss = self.loss
        estimator = loss.value_estimator
        return (
            tuple(tensor.data_ptr() for tensor in self._bound_tensors),
            tuple(bound.data_ptr() for bound in self._loss_tanh_bounds()),
            id(estimator),
            tuple(vars(estimator.tensor_keys).values()),
            tuple(vars(loss.tensor_keys).values()),
            id(loss.actor_network),
            id(loss.qvalue_network),
        )

    def _loss_tanh_bounds(self) -> tuple[torch.Tensor, torch.Tensor]:
        # the loss's copy, where TD3Loss reads them (it swaps its params into the actor), on the loss's device
        return tanh_bounds(self._tanh, self.loss.actor_network_params[ACTOR_TANH_PATH])

    def _ensure_bound(self) -> None:
        """Binds again (checking the loss again) when what the fused step bound has moved."""
        if self.implementation == "fused" and self._binding_state() != self._binding:
            self._bind()

    def _graphed(self) -> tuple:
        """The values a captured step holds as constants: Python numbers it reads, tensors by identity."""
        loss = self.loss

        def constant(value):
            return ("tensor", id(value)) if isinstance(value, torch.Tensor) else value

        groups = tuple(
            (key, constant(value))
            for optimizer in (self.critic_optimizer, self.actor_optimizer)
            for group in optimizer.param_groups
            for key, value in group.items()
            if key != "params"
        )
        values = (
            loss.policy_noise,
            loss.noise_clip,
            loss.value_estimator.gamma,
            self.target_updater.eps,
            getattr(loss, "preactivation_coef", 0.0),
        )
        return (*map(constant, values), self.actor_max_grad_norm, self.nstep_weight, groups)

    def _graph(self, update_actor: bool) -> CudaGraphModule:
        graphed = self._graphed()
        if graphed != self._graphed_values:
            self._graphs.clear()
            self._graphed_values = graphed
        graph = self._graphs.get(update_actor)
        if graph is None:
            graph = CudaGraphModule(partial(self._step, update_actor=update_actor), warmup=self.cudagraph_warmup)
            self._graphs[update_actor] = graph
        return graph

    def _autocast(self):
        dtype = _PRECISIONS[self.precision]
        return torch.autocast(self._device_type, dtype=dtype, enabled=dtype is not None)

    def _action(self, program: list, obs: torch.Tensor) -> torch.Tensor:
        # TanhModule's map (tanh, optional clamp, affine map onto [low, high]). The squashing runs
        # in the parameters' precision also under bf16 autocast (the last layer does, see _run): in
        # bfloat16, tanh(x) rounds to exactly +-1 from |x| ~ 3 on, and its gradient 1 - tanh^2 to 0,
        # which stalls the actor.
        return tanh_map(self._tanh, _run(program, obs), *self._tanh_bounds)

    def _critic_input(self, batch: TensorDictBase, action: torch.Tensor, prefix: tuple = ()) -> torch.Tensor:
        action_key = self.loss.tensor_keys.action
        parts = [
            action if key == action_key else batch[(*prefix, key) if prefix else key] for key in self._critic_in_keys
        ]
        return torch.cat(parts, -1) if len(parts) > 1 else parts[0]

    def _actor_input(self, batch: TensorDictBase, prefix: tuple = ()) -> torch.Tensor:
        parts = [batch[(*prefix, key) if prefix else key] for key in self._actor_in_keys]
        return torch.cat(parts, -1) if len(parts) > 1 else parts[0]

    def __call__(self, batch: TensorDictBase, update_actor: bool) -> dict[str, torch.Tensor]:
        """Runs one gradient step on ``batch`` and returns detached metrics.

        The critic step, then, if ``update_actor``, the actor step and the target update.

        Args:
            batch (TensorDictBase): a ``[B]`` batch of transitions with the loss's keys.
            update_actor (bool): also run the actor step and the target update.

        Returns:
            ``{"loss_qvalue", "q_mean"}`` (and ``"loss_qvalue_nstep"`` with ``nstep_key``) and, on
            actor steps, ``"loss_actor"`` (and
            ``"preactivation_penalty"`` with a :class:`~torchrl_sail.SAILLoss` whose
            ``preactivation_coef`` is > 0): detached scalar tensors (no host synchronisation).
        """
        self._ensure_bound()  # once per step; the three parts below trust it
        if self.cudagraphs:
            return self._graph(update_actor)(batch)
        return self._step(batch, update_actor)

    def _step(self, batch: TensorDictBase, update_actor: bool) -> dict[str, torch.Tensor]:
        metrics = self._critic_step(batch)
        if update_actor:
            metrics.update(self._actor_step(batch))
            self._update_targets()
        return metrics

    def critic_step(self, batch: TensorDictBase) -> dict[str, torch.Tensor]:
        """``value_loss``, its backward and ``critic_optimizer.step()``.

        With ``nstep_key``, the loss is ``value_loss(batch) + nstep_weight * value_loss(n-step
        view)``, and the metrics hold ``"loss_qvalue_nstep"`` (the unweighted n-step term).

        Args:
            batch (TensorDictBase): a ``[B]`` batch of transitions with the loss's keys.
        """
        self._ensure_bound()
        return self._critic_step(batch)

    def _critic_step(self, batch: TensorDictBase) -> dict[str, torch.Tensor]:
        loss = self.loss
        nstep = self.nstep_key is not None
        if self.implementation == "loss":
            with self._autocast():
                loss_q, info = loss.value_loss(batch)
                if nstep:
                    loss_n, _ = loss.value_loss(self._nstep_view(batch))
                    loss_q = loss_q + self.nstep_weight * loss_n
            q = info["pred_value"]
            squared_error = info["td_error"]
        else:
            action = batch[loss.tensor_keys.action]
            # drawn first, as TD3Loss.value_loss does ("for reprod"); the n-step loss's second
            # value_loss call draws the next one
            noise = self._noise(action)
            if nstep:
                view, noise_n = self._nstep_view(batch), self._noise(action)
            with self._autocast():
                with torch.no_grad():
                    target = self._target(batch, noise)
                    if nstep:
                        target_n = self._target(view, noise_n)
                # Q(s, a) of the sampled rows, shared by both TD losses
                q = _run(self._critic, self._critic_input(batch, action)).squeeze(-1)  # [num_qvalue_nets, B]
                loss_q = self._td_loss(q, target, batch)
                if nstep:
                    loss_n = self._td_loss(q, target_n, view)
                    loss_q = loss_q + self.nstep_weight * loss_n
            squared_error = (q.detach() - target).pow(2) if self.td_error else None
        if self.td_error:
            batch.set(loss.tensor_keys.priority, squared_error.detach().max(0).values)
        loss_q.backward()
        self.critic_optimizer.step()
        self.critic_optimizer.zero_grad(set_to_none=True)
        metrics = {"loss_qvalue": loss_q.detach(), "q_mean": q.detach().mean()}
        if nstep:
            metrics["loss_qvalue_nstep"] = loss_n.detach()
        return metrics

    def _nstep_view(self, batch: TensorDictBase) -> TensorDictBase:
        # the step count goes where the loss's estimator reads it
        return nstep_view(batch, self.nstep_key, steps_key=self.loss.value_estimator.tensor_keys.steps_to_next_obs)

    def _noise(self, action: torch.Tensor) -> torch.Tensor:
        loss = self.loss
        return (torch.randn_like(action) * loss.policy_noise).clamp(-loss.noise_clip, loss.noise_clip)

    def _target(self, batch: TensorDictBase, noise: torch.Tensor) -> torch.Tensor:
        """``TD3Loss.value_loss``'s target: ``TD0Estimator.value_estimate`` on the smoothed clipped double-Q.

        ``r + gamma^k (1 - terminated) min_i Q'_i(s', clamp(pi'(s') + noise))`` with the
        estimator's keys, ``k`` its ``steps_to_next_obs`` entry (``gamma`` alone without it).
        """
        loss = self.loss
        estimator = loss.value_estimator
        keys = estimator.tensor_keys
        next_action = self._action(self._target_actor, self._actor_input(batch, ("next",)))
        next_action = (next_action + noise).clamp(loss.min_action, loss.max_action)
        next_q = _run(self._target_critic, self._critic_input(batch, next_action, ("next",))).min(0)[0]
        reward = batch["next", keys.reward]
        gamma = estimator.gamma
        steps = batch.get(keys.steps_to_next_obs, None)
        if steps is not None:  # n-step transitions, as TD0Estimator.value_estimate discounts them
            gamma = gamma ** steps.view_as(reward)
        terminated = batch.get(("next", keys.terminated), None)
        if terminated is None:  # the estimator's fallback
            terminated = batch["next", keys.done]
        not_terminated = (~terminated).int()
        return (reward + gamma * not_terminated * next_q).squeeze(-1)

    def _td_loss(self, q: torch.Tensor, target: torch.Tensor, batch: TensorDictBase) -> torch.Tensor:
        """``value_loss``'s reduction: the distance summed over the critics, then the loss's masks and weights."""
        loss = self.loss
        return reduce_loss(loss, distance_loss(q, target.expand_as(q), loss_function=loss.loss_function).sum(0), batch)

    def actor_step(self, batch: TensorDictBase) -> dict[str, torch.Tensor]:
        """``actor_loss``, its backward and ``actor_optimizer.step()`` (targets not moved).

        Args:
            batch (TensorDictBase): a ``[B]`` batch of transitions with the loss's keys.
        """
        self._ensure_bound()
        return self._actor_step(batch)

    def _actor_step(self, batch: TensorDictBase) -> dict[str, torch.Tensor]:
        loss = self.loss
        coef = getattr(loss, "preactivation_coef", 0.0)  # SAILLoss's pre-tanh penalty; TD3Loss has none
        with self._autocast():
            if self.implementation == "loss":
                loss_a, info = loss.actor_loss(batch)
            else:
                # tanh_map as in _action, keeping the pre-tanh output for SAILLoss's penalty
                x = _run(self._actor, self._actor_input(batch))
                pi = tanh_map(self._tanh, x, *self._tanh_bounds)
                q_pi = _run(self._critic_first, self._critic_input(batch, pi)).squeeze(-1)
                loss_a = reduce_loss(loss, -q_pi, batch)
                if coef:
                    penalty = reduce_loss(loss, x.pow(2).sum(-1), batch)
                    loss_a = loss_a + coef * penalty
        loss_a.backward()
        if self.actor_max_grad_norm is not None:
            torch.nn.utils.clip_grad_norm_(self._actor_params, self.actor_max_grad_norm, foreach=True)
        self.actor_optimizer.step()
        self.actor_optimizer.zero_grad(set_to_none=True)
        metrics = {"loss_actor": loss_a.detach()}
        if coef:
            metrics["preactivation_penalty"] = (
                info["preactivation_penalty"] if self.implementation == "loss" else penalty.detach()
            )
        return metrics

    def update_targets(self) -> None:
        """The Polyak step of the target networks (``target_updater.step()``)."""
        self._ensure_bound()
        self._update_targets()

    def _update_targets(self) -> None:
        if self.implementation == "loss":
            self.target_updater.step()
        else:
            with torch.no_grad():
                torch._foreach_lerp_(self._polyak_targets, self._polyak_sources, 1.0 - self.target_updater.eps)

    def __repr__(self) -> str:
        nstep = "" if self.nstep_key is None else f", nstep_key={self.nstep_key!r}, nstep_weight={self.nstep_weight}"
        return (
            f"{type(self).__name__}(loss={type(self.loss).__name__}, implementation={self.implementation!r}, "
            f"precision={self.precision!r}{nstep}, cudagraphs={self.cudagraphs})"
        )


def _check_cudagraphs(implementation: str, loss, critic_optimizer, actor_optimizer, cudagraph_warmup) -> None:
    """What ``TD3Update(cudagraphs=True)`` needs: the fused step, a CUDA loss, capturable optimizers."""
    if implementation != "fused":
        raise ValueError("cudagraphs=True replays the fused step: use implementation='fused'.")
    if loss.max_action.device.type != "cuda":
        raise ValueError(f"cudagraphs=True needs the loss on a CUDA device, got {loss.max_action.device}.")
    for name, optimizer in (("critic_optimizer", critic_optimizer), ("actor_optimizer", actor_optimizer)):
        if not all(group.get("capturable", False) for group in optimizer.param_groups):
            raise ValueError(
                f"cudagraphs=True needs {name} built with capturable=True (e.g. "
                "torch.optim.Adam(params, capturable=True)): a graph cannot read its step count on the host."
            )
    if not (isinstance(cudagraph_warmup, int) and cudagraph_warmup >= 1):
        raise ValueError(f"cudagraph_warmup must be an int >= 1, got {cudagraph_warmup!r}.")
