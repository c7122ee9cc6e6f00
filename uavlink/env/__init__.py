"""The environment: batched numpy core, observation builder, action mapping, reward.

The Gymnasium face lives in ``uavlink.env.gym_env`` and the SB3 VecEnv in ``uavlink.env.vec_env``
(it imports stable-baselines3). Names are resolved on first use, so ``import uavlink`` (which only
registers the Gymnasium id) loads neither the core nor the radio and mobility layers below it.

May import: ``config``, ``errors``, ``seeding``, ``radio``, ``mobility``.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "ActionMapping": "actions",
    "BatchedUavEnv": "core",
    "GroundTruth": "core",
    "StepResult": "core",
    "OBS_LAYOUT_VERSION": "observation",
    "ObservationBuilder": "observation_builder",
    "ObservationLayout": "observation",
    "RewardBounds": "reward",
}
__all__ = sorted(_HOMES)


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module 'uavlink.env' has no attribute {name!r}")
    return getattr(importlib.import_module(f"uavlink.env.{_HOMES[name]}"), name)
