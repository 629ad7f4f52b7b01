"""torchrl_sail.objectives."""
