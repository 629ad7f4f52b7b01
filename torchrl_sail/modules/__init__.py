"""Neural network modules: the SAIL discriminator D(s, a)."""

from torchrl_sail.modules.discriminator import Discriminator, DiscriminatorNet, RunningObsNorm
from torchrl_sail.modules.exploration import TD3ExplorationPolicy

__all__ = ["Discriminator", "DiscriminatorNet", "RunningObsNorm", "TD3ExplorationPolicy"]
