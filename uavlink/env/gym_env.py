"""Gymnasium face of the batched core: one episode, ``gymnasium.make("uavlink/UavBs-v0")``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv


def make_config(scenario: str = "circular", aoa_noise_deg: float = 0.0, **overrides: Any) -> EnvConfig:
    """An EnvConfig from the SPEC defaults plus keyword overrides (``radio.x`` or plain field names)."""
    return EnvConfig().replace(scenario=scenario, aoa_noise_deg=aoa_noise_deg, **overrides).validate()


class UavBsEnv(gym.Env):
    """Single-episode Gymnasium env; observation and action spaces as in the SPEC."""

    metadata = {"render_modes": []}

    def __init__(self, scenario: str = "circular", aoa_noise_deg: float = 0.0,
                 config: EnvConfig | None = None, **overrides: Any) -> None:
        super().__init__()
        cfg = config if config is not None else make_config(scenario, aoa_noise_deg, **overrides)
        self.core = BatchedUavEnv(cfg, n_envs=1)
        self.config = self.core.cfg
        self.layout = self.core.layout
        self.observation_space = gym.spaces.Box(*self.layout.bounds(), dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None and not hasattr(self, "_seeded"):
            seed = int(self.np_random.integers(2**63 - 1))  # unseeded: draw one, as Gymnasium does
        self._seeded = True
        obs = self.core.reset(seed)
        return obs[0], {}

    def step(self, action):
        result = self.core.step(np.asarray(action, dtype=float).reshape(1, -1)
                                if np.ndim(action) == 1 else action)
        info = {"mean_rate_mbps": float(result.mean_rate_mbps[0]), "fair_rate": float(result.fair_rate[0])}
        return (result.observation[0], float(result.reward[0]), False, bool(result.truncated[0]), info)
