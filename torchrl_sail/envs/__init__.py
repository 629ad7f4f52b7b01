"""torchrl_sail.envs."""
