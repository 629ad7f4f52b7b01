"""Neural network modules: the SAIL discriminator D(s, a)."""

from torchrl_sail.modules.discriminator import Discriminator, DiscriminatorNet, RunningObsNorm

__all__ = ["Discriminator", "DiscriminatorNet", "RunningObsNorm"]
