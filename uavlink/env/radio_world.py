"""The radio world a flying vehicle lives in: the env's UE mobility and channel, stepped at the
positions the vehicle actually reaches instead of at positions mapped from actions.

The SITL's radio payload is its user: it asks for the readings the base station senses and, once a
frame, advances the world with the vehicle's position. Episode 0 of the evaluation stream
(``uavlink.seeding.EVAL``) with seed S: a flight with ``--seed S`` meets the UEs of
``uavlink evaluate --episodes 1 --seed S``. It holds the config's ``n_uavs`` UAVs: a fleet of SITL
vehicles shares one world (``sitl_stub.fleet``), each vehicle's payload reporting its UAV's readings,
and the world advances once per frame with every vehicle's position.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from uavlink.config import MIXED, SCENARIOS, EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.seeding import EVAL


@dataclass(frozen=True)
class UavReadings:
    """What one UAV's base station senses this frame (the policy's input)."""

    sinr_db: np.ndarray  # (U,) effective SINR per UE
    aoa_deg: np.ndarray  # (U,) measured angle of arrival per UE, deg from east
    serves: np.ndarray  # (U,) bool: the UEs attached to this UAV (its cell; every UE for one UAV)


@dataclass(frozen=True)
class FrameScore:
    """The simulator's truth for one advanced frame (for scoring and logs, never for the policy)."""

    mean_rate_mbps: float
    fair_rate: float
    rate_bps: np.ndarray  # (U,) per-UE rate


class RadioWorld:
    """UEs and channel of one episode, advanced one frame at a time at given UAV positions."""

    def __init__(self, cfg: EnvConfig, seed: int) -> None:
        self.cfg = cfg.validate()
        self.n_uavs = self.cfg.n_uavs
        # its UAVs are vehicles flown by their position loop: the world starts them where a
        # PX4-motion evaluation does (a lockstep flight's replay; only the start differs here, as
        # the world moves its UAVs with step_to)
        flown = replace(self.cfg, uav_motion="px4")
        self._env = BatchedUavEnv(flown, n_envs=1, seed=EVAL.seed(seed, 0))
        self._env.reset()

    @property
    def scenario(self) -> str:
        """The UE mobility scenario of this episode: the config's, or the one ``mixed`` drew for it
        (the env's own draw, so it is the scenario evaluation's episode 0 of this seed flies)."""
        return SCENARIOS[int(self._env.scenario_ids[0])]

    @property
    def frame(self) -> int:
        """Frames advanced since the episode started (0 before the first :meth:`advance`)."""
        return self._env.frame

    def readings(self, uav: int = 0) -> UavReadings:
        """The current frame's readings at UAV ``uav`` (index into the world's UAVs)."""
        r = self._env.readings
        assert r is not None  # the env was reset in __init__
        return UavReadings(r.heard_sinr_db[0, uav], r.heard_aoa_deg[0, uav], r.serving[0] == uav)

    def ue_xy_m(self) -> np.ndarray:
        """(U, 2) the UEs' true positions now, metres east and north (truth: for pictures only)."""
        assert self._env.mobility is not None  # the env was reset in __init__
        return self._env.mobility.position_m[0].copy()

    def ue_velocity_mps(self) -> np.ndarray:
        """(U, 2) the UEs' true velocities now, m/s east and north (truth: for pictures only)."""
        assert self._env.mobility is not None  # the env was reset in __init__
        return self._env.mobility.velocity_mps[0].copy()

    def advance(self, uav_xy_m: npt.ArrayLike) -> FrameScore:
        """Move the UEs one frame with the UAVs at ``uav_xy_m`` ((n_uavs, 2) or (2,), metres east
        and north, clipped to the area) and score the new frame."""
        xy = np.asarray(uav_xy_m, dtype=float).reshape(self.n_uavs, 2)
        result = self._env.step_to(xy)
        assert self._env.readings is not None  # step_to() set them
        return FrameScore(
            float(result.mean_rate_mbps[0]),
            float(result.fair_rate[0]),
            self._env.readings.rate_bps[0].copy(),
        )


def episode_scenario(cfg: EnvConfig, seed: int) -> str:
    """The scenario episode 0 of ``seed`` flies (a vehicle's episode of that seed, and ``uavlink
    evaluate --episodes 1 --seed``): ``cfg``'s own, or for ``mixed`` the one drawn for that seed."""
    return cfg.scenario if cfg.scenario != MIXED else RadioWorld(cfg, seed).scenario
