"""Gymnasium face of the batched core: one episode, ``gymnasium.make("uavlink/UavBs-v0")``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.errors import ConfigError, UserError


def config_with(config: EnvConfig, named: dict[str, Any], overrides: dict[str, Any]) -> EnvConfig:
    """``config`` with the named arguments that were given (not None) and ``overrides`` applied, so
    ``make(..., config=cfg, scenario="hotspot")`` flies hotspot rather than dropping the argument."""
    if not isinstance(config, EnvConfig):
        raise ConfigError(
            f"config must be an EnvConfig (uavlink.config.EnvConfig), got {type(config).__name__} "
            f"{config!r}; or pass scenario=... and fields by name"
        )
    changes = {key: value for key, value in named.items() if value is not None} | overrides
    return config.replace(**changes).validate() if changes else config.validate()


class UavBsEnv(gym.Env):
    """One UAV's episode as a Gymnasium env (``gymnasium.make("uavlink/UavBs-v0", scenario=...,
    n_ues=..., **{"radio.shadowing": False})``): the observation is the layout's float32 Box (docs/design/learning.md, "Observation"),
    the action a move in Box(-1, 1, (2,)) (``EnvConfig.action_mapping``). An episode ends by
    truncation after ``episode_frames`` steps; the info after a step carries the frame's
    ``mean_rate_mbps`` (mean UE throughput, Mbit/s) and ``fair_rate`` (R_fair, the sum over UEs of
    log10 of the rate in bit/s). A fleet (``n_uavs > 1``) is the PettingZoo face's,
    ``uavlink.fleet.parallel_env``. Nothing is rendered: flights are drawn by ``uavlink plot``."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: str | None = None,
        aoa_noise_deg: float | None = None,
        *,
        config: EnvConfig | None = None,
        render_mode: str | None = None,
        **overrides: Any,
    ) -> None:
        super().__init__()
        if render_mode is not None:
            raise UserError(
                f"render_mode {render_mode!r} is not supported; the env renders nothing "
                "(a flight's picture: uavlink plot)"
            )
        self.render_mode = None
        cfg = config_with(
            config if config is not None else EnvConfig(),
            {"scenario": scenario, "aoa_noise_deg": aoa_noise_deg},
            overrides,
        )
        if cfg.n_uavs > 1:
            raise UserError(
                f"n_uavs={cfg.n_uavs}: a fleet has one observation and action per UAV; "
                "use uavlink.fleet.parallel_env (PettingZoo) or uavlink.env.vec_env.UavVecEnv"
            )
        self.core = BatchedUavEnv(cfg, n_envs=1)
        self.config = self.core.cfg
        self.layout = self.core.layout
        self.observation_space = gym.spaces.Box(*self.layout.bounds(), dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self._running = False

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode (the UAV over the team's start); ``options`` are accepted and unused."""
        super().reset(seed=seed)
        if seed is None and not hasattr(self, "_seeded"):
            seed = int(self.np_random.integers(2**63 - 1))  # unseeded: draw one, as Gymnasium does
        self._seeded = True
        obs = self.core.reset(seed)
        self._running = True
        return obs[0], {}

    def step(self, action):
        """Move the UAV by ``action`` and advance a frame: (observation, reward, False, truncated, info)."""
        if not self._running:
            raise RuntimeError("the episode has ended (or not begun): call reset()")
        move = np.asarray(action, dtype=float)
        if move.shape not in ((2,), (1, 2)):
            raise UserError(f"the action has shape (2,) (the action space's), got {move.shape}")
        result = self.core.step(move.reshape(1, 2))
        info = {
            "mean_rate_mbps": float(result.mean_rate_mbps[0]),
            "fair_rate": float(result.fair_rate[0]),
        }
        truncated = bool(result.truncated[0])
        self._running = not truncated
        return (result.observation[0], float(result.reward[0]), False, truncated, info)

    def render(self) -> None:
        """No render modes (``metadata["render_modes"]`` is empty)."""
        return None
