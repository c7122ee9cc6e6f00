"""``uavlink fly``: a policy flies the vehicle, one (angle, distance) decision per radio frame.

Connect, wait for a PX4 multicopter, arm, take off to the SPEC altitude, stream setpoints and enter
OFFBOARD; then for every radio report: build the observation with the env's own builder, run the
policy, turn its move into a LOCAL_NED position target clamped to the geofence, send it at once.
Between reports the current target is re-sent every ``stream_period_vehicle_s`` so PX4's offboard
loss timeout (COM_OF_LOSS_T, 1 s) never fires. At the end (or on Ctrl-C) it lands.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationBuilder, ObservationLayout
from uavlink.flight.link import (
    PX4_MAIN_AUTO,
    PX4_MAIN_OFFBOARD,
    PX4_SUB_LOITER,
    LinkError,
    VehicleLink,
)
from uavlink.flight.radio_codec import RadioReport, ScoreReport
from uavlink.flight.radio_source import MavlinkRadioSource, RadioSource
from uavlink.policies.base import Policy

log = logging.getLogger(__name__)


@dataclass
class MissionConfig:
    frames: int = 128
    stream_period_vehicle_s: float = 0.2
    takeoff: bool = True
    land: bool = True


@dataclass
class MissionResult:
    frames: int = 0
    frame_rates_mbps: list[float] = field(default_factory=list)
    latencies_s: list[float] = field(default_factory=list)
    guarded_actions: int = 0
    rejected_reports: int = 0
    resumed: bool = False
    episode_wall_s: float = 0.0
    interrupted: bool = False

    inference_s: list[float] = field(default_factory=list)

    def summary(self) -> dict:
        lat_ms = np.array(self.latencies_s) * 1e3 if self.latencies_s else np.array([np.nan])
        inf_us = np.array(self.inference_s) * 1e6 if self.inference_s else np.array([np.nan])
        return {
            "frames": self.frames,
            "mean_rate_mbps": round(float(np.mean(self.frame_rates_mbps)), 6) if self.frame_rates_mbps else None,
            "latency_ms_p50": round(float(np.percentile(lat_ms, 50)), 4),
            "latency_ms_p99": round(float(np.percentile(lat_ms, 99)), 4),
            "inference_us_p50": round(float(np.percentile(inf_us, 50)), 2),
            "inference_us_p99": round(float(np.percentile(inf_us, 99)), 2),
            "episode_wall_s": round(self.episode_wall_s, 3),
            "guarded_actions": self.guarded_actions,
            "rejected_radio_reports": self.rejected_reports,
            "resumed_in_air": self.resumed,
            "interrupted": self.interrupted,
        }


class PolicyPilot:
    """Turns radio reports into position targets: observation builder + policy + output guard."""

    def __init__(self, policy: Policy, cfg: EnvConfig) -> None:
        self.policy = policy
        self.cfg = cfg
        self.layout = ObservationLayout.for_config(cfg)
        if policy.layout is not None:
            policy.layout.check_matches(self.layout, what=f"policy {policy.name!r}")
        self.mapping = ActionMapping(cfg.r_max_m, cfg.action_mapping)
        self.builder = ObservationBuilder(self.layout, 1)
        self.guarded = 0
        self.inference_s: list[float] = []

    def decide(self, report: RadioReport, uav_east_north_m: np.ndarray, first: bool) -> np.ndarray:
        """East/north displacement (m) for this frame; a hold (zero move) if the policy misbehaves."""
        pos = uav_east_north_m.reshape(1, 2)
        step = self.builder.reset if first else self.builder.push
        obs = step(pos, report.sinr_db[None, :], report.aoa_deg[None, :])
        started = time.perf_counter()
        action = np.asarray(self.policy.act(obs), dtype=float)
        self.inference_s.append(time.perf_counter() - started)
        if action.shape != (1, 2) or not np.isfinite(action).all() or (np.abs(action) > 1.0 + 1e-6).any():
            self.guarded += 1
            log.warning("policy returned an unusable action %s: holding position", action.tolist())
            return np.zeros(2)
        return self.mapping.to_displacement_m(action)[0]


def fly_mission(link: VehicleLink, pilot: PolicyPilot, cfg: EnvConfig, mission: MissionConfig,
                radio: RadioSource | None = None,
                status: Callable[[int, np.ndarray, float | None], None] | None = None) -> MissionResult:
    result = MissionResult()
    source = radio or MavlinkRadioSource(cfg.n_ues)
    if isinstance(source, MavlinkRadioSource):
        link.on_radio = source.feed
    scores: dict[int, ScoreReport] = {}
    link.on_score = lambda s: scores.__setitem__(s.frame, s)
    half, altitude = cfg.area.half_width_m, cfg.area.uav_altitude_m

    link.wait_vehicle()
    st = link.status
    if st.armed and st.in_air:
        result.resumed = True
        log.info("vehicle already armed and in the air: resuming without take-off")
    elif mission.takeoff:
        link.arm()
        link.takeoff(altitude)
    target = np.array([st.east_m, st.north_m])  # env frame: x east, y north
    down = -altitude

    def send() -> None:
        link.stream_ned = (float(target[1]), float(target[0]), down)
        link.send_setpoint(*link.stream_ned)

    # PX4 refuses OFFBOARD without a setpoint stream: stream for a moment, then switch.
    link.stream_period_vehicle_s = mission.stream_period_vehicle_s
    send()
    for _ in range(5):
        link.poll(mission.stream_period_vehicle_s / link.speed_factor())
    if not st.offboard:
        link.set_mode(PX4_MAIN_OFFBOARD)
        link.wait_until(lambda: st.offboard, 3.0, "OFFBOARD in the heartbeat")

    last_frame, started_wall = -1, None
    try:
        while True:
            link.poll(0.5)
            for report in source.take_reports():
                if not report.running or report.frame <= last_frame and last_frame >= 0:
                    continue
                arrived = time.monotonic()
                if started_wall is None:
                    started_wall = arrived
                first = last_frame < 0
                last_frame = report.frame
                if report.frame >= mission.frames:
                    continue
                move = pilot.decide(report, np.array([st.east_m, st.north_m]), first)
                target = np.clip(target + move, -half, half)
                send()
                result.latencies_s.append(time.monotonic() - arrived)
                if status:
                    frame_score = scores.get(report.frame)
                    status(report.frame, target, frame_score.mean_rate_mbps if frame_score else None)
            if st.main_mode == PX4_MAIN_AUTO and st.sub_mode == PX4_SUB_LOITER and last_frame >= 0:
                log.warning("vehicle left OFFBOARD (failsafe hold); re-entering")
                link.set_mode(PX4_MAIN_OFFBOARD)
            if mission.frames in scores or (last_frame >= mission.frames and len(scores) >= mission.frames):
                break
    except KeyboardInterrupt:
        result.interrupted = True
    finally:
        result.episode_wall_s = time.monotonic() - started_wall if started_wall else 0.0
        result.frame_rates_mbps = [scores[k].mean_rate_mbps for k in sorted(scores) if 1 <= k <= mission.frames]
        result.frames = len(result.frame_rates_mbps)
        result.guarded_actions = pilot.guarded
        result.inference_s = pilot.inference_s
        result.rejected_reports = getattr(source, "rejected", 0)
        link.stream_ned = None
        if mission.land:
            try:
                link.set_mode(PX4_MAIN_AUTO, PX4_SUB_LOITER)
                link.land()
            except LinkError as exc:
                log.error("landing command failed: %s", exc)
    return result


