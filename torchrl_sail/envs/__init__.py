"""Environment transforms: the delayed-reward setting, the time feature, the imitation reward,
DAC's absorbing state, a sample-time RND bonus, the SAIL env stack, DDPGfD's n-step view."""

from torchrl_sail.envs.absorbing import AbsorbingStateTransform
from torchrl_sail.envs.delayed_reward import DelayedRewardTransform
from torchrl_sail.envs.discriminator_reward import DiscriminatorReward
from torchrl_sail.envs.make import SEED_STRIDE, make_sail_env, observation_normalizer
from torchrl_sail.envs.nstep import NStepTransform, nstep_view
from torchrl_sail.envs.rnd_reward import RNDReward
from torchrl_sail.envs.time_feature import TimeFeature

__all__ = [
    "AbsorbingStateTransform",
    "DelayedRewardTransform",
    "DiscriminatorReward",
    "NStepTransform",
    "RNDReward",
    "TimeFeature",
    "SEED_STRIDE",
    "make_sail_env",
    "nstep_view",
    "observation_normalizer",
]
