"""The radio payload: the base station as its own MAVLink component on the vehicle's system.

It runs the simulator's UE mobility and radio model (``uavlink.env.radio_world.RadioWorld``,
advanced at the vehicle's actual position) and publishes each frame's readings as
``uavlink.mavlink.radio_codec`` describes. Each flight (an arming) meets a fresh episode
(:mod:`sitl_stub.sim.radio_episodes`): a vehicle started with ``--seed S`` serves episode 0 of seed S
first, so its first flight meets the UEs of ``uavlink evaluate --episodes 1 --seed S``, and its
k-th those of ``--seed S+k``; the episode starts at the first frame tick in OFFBOARD.

Each frame's readings go out ``READINGS_COPIES`` times (the flight loop drops the repeats by frame
number): over a link that loses packets independently, a frame's decision is lost only when every
copy is (30 % loss: 9 % of frames with two copies instead of 30 %). Bursts that eat both copies
still cost that frame's decision. The score (truth, for logs) goes once, and so does each UE's
position (truth, for ground pictures: ADSB_VEHICLE, :mod:`sitl_stub.sim.ue_truth`) unless
``PayloadOptions.ue_truth`` is off.

With ``PayloadOptions.lockstep`` each frame of a running episode in OFFBOARD holds simulated time
until the flight computer says it has decided that frame (``FRAME_DECIDED_COMMAND``,
``uavlink.mavlink.radio_codec``), as the env does, where a step waits for its action: the flight
no longer depends on how long a decision took in wall time, and a seed's flight replays exactly.
A frame that gets no answer in time is let go (:mod:`sitl_stub.sim.lockstep`; counted in the summary).
"""

from __future__ import annotations

from typing import Any

from sitl_stub.core.modes import FlightMode
from sitl_stub.core.vehicle_state import VehicleState
from sitl_stub.sim.lockstep import FrameHold
from sitl_stub.sim.payload import MAV_AUTOPILOT_INVALID, PayloadOptions
from sitl_stub.sim.radio_episodes import RadioEpisodes
from sitl_stub.sim.ue_truth import send_ue_truth
from uavlink.config import EnvConfig
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.radio_codec import (
    RADIO_COMPONENT_ID,
    READINGS_NAME,
    SCORE_NAME,
    encode_readings,
    encode_score,
)

# The payload component's HEARTBEAT (type, autopilot, base mode, custom mode, state): a companion
# computer's, never an autopilot's, so a ground link does not take it for the vehicle.
HEARTBEAT = (
    mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
    MAV_AUTOPILOT_INVALID,
    0,
    0,
    mavlink.MAV_STATE_ACTIVE,
)
READINGS_COPIES = 2  # each frame's readings, sent this many times against packet loss


def payload_env(options: PayloadOptions, n_uavs: int = 1) -> EnvConfig:
    """The radio world's env: the options' ``--set`` settings, scenario and AoA noise, with ``n_uavs``
    UAVs (a fleet's shared world; ``--set n_uavs`` may only agree)."""
    cfg = EnvConfig().replace(**dict(options.settings))
    if n_uavs == 1 and cfg.n_uavs != 1:
        raise ValueError(
            f"n_uavs={cfg.n_uavs} needs a fleet of vehicles: use --fleet {cfg.n_uavs} "
            "(one vehicle serves one UAV)"
        )
    if cfg.n_uavs not in (1, n_uavs):
        raise ValueError(f"--set n_uavs={cfg.n_uavs} disagrees with --fleet {n_uavs}; drop one")
    return cfg.replace(
        scenario=options.scenario, aoa_noise_deg=options.aoa_noise_deg, n_uavs=n_uavs
    ).validate()


def publish_frame(
    mav: Any,
    sim_time_s: float,
    episodes: RadioEpisodes,
    score: list[float] | None,
    readings: list[float],
    truth_origin: GeoOrigin | None,
) -> None:
    """One frame of a payload's messages: the encoded score (None before the episode starts), the
    episode's seed and count, the encoded readings ``READINGS_COPIES`` times, and the UEs' positions
    when ``truth_origin`` is given."""
    frame, usec = episodes.world.frame, int(sim_time_s * 1e6)
    if score is not None:
        mav.debug_float_array_send(usec, SCORE_NAME.encode(), frame, score)
    episodes.send_episode(mav, sim_time_s)
    for _ in range(READINGS_COPIES):
        mav.debug_float_array_send(usec, READINGS_NAME.encode(), frame, readings)
    if truth_origin is not None:
        send_ue_truth(mav, episodes.world, truth_origin)


class RadioPayload:
    """One vehicle's radio payload, serving one UAV's world."""

    component_id = RADIO_COMPONENT_ID

    def __init__(self, options: PayloadOptions) -> None:
        self.cfg = payload_env(options)
        self.frame_s = self.cfg.frame_s
        self.episodes = RadioEpisodes(self.cfg, options.seed)
        self.truth_origin = options.home if options.ue_truth else None
        self.lockstep = options.lockstep
        self.hold = FrameHold()

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        return HEARTBEAT

    def on_frame(self, sim_time_s: float, state: VehicleState, mav: Any) -> None:
        episodes = self.episodes
        result = episodes.tick([state])
        readings = episodes.world.readings()
        publish_frame(
            mav,
            sim_time_s,
            episodes,
            None if result is None else encode_score(result.rate_bps, result.fair_rate),
            encode_readings(
                readings.sinr_db, readings.aoa_deg, episodes.started, waits=self.lockstep
            ),
            self.truth_origin,
        )
        if self.lockstep and episodes.awaits_decision([state]):
            self.hold.hold(episodes.world.frame)

    def on_command(self, msg: Any, mav: Any) -> int | None:
        return self.hold.on_command(msg)

    def holds_clock(self, state: VehicleState) -> bool:
        return self.hold.holding(flying=state.mode is FlightMode.OFFBOARD)

    def summary(self) -> dict[str, Any]:
        lockstep = {"lockstep_timeouts": self.hold.timeouts} if self.lockstep else {}
        return {**self.episodes.summary(), **lockstep}
