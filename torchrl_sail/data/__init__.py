"""torchrl_sail.data."""
