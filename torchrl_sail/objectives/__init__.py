"""Losses: SAIL's alpha-mixed TD3 loss, its alpha schedule, the discriminator loss, and the TD3 step."""

from torchrl_sail.objectives.alpha import AlphaScheduler
from torchrl_sail.objectives.discriminator import DiscriminatorLoss
from torchrl_sail.objectives.sail import SAILLoss
from torchrl_sail.objectives.td3_update import TD3Update

__all__ = ["AlphaScheduler", "DiscriminatorLoss", "SAILLoss", "TD3Update"]
