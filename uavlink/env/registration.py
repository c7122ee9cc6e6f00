"""Gymnasium registration, in one place."""

from __future__ import annotations

import gymnasium as gym

ENV_ID = "uavlink/UavBs-v0"


def register_envs() -> None:
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="uavlink.env.gym_env:UavBsEnv")
