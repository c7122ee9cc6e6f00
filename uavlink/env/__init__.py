"""The environment: batched numpy core, observation builder, action mapping, reward.

The Gymnasium face lives in ``uavlink.env.gym_env`` and the SB3 VecEnv in ``uavlink.env.vec_env``
(it imports stable-baselines3); neither is imported here, so the core stays light.
"""

from uavlink.env.actions import ActionMapping
from uavlink.env.core import BatchedUavEnv, GroundTruth, StepResult
from uavlink.env.observation import OBS_LAYOUT_VERSION, ObservationBuilder, ObservationLayout
from uavlink.env.reward import RewardBounds

__all__ = ["OBS_LAYOUT_VERSION", "ActionMapping", "BatchedUavEnv", "GroundTruth",
           "ObservationBuilder", "ObservationLayout", "RewardBounds", "StepResult"]
