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
from uavlink.mavlink.radio_codec import (
    RADIO_COMPONENT_ID,
    READINGS_NAME,
    SCORE_NAME,
    encode_readings,
    encode_score,
)

MAV_TYPE_ONBOARD_CONTROLLER = 18
MAV_STATE_ACTIVE = 4


class RadioPayload:
    component_id = RADIO_COMPONENT_ID
    READINGS_COPIES = 2

    def __init__(self, options: PayloadOptions, cfg: EnvConfig | None = None) -> None:
        base = cfg or EnvConfig().replace(**dict(options.settings))
        self.cfg = base.replace(scenario=options.scenario, aoa_noise_deg=options.aoa_noise_deg).validate()
        if self.cfg.n_uavs != 1:
            raise ValueError(f"n_uavs={self.cfg.n_uavs} needs a fleet of vehicles: use --fleet "
                             f"{self.cfg.n_uavs} (one vehicle serves one UAV)")
        self.frame_s = self.cfg.frame_s
        self.episodes = RadioEpisodes(self.cfg, options.seed)
        self.truth_origin = options.home if options.ue_truth else None
        self.lockstep = options.lockstep
        self.hold = FrameHold()

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        return (MAV_TYPE_ONBOARD_CONTROLLER, MAV_AUTOPILOT_INVALID, 0, 0, MAV_STATE_ACTIVE)

    def on_frame(self, sim_time_s: float, state: VehicleState, mav: Any) -> None:
        episodes = self.episodes
        score = episodes.tick([state])
        if score is not None:
            self._send(mav, sim_time_s, SCORE_NAME, encode_score(score.rate_bps, score.fair_rate))
        episodes.send_episode(mav, sim_time_s)
        readings = episodes.world.readings()
        data = encode_readings(readings.sinr_db, readings.aoa_deg, episodes.started)
        for _ in range(self.READINGS_COPIES):
            self._send(mav, sim_time_s, READINGS_NAME, data)
        if self.truth_origin is not None:
            send_ue_truth(mav, episodes.world, self.truth_origin)
        if self.lockstep and episodes.awaits_decision([state]):
            self.hold.hold(episodes.world.frame)

    def on_command(self, msg: Any, mav: Any) -> int | None:
        return self.hold.on_command(msg)

    def holds_clock(self, state: VehicleState) -> bool:
        return self.hold.holding(flying=state.mode is FlightMode.OFFBOARD)

    def summary(self) -> dict[str, Any]:
        lockstep = {"lockstep_timeouts": self.hold.timeouts} if self.lockstep else {}
        return {**self.episodes.summary(), **lockstep}

    def _send(self, mav: Any, sim_time_s: float, name: str, data: list[float]) -> None:
        mav.debug_float_array_send(int(sim_time_s * 1e6), name.encode(), self.episodes.world.frame, data)
