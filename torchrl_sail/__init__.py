"""torchrl_sail: Self-Adaptive Imitation Learning (SAIL) as TorchRL components.

The public names are importable from the top level, e.g.
``from torchrl_sail import DelayedRewardTransform, SAILLoss``.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0.dev0"

# public name -> submodule that defines it (resolved on first access, PEP 562)
_EXPORTS = {
    "DelayedRewardTransform": "torchrl_sail.envs.delayed_reward",
    "TimeFeature": "torchrl_sail.envs.time_feature",
    "DiscriminatorReward": "torchrl_sail.envs.discriminator_reward",
    "Discriminator": "torchrl_sail.modules.discriminator",
    "DiscriminatorNet": "torchrl_sail.modules.discriminator",
    "RunningObsNorm": "torchrl_sail.modules.discriminator",
    "DiscriminatorLoss": "torchrl_sail.objectives.discriminator",
    "SAILLoss": "torchrl_sail.objectives.sail",
    "AlphaScheduler": "torchrl_sail.objectives.alpha",
    "TopKTeacherReplayBuffer": "torchrl_sail.data.teacher_buffer",
    "MixedReplayBuffer": "torchrl_sail.data.mixed_buffer",
    "Demonstrations": "torchrl_sail.data.demonstrations",
    "load_sb_demonstrations": "torchrl_sail.data.demonstrations",
    "load_demonstrations": "torchrl_sail.data.demonstrations",
    "save_demonstrations": "torchrl_sail.data.demonstrations",
    "check_demonstration_dims": "torchrl_sail.data.demonstrations",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'torchrl_sail' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__():
    return __all__
