"""Every private TorchRL API this package and its examples rely on, in one place.

TorchRL keeps these names private (a leading underscore, or an internal layout), so a release
may change them without notice. Each one is used here only, through a small function that
says what it reads and why no public API does; the rest of the code (``TD3Update``, the
transforms, ``examples/``) calls these functions. ``tests/test_compat.py`` checks every entry
against the installed TorchRL, so an upgrade that breaks one fails there, naming it.

Checked against torchrl 0.14.1 (tensordict 0.14.3, torch 2.13.0).

Reads of TorchRL internals (functions below):

- the registry ``timeit._REG`` of TorchRL's section timer ``torchrl.timeit`` (:func:`timeit_totals`);
- ``TargetNetUpdater._sources`` / ``_targets`` and their ``"target_" + name`` pairing
  (:func:`soft_update_pairs`);
- ``LossModule._reduce_loss`` and ``LossModule._maybe_get_priority_weight`` (:func:`reduce_loss`);
- the parameter layout of ``TD3Loss``'s functional copies of SAIL's actor and critic
  (:data:`ACTOR_MLP_PATH`, :data:`CRITIC_MLP_PATH`, :func:`mlp_params`);
- ``TanhModule``'s bound buffers ``<out_key>_low`` / ``<out_key>_high`` (:func:`tanh_bounds`) and
  its ``clamp`` / ``non_trivial`` flags (:func:`tanh_map`);
- ``TensorStorage._storage``, the TensorDict a tensor storage writes into (:func:`storage_tensordict`);
- ``EnvBase._filtered_reset_keys`` (:func:`filtered_reset_keys`);
- ``torchrl.envs.transforms.utils._get_reset`` (:func:`reset_mask`);
- ``torchrl.data.postprocs.postprocs._multi_step_func`` (:func:`multi_step`);
- ``GymLikeEnv._env``, the wrapped gymnasium env, for its ``metadata`` (:func:`render_fps`);
- ``torchrl.weight_update._ray._DIST_TIMEOUT``, the Ray weight-sync group's fixed 60 s timeout, which
  the learner's side is given another value through (:func:`set_ray_weight_sync_timeout`);
- torch's ``nn.modules.dropout._DropoutNd`` (:data:`DropoutLayer`) and
  ``torch.ops.mkldnn._is_mkldnn_bf16_supported`` (:func:`native_bf16_matmul`). ``TD3Update`` also
  calls ``torch._foreach_lerp_`` directly: torch's foreach kernels have no public alias.

One tensordict method is patched on request, not read: ``TensorDictBase.from_any`` gets tensordict
0.15's shortcut for plain tensors (:func:`fast_tensor_outputs`), which the training scripts apply.

Hooks this package's subclasses override or call on ``self``/``super()`` (inheritance, listed in
:data:`SUBCLASS_HOOKS`; the subclasses use them in place): ``SAILLoss`` (a ``TD3Loss``) and
``NStepTransform`` (a ``MultiStepTransform``).
"""

from __future__ import annotations

import functools
from datetime import timedelta

import tensordict
import torch
from tensordict import TensorDictBase
from torch import nn
from torchrl import timeit
from torchrl.data.postprocs.postprocs import _multi_step_func
from torchrl.envs.transforms.utils import _get_reset

__all__ = [
    "ACTOR_MLP_PATH",
    "ACTOR_TANH_PATH",
    "CRITIC_MLP_PATH",
    "DropoutLayer",
    "SUBCLASS_HOOKS",
    "TORCHRL_VERSION",
    "fast_tensor_outputs",
    "filtered_reset_keys",
    "mlp_params",
    "multi_step",
    "native_bf16_matmul",
    "reduce_loss",
    "render_fps",
    "reset_mask",
    "set_ray_weight_sync_timeout",
    "soft_update_pairs",
    "storage_tensordict",
    "tanh_bounds",
    "tanh_map",
    "timeit_totals",
]

#: The TorchRL release every entry of this module was checked against.
TORCHRL_VERSION = "0.14.1"

