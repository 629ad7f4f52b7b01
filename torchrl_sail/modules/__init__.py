"""torchrl_sail.modules."""
