"""Losses: SAIL's alpha-mixed TD3 loss, its alpha schedule, and the discriminator loss."""
from torchrl_sail.objectives.alpha import AlphaScheduler
from torchrl_sail.objectives.discriminator import DiscriminatorLoss
from torchrl_sail.objectives.sail import SAILLoss

__all__ = ["AlphaScheduler", "DiscriminatorLoss", "SAILLoss"]
