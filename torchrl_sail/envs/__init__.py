"""Environment transforms: the delayed-reward setting, the time feature, the imitation reward, the SAIL env stack."""
from torchrl_sail.envs.delayed_reward import DelayedRewardTransform
from torchrl_sail.envs.discriminator_reward import DiscriminatorReward
from torchrl_sail.envs.make import make_sail_env
from torchrl_sail.envs.time_feature import TimeFeature

__all__ = ["DelayedRewardTransform", "DiscriminatorReward", "TimeFeature", "make_sail_env"]
