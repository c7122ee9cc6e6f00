"""The privileged critic (ours; ``TrainConfig.critic = "privileged"``): an asymmetric actor-critic.

PPO's critic only serves the training: no vehicle ever runs it. So in training it may read what no
vehicle senses, which makes its value estimates (and with them the advantages the actor learns
from) less noisy, while the actor, the part a policy file flies and exports, reads the observation
alone and stays GPS-free. ``PrivilegedVecEnv`` appends to every agent row's observation
``privileged_size(cfg)`` columns from the simulator's ground truth (``GroundTruth``):

- every UE's true position relative to this row's UAV, over the area's half width (U x 2, x then y
  per UE), in [-2, 2];
- every UE's true velocity over ``env.ue_speed_mps`` (U x 2; zeros when that is 0), in [-1, 1];
- the episode's progress, frames stepped over ``env.episode_frames``, in [0, 1]: the episode clock
  the paper's observation lacks, so the critic can tell a state near the end from one at the start.

The width is 4 U + 1 whatever the fleet's size D, so one policy can train on D = 2, 3 and 4 together
(``TrainConfig.fleet_sizes_up_to``: ``privileged_env`` wraps each size's part). PPO's
policy (``uavlink.policies.sb3_policy.PrivilegedCriticPolicy``) reads the first ``layout.size``
columns, the actor's observation, in its actor and all of them in its critic
(``uavlink.learn.training.policy_settings`` builds it). Imports stable-baselines3 (the VecEnv
wrapper's base class).
"""

from __future__ import annotations

import inspect

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvStepReturn, VecEnvWrapper

from uavlink.config import EnvConfig
from uavlink.env.core import GroundTruth
from uavlink.env.vec_env import FleetSizesVecEnv, UavVecEnv

__all__ = [
    "PrivilegedVecEnv",
    "privileged_bounds",
    "privileged_columns",
    "privileged_env",
    "privileged_size",
]


def privileged_size(cfg: EnvConfig) -> int:
    """How many columns the privileged critic reads after the actor's observation: 4 U + 1."""
    return 4 * cfg.n_ues + 1


def privileged_bounds(cfg: EnvConfig) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) float32 of the privileged columns (the module docstring's ranges)."""
    u = 2 * cfg.n_ues
    low = np.concatenate([np.full(u, -2.0), np.full(u, -1.0), [0.0]]).astype(np.float32)
    high = np.concatenate([np.full(u, 2.0), np.full(u, 1.0), [1.0]]).astype(np.float32)
    return low, high


def privileged_columns(truth: GroundTruth, cfg: EnvConfig) -> np.ndarray:
    """The privileged columns (N D, 4 U + 1) float32 of every agent row of ``truth`` (row i is UAV
    i % D of env i // D, as the core's rows)."""
    rows, d = truth.uav_xy_m.shape[0], cfg.n_uavs
    ue_xy = np.repeat(truth.ue_xy_m, d, axis=0)  # (N D, U, 2): each row's env's UEs
    relative = (ue_xy - truth.uav_xy_m[:, None, :]) / cfg.area.half_width_m
    speed = cfg.ue_speed_mps
    velocity = (
        np.repeat(truth.ue_velocity_mps, d, axis=0) / speed if speed > 0 else np.zeros_like(ue_xy)
    )
    progress = np.full((rows, 1), truth.frame / cfg.episode_frames)
    return np.concatenate(
        [relative.reshape(rows, -1), velocity.reshape(rows, -1), progress], axis=1
    ).astype(np.float32)


class PrivilegedVecEnv(VecEnvWrapper):
    """``UavVecEnv`` with the privileged columns appended to every row's observation, the returned
    ones and ``info["terminal_observation"]`` alike (that one from the last frame's ground truth,
    ``UavVecEnv.terminal_truth``, kept before the batch reset). The env itself is untouched: its
    steps, rewards and episodes are ``UavVecEnv``'s. A critic that reads other columns (a research
    variant) overrides ``bounds`` and ``columns``."""

    venv: UavVecEnv

    def __init__(self, venv: UavVecEnv) -> None:
        self.cfg = venv.core.cfg
        space = venv.observation_space
        assert isinstance(space, gym.spaces.Box)  # UavVecEnv's, a Box of the layout's bounds
        low, high = self.bounds()
        wide = gym.spaces.Box(
            np.concatenate([space.low, low]), np.concatenate([space.high, high]), dtype=np.float32
        )
        super().__init__(venv, observation_space=wide)

    def __getstate__(self) -> dict:
        # SB3's VecEnvWrapper keeps its class's members (a mappingproxy among them), which do not
        # pickle; a training snapshot (uavlink.learn.snapshot) pickles the env stack
        state = self.__dict__.copy()
        del state["class_attributes"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.class_attributes = dict(inspect.getmembers(self.__class__))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of the appended columns."""
        return privileged_bounds(self.cfg)

    def columns(self, truth: GroundTruth) -> np.ndarray:
        """The appended columns (N D, width) of every agent row of ``truth``."""
        return privileged_columns(truth, self.cfg)

    def _widen(self, obs: np.ndarray, truth: GroundTruth) -> np.ndarray:
        return np.concatenate([obs, self.columns(truth)], axis=1)

    def reset(self) -> np.ndarray:
        obs = self.venv.reset()
        assert isinstance(obs, np.ndarray)  # UavVecEnv's: (N D, obs)
        return self._widen(obs, self.venv.core.ground_truth())

    def step_wait(self) -> VecEnvStepReturn:
        obs, reward, dones, infos = self.venv.step_wait()
        assert isinstance(obs, np.ndarray)  # UavVecEnv's: (N D, obs)
        if dones.any():
            truth = self.venv.terminal_truth
            assert truth is not None  # UavVecEnv keeps it on every step that ends episodes
            last = self.columns(truth)
            for i, info in enumerate(infos):
                if "terminal_observation" in info:
                    info["terminal_observation"] = np.concatenate(
                        [info["terminal_observation"], last[i]]
                    )
        # after an episode's end the core has reset: its truth is the new episode's first frame
        return self._widen(obs, self.venv.core.ground_truth()), reward, dones, infos


def privileged_env(env: VecEnv) -> VecEnv:
    """The training's env with the privileged columns: ``env`` wrapped, or for several fleet sizes
    trained together (``TrainConfig.fleet_sizes_up_to``) each size's part wrapped (the columns' width
    is the same for every size, so the parts still give one observation)."""
    if isinstance(env, FleetSizesVecEnv):
        parts = [part for part in env.parts if isinstance(part, UavVecEnv)]
        assert len(parts) == len(env.parts)  # FleetSizesVecEnv.for_sizes builds UavVecEnv parts
        return FleetSizesVecEnv([PrivilegedVecEnv(part) for part in parts])
    assert isinstance(env, UavVecEnv)  # make_model's one env of one fleet size
    return PrivilegedVecEnv(env)