#: Private methods of TorchRL classes that this package's subclasses override or call on
#: ``self``/``super()``: ``"module.Class": (name, ...)``.
SUBCLASS_HOOKS = {
    # SAILLoss: adds is_teacher to the in_keys (mixing="weights"), computes the per-row weights
    # TD3Loss reduces with, applies them itself with weight_normalization="count", and reads the
    # loss masks the same way TD3Loss does
    "torchrl.objectives.TD3Loss": (
        "_set_in_keys",
        "_maybe_get_priority_weight",
        "_reduce_loss",
        "_loss_mask_keys",
        "_expand_loss_mask",
    ),
    # NStepTransform: overrides MultiStepTransform's buffering of the last n steps (its ``_buffer``
    # attribute) and calls its key validation (``_validated`` flag)
    "torchrl.envs.transforms.MultiStepTransform": ("_validate", "_append_tensordict"),
}


# ----------------------------------------------------------------------------- timing
def timeit_totals() -> dict[str, tuple[float, int]]:
    """Total seconds and number of calls of each ``timeit`` section since the last ``timeit.erase()``.

    ``timeit.todict(percall=False)`` gives the totals but not the counts; both are in the
    private registry ``timeit._REG`` (``name -> [mean seconds, total seconds, count]``).

    Examples:
        >>> from torchrl import timeit
        >>> from torchrl_sail._compat import timeit_totals
        >>> timeit.erase()
        >>> with timeit("compat_doctest"):
        ...     pass
        >>> timeit_totals()["compat_doctest"][1]
        1
    """
    return {name: (float(total), int(count)) for name, (_, total, count) in timeit._REG.items()}


# ----------------------------------------------------------------------------- objectives
def soft_update_pairs(updater) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """The source and target parameter tensors of a ``SoftUpdate``, paired as its ``step()`` pairs them.

    Reads ``TargetNetUpdater._sources`` and ``_targets`` (TensorDicts of the loss's
    ``*_params`` and ``target_*_params``) and their pairing rule: the target of the source entry
    ``(name, *rest)`` is ``("target_" + name, *rest)``. Returns the ``.data`` of each, in one
    order, for one ``torch._foreach_lerp_(targets, sources, 1 - updater.eps)``.
    """
    sources, targets = updater._sources, updater._targets
    keys = list(sources.keys(True, True))
    target_keys = [("target_" + key[0], *key[1:]) if isinstance(key, tuple) else "target_" + key for key in keys]
    return [sources[key].data for key in keys], [targets[key].data for key in target_keys]


def reduce_loss(loss, value: torch.Tensor, batch: TensorDictBase) -> torch.Tensor:
    """A per-row loss ``value`` reduced as the loss's own ``value_loss``/``actor_loss`` reduce it.

    ``LossModule._reduce_loss`` applies the batch's loss masks and the loss's reduction
    (``"mean"``, ``"sum"``, ``"none"``) with the per-row weights of
    ``LossModule._maybe_get_priority_weight`` (prioritized replay weights, or
    ``SAILLoss(mixing="weights")``'s teacher/agent weights).
    """
    return loss._reduce_loss(value, tensordict=batch, weights=loss._maybe_get_priority_weight(batch))


#: Where the MLP of an actor ``TensorDictSequential(TensorDictModule(MLP), TanhModule)`` sits in
#: ``TD3Loss.actor_network_params`` (and its target copy): the sequence's ``module`` list, its
#: first entry, that ``TensorDictModule``'s ``module``.
ACTOR_MLP_PATH = ("module", "0", "module")
#: Where the MLP of a critic ``TensorDictModule(MLP)`` (e.g. ``ValueOperator``) sits in
#: ``TD3Loss.qvalue_network_params`` (stacked over the ``num_qvalue_nets`` critics).
CRITIC_MLP_PATH = ("module",)
#: Where that actor's ``TanhModule`` buffers sit in ``TD3Loss.actor_network_params``.
ACTOR_TANH_PATH = ("module", "1")


def mlp_params(params: TensorDictBase, path: tuple[str, ...]) -> TensorDictBase:
    """The parameters of the MLP at ``path`` (:data:`ACTOR_MLP_PATH`, :data:`CRITIC_MLP_PATH`) in a
    ``TD3Loss``'s functional parameters: entries ``"<layer index>", "weight" | "bias"``.

    The layout is ``TensorDictParams.from_module``'s, which mirrors the modules' attribute
    names; TorchRL documents no accessor for a sub-module's entry.
    """
    return params[path]


