"""Stable-Baselines3 ``VecEnv`` face of the batched core, for training.

Follows SB3's contract: on the last frame of an episode the env is reset automatically, the returned
observation is the new episode's first, and ``info["terminal_observation"]`` holds the last one,
with ``TimeLimit.truncated`` so PPO bootstraps the value of the cut-off state. ``info["episode"]``
carries the episode return and length (as SB3's Monitor would) plus the mean UE throughput.
A fleet of D UAVs flattens N episodes x D UAVs into N D rows (the core's agent rows), so one
parameter-shared policy acts for every UAV; each row's return is its env's team return.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvObs, VecEnvStepReturn

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv


class UavVecEnv(VecEnv):
    def __init__(self, cfg: EnvConfig, n_envs: int, seed: int | None = None) -> None:
        self.core = BatchedUavEnv(cfg, n_envs=n_envs, seed=seed)
        obs_space = gym.spaces.Box(*self.core.layout.bounds(), dtype=np.float32)
        act_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.render_mode = None
        super().__init__(self.core.n_rows, obs_space, act_space)
        self._actions: np.ndarray | None = None
        self._next_seed: int | None = seed
        self._start = time.time()
        self._returns = np.zeros(self.core.n_rows)
        self._rate_sums = np.zeros(n_envs)

    def reset(self) -> VecEnvObs:
        obs = self.core.reset(self._next_seed)
        self._next_seed = None
        self._returns[:] = 0.0
        self._rate_sums[:] = 0.0
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        result = self.core.step(self._actions)
        self._returns += result.reward
        self._rate_sums += result.mean_rate_mbps
        dones = result.truncated | result.terminated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        obs = result.observation
        if dones.any():  # fixed-length episodes: the whole batch ends together
            frames = self.core.frame
            for i, info in enumerate(infos):
                info["terminal_observation"] = obs[i]
                info["TimeLimit.truncated"] = bool(result.truncated[i] and not result.terminated[i])
                info["episode"] = {"r": float(self._returns[i]), "l": frames,
                                   "t": round(time.time() - self._start, 6),
                                   "mean_rate_mbps": float(self._rate_sums[i // self.core.n_uavs] / frames)}
            obs = self.reset()
        return obs, result.reward.astype(np.float32), dones, infos

    def close(self) -> None:
        pass

    def seed(self, seed: int | None = None) -> Sequence[None | int]:
        self._next_seed = seed
        return [seed] * self.num_envs

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        owner = self.core if hasattr(self.core, attr_name) else self  # e.g. render_mode lives here
        return [getattr(owner, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.core, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        return [getattr(self.core, method_name)(*args, **kwargs)] * len(self._get_indices(indices))

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._get_indices(indices))
