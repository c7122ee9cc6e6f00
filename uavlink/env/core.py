"""The batched environment core: N independent episodes stepped together as numpy arrays.

Per frame: the UAV moves by the mapped action (clipped to the area, its geofence), the UEs move,
the channel reports SINR/AoA/rates at the new positions, the reward is the normalised R_fair.
Episodes have a fixed length, so all N envs start and end together; ``reset`` restarts the batch.
Mobility, radio and AoA noise draw from separate streams of one seed, so two policies evaluated with
the same seed see the same UE trajectories (common random numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationBuilder, ObservationLayout
from uavlink.env.reward import RewardBounds
from uavlink.mobility import draw_scenarios, init_mobility, step_mobility
from uavlink.radio.channel import RadioChannel, RadioReadings
from uavlink.radio.rates import fair_rate


@dataclass
class GroundTruth:
    """What only the simulator knows (for the oracle baseline and plots; never observed)."""

    uav_xy_m: np.ndarray  # (N, 2)
    ue_xy_m: np.ndarray  # (N, U, 2)
    ue_velocity_mps: np.ndarray  # (N, U, 2)
    scenario_ids: np.ndarray  # (N,)


@dataclass
class StepResult:
    observation: np.ndarray  # (N, obs) float32
    reward: np.ndarray  # (N,)
    terminated: np.ndarray  # (N,) bool, always False: no terminal states
    truncated: np.ndarray  # (N,) bool, True at the last frame
    mean_rate_mbps: np.ndarray  # (N,) mean UE rate of the frame
    fair_rate: np.ndarray  # (N,)


class BatchedUavEnv:
    """N aerial-base-station episodes as arrays; the physics behind both env faces."""

    def __init__(self, cfg: EnvConfig | None = None, n_envs: int = 1,
                 seed: int | np.random.SeedSequence | None = None) -> None:
        self.cfg = (cfg or EnvConfig()).validate()
        if int(n_envs) != n_envs or n_envs < 1:
            raise ValueError(f"n_envs must be a positive integer, got {n_envs}")
        self.n_envs = int(n_envs)
        self.layout = ObservationLayout.for_config(self.cfg)
        self.actions = ActionMapping.for_config(self.cfg)
        self.reward_bounds = RewardBounds.for_config(self.cfg)
        self.channel = RadioChannel(self.cfg.radio, self.cfg.area, self.cfg.n_ues)
        self._builder = ObservationBuilder(self.layout, self.n_envs)
        self._seed(seed)
        self.frame = 0
        self.uav_xy_m = np.zeros((self.n_envs, 2))
        self.mobility = None
        self.readings: RadioReadings | None = None

    def _seed(self, seed: int | np.random.SeedSequence | None) -> None:
        if not isinstance(seed, np.random.SeedSequence):
            seed = np.random.SeedSequence(seed)
        streams = seed.spawn(2)
        self.mobility_rng, self.radio_rng = (np.random.default_rng(s) for s in streams)

    def reset(self, seed: int | np.random.SeedSequence | None = None) -> np.ndarray:
        """Start N new episodes (UAV at the centre); returns the observations (N, obs)."""
        if seed is not None:
            self._seed(seed)
        self.frame = 0
        self.scenario_ids = draw_scenarios(self.mobility_rng, self.cfg.scenario, self.n_envs)
        self.mobility = init_mobility(self.mobility_rng, self.scenario_ids, self.cfg)
        self.uav_xy_m = np.zeros((self.n_envs, 2))
        self.readings = self.channel.reset(self.radio_rng, self.uav_xy_m[:, None, :],
                                           self.mobility.position_m)
        return self._builder.reset(self.uav_xy_m, self.readings.sinr_db, self.readings.aoa_deg)

    def step(self, action: np.ndarray) -> StepResult:
        """Advance every env one frame with actions (N, 2) in [-1, 1]."""
        if self.mobility is None:
            raise RuntimeError("call reset() before step()")
        action = self.actions.validate(action, self.n_envs)
        return self.step_to(self.uav_xy_m + self.actions.to_displacement_m(action))

    def step_to(self, uav_xy_m: np.ndarray) -> StepResult:
        """Advance one frame with the UAVs at the given positions (N, 2), clipped to the area.

        ``step`` uses it after mapping actions; the SITL radio payload uses it with the vehicle's
        actual position, so flight and simulation share one frame update.
        """
        if self.mobility is None:
            raise RuntimeError("call reset() before step_to()")
        half = self.cfg.area.half_width_m
        self.uav_xy_m = np.clip(np.asarray(uav_xy_m, dtype=float).reshape(self.n_envs, 2), -half, half)
        step_mobility(self.mobility, self.cfg.frame_s, half)
        self.readings = self.channel.step(self.radio_rng, self.uav_xy_m[:, None, :],
                                          self.mobility.position_m)
        self.frame += 1
        obs = self._builder.push(self.uav_xy_m, self.readings.sinr_db, self.readings.aoa_deg)
        fair = fair_rate(self.readings.rate_bps)
        done = self.frame >= self.cfg.episode_frames
        return StepResult(
            observation=obs,
            reward=self.reward_bounds.normalise(fair),
            terminated=np.zeros(self.n_envs, dtype=bool),
            truncated=np.full(self.n_envs, done),
            mean_rate_mbps=self.readings.rate_bps.mean(axis=1) * 1e-6,
            fair_rate=fair,
        )

    def ground_truth(self) -> GroundTruth:
        return GroundTruth(self.uav_xy_m.copy(), self.mobility.position_m.copy(),
                           self.mobility.velocity_mps.copy(), self.scenario_ids.copy())
