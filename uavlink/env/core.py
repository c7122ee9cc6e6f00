"""The batched environment core: N independent episodes stepped together as numpy arrays.

Per frame: each UAV moves by its mapped action (clipped to the area, its geofence, and for a fleet
shortened by the separation filter; with ``uav_motion="px4"`` the action moves the UAV's setpoint
that way, a fleet's through the flight loop's own code with its transit guard, and the UAV flies
towards it as PX4 does), the UEs move, the channel reports SINR/AoA/rates at the new positions, the
reward is the normalised R_fair of all UEs (one team reward for a fleet). The core
speaks in agent rows: row i is UAV i % D of env i // D (D = ``n_uavs``), so one UAV gives the
paper's (N, obs) / (N, 2) and a fleet of D gives N D rows for one parameter-shared policy.
Episodes have a fixed length, so all N envs start and end together; ``reset`` restarts the batch.
Mobility, radio and AoA noise draw from separate streams of one seed, so two policies evaluated with
the same seed see the same UE trajectories (common random numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import EnvConfig
from uavlink.config.env import MOTION_PX4
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationLayout, fleet_view_quantities
from uavlink.env.observation_builder import ObservationBuilder
from uavlink.env.place_memory import PlaceMemory
from uavlink.env.reward import RewardBounds
from uavlink.mobility import MobilityState, draw_scenarios, init_mobility, step_mobility
from uavlink.mobility.fleet import apply_moves, next_setpoints, start_positions_m
from uavlink.mobility.uav_motion import PX4_MOTION
from uavlink.radio.channel import RadioChannel, RadioReadings
from uavlink.radio.rates import fair_rate
from uavlink.radio.spatial_shadowing import SpatialShadowField


@dataclass
class GroundTruth:
    """What only the simulator knows (for the privileged baselines and plots; never observed).

    The GPS baselines read positions and velocities; the genie (``uavlink.policies.genie``) also
    reads the episode's future: the UEs' kinematic state (their motion is deterministic from it)
    and the spatial shadowing field."""

    uav_xy_m: np.ndarray  # (N D, 2) agent rows
    ue_xy_m: np.ndarray  # (N, U, 2)
    ue_velocity_mps: np.ndarray  # (N, U, 2)
    scenario_ids: np.ndarray  # (N,)
    frame: int = 0  # frames stepped since reset
    mobility: MobilityState | None = None  # a copy of the UEs' state
    # The episode's shadowing field; None on AR(1) or without shadowing.
    shadow_field: SpatialShadowField | None = None


@dataclass
class StepResult:
    observation: np.ndarray  # (N D, obs) float32, agent rows
    reward: np.ndarray  # (N D,) the env's (team) reward on each of its rows
    terminated: np.ndarray  # (N D,) bool, always False: no terminal states
    truncated: np.ndarray  # (N D,) bool, True at the last frame
    mean_rate_mbps: np.ndarray  # (N,) mean UE rate of the frame, per env
    fair_rate: np.ndarray  # (N,) per env


class BatchedUavEnv:
    """N aerial-base-station episodes as arrays; the physics behind both env faces."""

    def __init__(
        self,
        cfg: EnvConfig | None = None,
        n_envs: int = 1,
        seed: int | np.random.SeedSequence | None = None,
    ) -> None:
        self.cfg = (cfg or EnvConfig()).validate()
        if int(n_envs) != n_envs or n_envs < 1:
            raise ValueError(f"n_envs must be a positive integer, got {n_envs}")
        self.n_envs = int(n_envs)
        self.n_uavs = self.cfg.n_uavs
        self.n_rows = self.n_envs * self.n_uavs
        self.layout = ObservationLayout.for_config(self.cfg)
        self.actions = ActionMapping.for_config(self.cfg)
        self.reward_bounds = RewardBounds.for_config(self.cfg)
        self.channel = RadioChannel(
            self.cfg.radio, self.cfg.area, self.cfg.n_ues, self.cfg.fleet_reuse
        )
        self._builder = ObservationBuilder(self.layout, self.n_rows, self.n_uavs)
        self._start_xy_m = self._as_carried(
            np.tile(start_positions_m(self.n_uavs, self.cfg.fleet_start_radius_m), (self.n_envs, 1))
        )  # with uav_motion px4, where a vehicle holding its reported position holds
        self._seed(seed)
        self.frame = 0
        self.uav_xy_m = self._start_xy_m.copy()
        self.setpoint_xy_m = self._start_xy_m.copy()
        self.uav_velocity_mps = np.zeros_like(self.uav_xy_m)
        self.mobility: MobilityState | None = None  # both set by reset()
        self.readings: RadioReadings | None = None

    def _seed(self, seed: int | np.random.SeedSequence | None) -> None:
        if not isinstance(seed, np.random.SeedSequence):
            seed = np.random.SeedSequence(seed)
        streams = seed.spawn(2)
        self.mobility_rng, self.radio_rng = (np.random.default_rng(s) for s in streams)

    @property
    def place_memory(self) -> PlaceMemory | None:
        """The memory of place the observations are built from (None without one), for pictures."""
        return self._builder.place

    def reset(self, seed: int | np.random.SeedSequence | None = None) -> np.ndarray:
        """Start N new episodes (UAVs at their start positions); returns the observations (N D, obs)."""
        if seed is not None:
            self._seed(seed)
        self.frame = 0
        self.scenario_ids = draw_scenarios(self.mobility_rng, self.cfg.scenario, self.n_envs)
        self.mobility = init_mobility(self.mobility_rng, self.scenario_ids, self.cfg)
        self.uav_xy_m = self._start_xy_m.copy()
        self.setpoint_xy_m = self._start_xy_m.copy()  # uav_motion px4: where PX4 is asked to be
        self.uav_velocity_mps = np.zeros_like(self.uav_xy_m)
        self.readings = self.channel.reset(
            self.radio_rng, self._per_env(self.uav_xy_m), self.mobility.position_m
        )
        return self._builder.reset(**self._sensed())

    def step(self, action: np.ndarray) -> StepResult:
        """Advance every env one frame with actions (N D, 2) in [-1, 1]."""
        if self.mobility is None:
            raise RuntimeError("call reset() before step()")
        action = self.actions.validate(action, self.n_rows)
        half = self.cfg.area.half_width_m
        # the move shifts the setpoint, which PX4 then flies to
        if self.cfg.uav_motion == MOTION_PX4:
            # as ``uavlink fly`` moves them: clipped, separated, and for a fleet cut where the
            # UAVs' predicted flight from where they are, as fast as they fly, would bring two
            # closer than the minimum
            self.setpoint_xy_m = next_setpoints(
                self._per_env(self.setpoint_xy_m),
                self._per_env(self.actions.to_displacement_m(action)),
                half,
                self.cfg.uav_separation_m,
                self._per_env(self._as_carried(self.uav_xy_m)) if self.n_uavs > 1 else None,
                self._per_env(self._as_carried(self.uav_velocity_mps)),
            ).reshape(self.n_rows, 2)
            position, self.uav_velocity_mps = PX4_MOTION.fly(
                self.uav_xy_m,
                self.uav_velocity_mps,
                self._as_carried(self.setpoint_xy_m),
                self.cfg.frame_s,
                half,
            )
            return self.step_to(position)
        moves = self._per_env(self.actions.to_displacement_m(action))
        target = apply_moves(self._per_env(self.uav_xy_m), moves, half, self.cfg.uav_separation_m)
        return self.step_to(target.reshape(self.n_rows, 2))

    def step_to(self, uav_xy_m: np.ndarray) -> StepResult:
        """Advance one frame with the UAVs at the given positions (N D, 2), clipped to the area.

        ``step`` uses it after mapping actions; the SITL radio payload uses it with the vehicles'
        actual positions, so flight and simulation share one frame update.
        """
        if self.mobility is None:
            raise RuntimeError("call reset() before step_to()")
        half = self.cfg.area.half_width_m
        self.uav_xy_m = np.clip(
            np.asarray(uav_xy_m, dtype=float).reshape(self.n_rows, 2), -half, half
        )
        step_mobility(self.mobility, self.cfg.frame_s, half)
        self.readings = self.channel.step(
            self.radio_rng, self._per_env(self.uav_xy_m), self.mobility.position_m
        )
        self.frame += 1
        obs = self._builder.push(**self._sensed())
        fair = fair_rate(self.readings.rate_bps)
        done = self.frame >= self.cfg.episode_frames
        return StepResult(
            observation=obs,
            reward=np.repeat(self.reward_bounds.normalise(fair), self.n_uavs),
            terminated=np.zeros(self.n_rows, dtype=bool),
            truncated=np.full(self.n_rows, done),
            mean_rate_mbps=self.readings.rate_bps.mean(axis=1) * 1e-6,
            fair_rate=fair,
        )

    def _per_env(self, rows: np.ndarray) -> np.ndarray:
        """Agent rows (N D, ...) as (N, D, ...)."""
        return rows.reshape(self.n_envs, self.n_uavs, *rows.shape[1:])

    def _as_carried(self, values: np.ndarray) -> np.ndarray:
        """``values`` as a flight's policy and vehicle get them: with ``uav_motion="px4"`` rounded
        to float32, as MAVLink carries positions, velocities, setpoints (LOCAL_POSITION_NED,
        SET_POSITION_TARGET_LOCAL_NED) and the radio payload (DEBUG_FLOAT_ARRAY); unchanged
        otherwise. A policy's episode can turn on the last bits of its inputs, so an evaluation that
        a lockstep flight is to equal must round where the flight does; the UAVs start where they
        are float32-exact (``sitl_stub.fleet.spawn_points_ne``), so that a vehicle told to hold its
        reported position before the episode does not creep."""
        if self.cfg.uav_motion != MOTION_PX4:
            return values
        return values.astype(np.float32).astype(float)

    def _sensed(self) -> dict[str, np.ndarray]:
        """The observation's inputs per agent row: position, what its UAV hears, fleet fields."""
        r, rows = self.readings, (self.n_rows, -1)
        assert r is not None  # called after reset() set the readings
        uav_xy_m, aoa_deg = self._as_carried(self.uav_xy_m), self._as_carried(r.heard_aoa_deg)
        fleet = fleet_view_quantities(self.layout, self._per_env(uav_xy_m), r.serving, aoa_deg)
        return {
            "uav_xy_m": uav_xy_m,
            "sinr_db": self._as_carried(r.heard_sinr_db).reshape(rows),
            "aoa_deg": aoa_deg.reshape(rows),
            **fleet,
        }

    def ground_truth(self) -> GroundTruth:
        mobility = MobilityState(**{k: v.copy() for k, v in vars(self.mobility).items()})
        return GroundTruth(
            self.uav_xy_m.copy(),
            mobility.position_m.copy(),
            mobility.velocity_mps.copy(),
            self.scenario_ids.copy(),
            self.frame,
            mobility,
            self.channel.field,
        )
