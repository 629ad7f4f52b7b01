"""TD3's exploration policy as one module: the actor's MLP, TanhModule's map and AdditiveGaussianModule's noise.

TorchRL's exploration policy for TD3 is a sequence of three TensorDict modules (the MLP, the
``TanhModule``, the ``AdditiveGaussianModule``), each reading and writing the tensordict of every
env step. At SAIL's sizes ([400, 300] actor, one env) that bookkeeping costs more than the
products (``benchmarks/bench_collect.py``). :class:`TD3ExplorationPolicy` computes the same
action from the same modules in one read and one write.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictModuleBase, TensorDictSequential
from torchrl.envs.utils import ExplorationType, exploration_type
from torchrl.modules import AdditiveGaussianModule, TanhModule

from torchrl_sail._compat import tanh_bounds, tanh_map

__all__ = ["TD3ExplorationPolicy"]


class TD3ExplorationPolicy(TensorDictModuleBase):
    """``TensorDictSequential(actor, noise)`` as one module, for collection.

    Computes what TorchRL's sequence computes: the actor's MLP on its ``in_keys``, the
    ``TanhModule`` map onto the action bounds, and, in ``ExplorationType.RANDOM`` mode (or with
    no mode set), ``AdditiveGaussianModule``'s noise ``N(mean, std) * sigma`` drawn with the same
    call (a seeded call gives the same action), then projected onto the noise module's spec.
    In deterministic modes the noise is left out, as the noise module does. It holds the same
    modules, so optimizer steps on the actor, ``noise.step()`` annealing and
    ``update_policy_weights_()`` reach it.

    It writes the action only: the MLP's output (the ``TanhModule``'s input key, e.g.
    ``"param"``) is not written into the collected tensordict.

    Args:
        actor (TensorDictSequential): ``TensorDictSequential(TensorDictModule(MLP), TanhModule)``,
            the TD3 actor (the one the loss trains).
        noise (AdditiveGaussianModule, optional): the exploration noise on the actor's action;
            ``None`` acts with the actor alone. Defaults to ``None``.

    Examples:
        >>> import torch
        >>> from tensordict import TensorDict
        >>> from tensordict.nn import TensorDictModule, TensorDictSequential
        >>> from torchrl.data import Bounded
        >>> from torchrl.modules import MLP, AdditiveGaussianModule, TanhModule
        >>> from torchrl_sail import TD3ExplorationPolicy
        >>> spec = Bounded(-1.0, 1.0, (2,))
        >>> actor = TensorDictSequential(
        ...     TensorDictModule(MLP(in_features=3, out_features=2, num_cells=[16]), ["observation"], ["param"]),
        ...     TanhModule(["param"], ["action"], spec=spec))
        >>> noise = AdditiveGaussianModule(spec=spec, sigma_init=1.0, sigma_end=1.0, std=0.1)
        >>> policy = TD3ExplorationPolicy(actor, noise)
        >>> td = TensorDict({"observation": torch.randn(3)}, [])
        >>> _ = torch.manual_seed(0)
        >>> fused = policy(td.clone())["action"]
        >>> _ = torch.manual_seed(0)
        >>> torch.equal(fused, TensorDictSequential(actor, noise)(td.clone())["action"])
        True
    """

    def __init__(self, actor: TensorDictSequential, noise: AdditiveGaussianModule | None = None) -> None:
        super().__init__()
        unsupported = self._unsupported(actor)
        if unsupported:
            raise TypeError(unsupported)
        body, tanh = actor.module
        action_key = tanh.out_keys[0]
        if noise is not None:
            if not isinstance(noise, AdditiveGaussianModule):
                raise TypeError(f"noise must be an AdditiveGaussianModule or None, got {type(noise).__name__}.")
            if noise.action_key != action_key:
                raise ValueError(f"the noise module perturbs {noise.action_key!r}, the actor writes {action_key!r}.")
            if noise.spec is None:
                raise ValueError("the noise module has no spec: pass AdditiveGaussianModule(spec=...).")
        self.mlp = body.module
        self.tanh = tanh
        self.noise = noise
        self.in_keys = list(body.in_keys)
        self.out_keys = [action_key]

    @classmethod
    def supports(cls, actor) -> bool:
        """Whether ``actor`` is what this policy fuses: ``TensorDictSequential(TensorDictModule(MLP),
        TanhModule)``, the TanhModule mapping the MLP's output to one action (a TD3 actor; not SAC's
        or PPO's)."""
        return cls._unsupported(actor) is None

    @staticmethod
    def _unsupported(actor) -> str | None:
        """Why ``actor`` is not a TD3 actor this policy fuses, or ``None``."""
        if not (
            isinstance(actor, TensorDictSequential)
            and len(actor.module) == 2
            and type(actor.module[0]) is TensorDictModule
            and isinstance(actor.module[1], TanhModule)
        ):
            return (
                "TD3ExplorationPolicy needs the actor to be TensorDictSequential(TensorDictModule(MLP), "
                f"TanhModule), got {actor!r}."
            )
        body, tanh = actor.module
        if list(tanh.in_keys) != list(body.out_keys) or len(tanh.out_keys) != 1:
            return (
                f"TD3ExplorationPolicy needs the TanhModule to map the MLP's output to one action; got "
                f"{body.out_keys} -> {tanh.in_keys} -> {tanh.out_keys}."
            )
        return None

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        feature = self.mlp(*(tensordict.get(key) for key in self.in_keys))
        action = tanh_map(self.tanh, feature, *tanh_bounds(self.tanh))
        noise = self.noise
        if noise is not None and exploration_type() in (ExplorationType.RANDOM, None):
            # AdditiveGaussianModule._add_noise: the same draw; its spec's projection is a clamp
            # onto [low, high] (the identity inside the box)
            mean, std = noise.mean.expand(action.shape), noise.std.expand(action.shape)
            if not mean.dtype.is_floating_point:
                mean = mean.to(torch.get_default_dtype())
            if not std.dtype.is_floating_point:
                std = std.to(torch.get_default_dtype())
            drawn = torch.normal(mean=mean, std=std).to(action.device)
            space = noise.spec[self.out_keys[0]].space
            low, high = space.low.to(action.device), space.high.to(action.device)
            action = torch.clamp(action + drawn * noise.sigma, low, high)
        tensordict.set(self.out_keys[0], action)
        return tensordict