def tanh_bounds(tanh, params: TensorDictBase | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """The ``(low, high)`` action bounds a ``TanhModule`` maps onto, for its single out_key.

    ``TanhModule`` registers them as buffers named ``<out_key>_low`` / ``<out_key>_high`` (a
    nested out_key joined with ``"_"``). With ``params`` (a loss's functional copy of the
    module's entries, ``actor_network_params[ACTOR_TANH_PATH]``), the copy's: a loss's
    ``.to(device or dtype)`` moves that copy, not the module's own buffers.
    """
    key = tanh.out_keys[0] if isinstance(tanh.out_keys[0], str) else "_".join(tanh.out_keys[0])
    if params is not None:
        return params[f"{key}_low"], params[f"{key}_high"]
    return getattr(tanh, f"{key}_low"), getattr(tanh, f"{key}_high")


def tanh_map(tanh, feature: torch.Tensor, low: torch.Tensor, high: torch.Tensor) -> torch.Tensor:
    """``TanhModule.forward``'s map on a tensor (the module maps tensordict entries only): tanh,
    the optional clamp off +-1, and the affine map onto ``[low, high]`` when not ``[-1, 1]``."""
    feature = feature.tanh()
    if tanh.clamp:
        eps = torch.finfo(feature.dtype).resolution
        feature = feature.clamp(-1 + eps, 1 - eps)
    if tanh.non_trivial:  # as TanhModule tests it (a dict of flags: the map always runs there too)
        feature = low + (high - low) * (feature + 1) / 2
    return feature


# ----------------------------------------------------------------------------- replay
def storage_tensordict(storage) -> TensorDictBase:
    """The TensorDict a ``TensorStorage`` writes into: every row of its capacity, written or not.

    ``TensorStorage.get`` (``storage[index]``) first slices it to the rows written, then indexes
    every entry it holds; a reader that needs a few entries of a few rows, every gradient step
    (:class:`~torchrl_sail.PrioritizedMixedReplayBuffer`), selects them first and indexes the
    selection. Reads ``TensorStorage._storage``, which a lazy storage creates at its first write.
    """
    return storage._storage


# ----------------------------------------------------------------------------- envs and transforms
def filtered_reset_keys(env) -> list:
    """``env``'s effective reset keys: ``EnvBase._filtered_reset_keys`` (``reset_keys`` without the
    nested ones no done key uses), what TorchRL's own transforms read their ``"_reset"`` from."""
    return list(env._filtered_reset_keys)


def reset_mask(reset_key, tensordict: TensorDictBase) -> torch.Tensor:
    """Which entries of ``tensordict`` a reset starts afresh: ``torchrl.envs.transforms.utils._get_reset``
    (the ``reset_key`` entry, all ``True`` when absent, reduced to the parent's batch shape)."""
    return _get_reset(reset_key, tensordict)


def multi_step(
    tensordict: TensorDictBase, *, done_key, done_keys, reward_keys, mask_key, n_steps: int, gamma: float
) -> TensorDictBase:
    """TorchRL's n-step computation of ``MultiStepTransform``: ``torchrl.data.postprocs.postprocs._multi_step_func``.

    The discounted sum of the next ``n_steps`` rewards within the episode, the observation it
    bootstraps from and ``"steps_to_next_obs"``, for a ``[..., time]`` tensordict.
    """
    return _multi_step_func(
        tensordict,
        done_key=done_key,
        done_keys=done_keys,
        reward_keys=reward_keys,
        mask_key=mask_key,
        n_steps=n_steps,
        gamma=gamma,
    )


def render_fps(env, default: int = 30) -> int:
    """The wrapped gymnasium env's ``metadata["render_fps"]`` (MuJoCo tasks: ``1 / dt``), else ``default``.

    ``env`` is a TorchRL env over a ``GymEnv`` (``env.base_env``), which hands attributes it does not
    have, such as ``metadata``, to the gymnasium env it wraps.
    """
    base = getattr(env, "base_env", env)
    return int(base.metadata.get("render_fps", default))


# ----------------------------------------------------------------------------- collectors
def set_ray_weight_sync_timeout(seconds: float) -> None:
    """Sets how long the learner waits for its Ray actors to join TorchRL's weight-sync group.

    ``RayWeightSyncScheme`` builds its ``TCPStore`` and gloo group with the module constant
    ``torchrl.weight_update._ray._DIST_TIMEOUT`` (60 s in torchrl 0.14, not a constructor argument;
    TorchRL's ``TORCHRL_WEIGHT_SYNC_TIMEOUT`` does not reach it). That wait includes Ray starting a
    fresh worker for the scheme's connection-info actor, which imports torch and TorchRL: on a
    loaded machine, longer than 60 s. The learner reads the constant when it connects, so setting
    it in the learner's process before the first weight push is enough: each actor's own 60 s
    starts once it has found that connection info. The group keeps the timeout for every later push.
    """
    from torchrl.weight_update import _ray  # imported here: Ray is optional

    _ray._DIST_TIMEOUT = timedelta(seconds=seconds)


# ----------------------------------------------------------------------------- tensordict
def fast_tensor_outputs() -> bool:
    """Make ``TensorDict.from_any`` return a plain tensor at once, as tensordict 0.15 does; ``True`` if patched.

    tensordict 0.14's ``TensorDictModule`` passes every output through ``TensorDict.from_any``,
    which, for a plain ``torch.Tensor``, tries each container kind it converts and then looks
    pandas up on ``sys.path`` (``importlib.util.find_spec``) before returning the tensor as it is:
    about 0.1 ms per output of every ``TensorDictModule`` call, e.g. the actor's at each
    evaluation step. tensordict 0.15 skips ``from_any`` for plain tensors; torchrl 0.14
    pins tensordict below 0.15, so this applies the same shortcut to ``TensorDictBase.from_any``.
    The result is the same object either way (0.14's ``from_any`` returns a plain tensor
    unchanged), so only the time changes. Idempotent; a no-op (``False``) from tensordict 0.15 on.
    The training scripts call it once at start; a pipeline of your own can call it the same way.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from torchrl_sail._compat import fast_tensor_outputs
        >>> _ = fast_tensor_outputs()
        >>> x = torch.zeros(3)
        >>> TensorDict.from_any(x) is x
        True
    """
    if tuple(int(part) for part in tensordict.__version__.split(".")[:2]) >= (0, 15):
        return False
    from_any = TensorDictBase.__dict__["from_any"].__func__
    if is_from_any_shortcut(from_any):
        return True

    @functools.wraps(from_any)  # the original is its __wrapped__
    def from_any_shortcut(cls, obj, *, auto_batch_size=False, batch_dims=None, device=None, batch_size=None):
        if type(obj) is torch.Tensor:  # which from_any returns as it is, whatever the keywords
            return obj
        return from_any(
            cls, obj, auto_batch_size=auto_batch_size, batch_dims=batch_dims, device=device, batch_size=batch_size
        )

    from_any_shortcut._torchrl_sail_shortcut = True
    TensorDictBase.from_any = classmethod(from_any_shortcut)
    return True


def is_from_any_shortcut(function) -> bool:
    """Whether ``function`` is :func:`fast_tensor_outputs`' ``from_any`` (another wrapper is not)."""
    return getattr(function, "_torchrl_sail_shortcut", False)


# ----------------------------------------------------------------------------- torch
#: torch's base class of the dropout layers (``torch.nn.modules.dropout._DropoutNd``): TD3Update
#: refuses an MLP holding one (its fused step has no train/eval mode).
DropoutLayer = nn.modules.dropout._DropoutNd


def native_bf16_matmul(device: torch.device | str) -> bool:
    """Whether bfloat16 matrix products on ``device`` run on bf16 hardware paths.

    On a CPU this is oneDNN's bf16 support (AVX-512 or AMX, ``torch.ops.mkldnn._is_mkldnn_bf16_supported``,
    which has no public alias). Without it torch falls back to a reference GEMM: on an AVX2-only
    AMD EPYC a 256 x 256 bf16 product ran at 1.4 GFLOP/s against 78 for fp32. On CUDA it is a GPU
    of compute capability 8.0 or more (Ampere on), where bf16 has tensor cores; older GPUs emulate it.
    """
    device = torch.device(device)
    if device.type == "cpu":
        try:
            return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
        except (AttributeError, RuntimeError):  # a torch built without oneDNN
            return False
    if device.type == "cuda":
        return torch.cuda.is_available() and torch.cuda.get_device_capability(device) >= (8, 0)
    return True
