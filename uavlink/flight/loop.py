"""``uavlink fly``: a policy flies the vehicle, one (angle, distance) decision per radio frame.

Connect, wait for a PX4 multicopter, upload the operating area as its geofence, arm, take off to the SPEC altitude, stream setpoints and enter
OFFBOARD; then for every radio report: build the observation with the env's own builder, run the
policy, turn its move into a LOCAL_NED position target clamped to the operating area (the geofence
lies 2 m outside it), send it at once, then tell the radio payload the frame is decided (a lockstep
vehicle waits for that: docs/guides/sitl.md).
Between reports the current target is re-sent every ``stream_period_vehicle_s`` so PX4's offboard
loss timeout (COM_OF_LOSS_T, 1 s) never fires. At the end (or on Ctrl-C) it lands.

Faults: a vehicle that is already armed and in the air (``uavlink fly`` restarted after a crash) is
resumed without a take-off, from whatever frame its radio payload has reached; one that took off
away from its start position (an earlier flight landed elsewhere) flies there first
(:mod:`uavlink.flight.start_point`). A vehicle still landing from an earlier flight is waited for
until it has landed and disarmed; one landed but still armed is disarmed first: every flight begins
with an arming, which gives it a fresh radio episode (``sitl_stub.sim.radio_episodes``). When the
vehicle falls back to hold (offboard-loss failsafe after lost setpoints), the loop re-enters OFFBOARD,
trying again about once a second until the vehicle takes it. If the vehicle goes to AUTO.LAND or
AUTO.RTL, or disarms (an operator with the key, or a failsafe meant to end the flight), the loop
ends and leaves it alone. Lost radio reports cost their frame's decision only; a backlog of reports
(the loop was held up) is decided once, on the newest, the older ones only entering the observation
history; lost scores do not stall the end of the episode. Without any message from the vehicle for
``link_timeout_s`` of wall time, or without a fresh radio frame for ``radio_timeout_s`` in
OFFBOARD, the loop gives up.

The result says whether the flight flew the frames it set out to
(:func:`~uavlink.flight.result.judge`): every frame of a fresh episode from its start (a flight
that took off), or the rest of the running one (a resumed flight). Anything else (no radio reports, an episode already running or over, a vehicle that never
reached OFFBOARD, a lost link, an operator or failsafe ending the flight, Ctrl-C) is
``completed = False`` with the reason, one line that says what happened and what to do.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from uavlink.config import AreaConfig, EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationLayout
from uavlink.env.observation_builder import ObservationBuilder
from uavlink.errors import UserError
from uavlink.flight.link import STREAM_PERIOD_VEHICLE_S, LinkError, VehicleLink
from uavlink.flight.radio_source import MavlinkRadioSource, RadioSource
from uavlink.flight.result import EndedBy, FlightResult, judge, signing_hint
from uavlink.flight.start_point import fly_to_starts
from uavlink.flight.vehicle_control import (
    ending_mode,
    enter_offboard,
    land,
    mode_name,
    take_off_or_resume,
    wait_ready,
)
from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD
from uavlink.mavlink.radio_codec import RadioReport, ScoreReport, send_frame_decided
from uavlink.mobility.fleet import start_positions_m
from uavlink.policies.base import Policy

log = logging.getLogger(__name__)
ResultT = TypeVar("ResultT", bound=FlightResult)  # one vehicle's result or a fleet's


@dataclass
class LoopConfig:
    frames: int = 128
    stream_period_vehicle_s: float = STREAM_PERIOD_VEHICLE_S
    takeoff: bool = True
    land: bool = True
    link_timeout_s: float = 20.0  # wall seconds without any message from the vehicle: give up
    offboard_entry_s: float = 20.0  # wall seconds to get the vehicle into OFFBOARD at the start
    reenter_interval_s: float = 1.0  # wall seconds between attempts to re-enter OFFBOARD
    fence: bool = True  # upload the operating area as the vehicle's geofence first
    radio_timeout_s: float = 10.0  # wall seconds in OFFBOARD without a fresh radio frame: give up
    landing_wait_vehicle_s: float = 300.0  # vehicle seconds to wait for an earlier flight's landing

    def validate(self, episode_frames: int) -> LoopConfig:
        """UserError for frames no flight can fly (checked before anything starts or is written):
        under 1, or past the env's episode, where the policy's clock and the flight's replay end."""
        if not 1 <= self.frames <= episode_frames:
            raise UserError(
                f"--frames must be 1..{episode_frames} (decision frames to fly, at most the env's "
                f"episode: --set episode_frames=N for longer), got {self.frames}"
            )
        return self


class PolicyPilot:
    """Turns radio reports into position targets: observation builder + policy + output guard, for
    the ``cfg.n_uavs`` rows of one vehicle (here) or a fleet (``fleet_loop.FleetPilot``)."""

    def __init__(self, policy: Policy, cfg: EnvConfig) -> None:
        self.policy = policy
        self.cfg = cfg
        self.layout = ObservationLayout.for_config(cfg)
        if policy.layout is not None:
            policy.layout.check_matches(self.layout, what=f"policy {policy.name!r}")
        self.mapping = ActionMapping.for_config(cfg)
        self.builder = ObservationBuilder(self.layout, cfg.n_uavs, cfg.n_uavs)
        self.guarded = 0
        self.inference_s: list[float] = []

    def observe(self, report: RadioReport, uav_east_north_m: np.ndarray, first: bool) -> np.ndarray:
        """Add this frame to the observation history (no decision); returns the observation."""
        pos = uav_east_north_m.reshape(1, 2)
        step = self.builder.reset if first else self.builder.push
        return step(pos, report.sinr_db[None, :], report.aoa_deg[None, :])

    def decide(self, report: RadioReport, uav_east_north_m: np.ndarray, first: bool) -> np.ndarray:
        """East/north displacement (m) for this frame; a hold (zero move) if the policy misbehaves."""
        return self.guarded_moves(self.observe(report, uav_east_north_m, first), report.frame)[0]

    def guarded_moves(self, obs: np.ndarray, frame: int) -> np.ndarray:
        """The policy's east/north moves (rows, 2), m, for ``obs``; every row holds (zero moves) when
        its action is unusable (wrong shape, not finite, outside [-1, 1]), logged and counted."""
        rows = self.cfg.n_uavs
        started = time.perf_counter()
        action = np.asarray(self.policy.act(obs), dtype=float)
        self.inference_s.append(time.perf_counter() - started)
        why = (
            "wrong shape"
            if action.shape != (rows, 2)
            else "NaN/infinite"
            if not np.isfinite(action).all()
            else "outside [-1, 1]"
            if (np.abs(action) > 1.0 + 1e-6).any()
            else None
        )
        if why is None:
            return self.mapping.to_displacement_m(action)
        self.guarded += 1
        log.warning(
            "policy output guard: frame %d: policy %r returned an unusable action %s (%s): "
            "holding position (hold setpoint, no move); %d guarded so far",
            frame,
            getattr(self.policy, "name", "?"),
            action.tolist(),
            why,
            self.guarded,
        )
        return np.zeros((rows, 2))


def to_start(
    links: Sequence[VehicleLink], sources: Sequence[MavlinkRadioSource], cfg: EnvConfig
) -> bool:
    """Fly each vehicle to its UAV's start (a later flight took off where the last one landed) and
    drop the reports of what came before (an earlier episode, the wait); whether every payload's
    episode was still waiting for OFFBOARD, i.e. this flight meets the episode's start."""
    fly_to_starts(links, start_positions_m(cfg.n_uavs, cfg.fleet_start_radius_m))
    befores = [source.take_reports() for source in sources]
    return all(before and not before[-1].running for before in befores)


def stream_then_offboard(
    links: Sequence[VehicleLink], send: Callable[[int], None], loop_cfg: LoopConfig
) -> None:
    """PX4 refuses OFFBOARD without a setpoint stream: stream each vehicle's target (``send(i)``) for
    a moment, then switch each."""
    for i, link in enumerate(links):
        link.stream_period_vehicle_s = loop_cfg.stream_period_vehicle_s
        send(i)
    for _ in range(5):
        links[0].poll(loop_cfg.stream_period_vehicle_s / links[0].speed_factor())
    for link in links:
        enter_offboard(link, loop_cfg.offboard_entry_s)


def episode_over(loop_cfg: LoopConfig, scores: dict[int, ScoreReport], last_frame: int) -> bool:
    """The flight's frames are flown: the last one scored, or the reports two frames past it (its
    score lost), or past it with every frame scored."""
    return (
        loop_cfg.frames in scores
        or last_frame >= loop_cfg.frames + 2
        or (last_frame >= loop_cfg.frames and len(scores) >= loop_cfg.frames)
    )


def timed_out(
    loop_cfg: LoopConfig,
    result: FlightResult,
    radio_silence_s: float,
    link_silence_s: float,
    who: str = "the vehicle",
) -> bool:
    """Whether the loop must end for want of fresh radio frames (``result.ended_by`` says so);
    raises LinkError when nothing has been heard from ``who`` (a fleet: any vehicle) for
    ``link_timeout_s``. Both silences are wall seconds."""
    if radio_silence_s > loop_cfg.radio_timeout_s:
        result.ended_by = EndedBy.NO_RADIO_REPORTS
        return True
    if link_silence_s > loop_cfg.link_timeout_s:
        result.ended_by = EndedBy.LINK_LOST
        raise LinkError(
            f"no message from {who} for {loop_cfg.link_timeout_s:g} s: {EndedBy.LINK_LOST}"
        )
    return False


def close_episode(
    links: Sequence[VehicleLink],
    may_land: Sequence[bool],
    loop_cfg: LoopConfig,
    result: FlightResult,
    *,
    started_wall: float | None,
    scores: dict[int, ScoreReport],
    pilot: PolicyPilot,
    rejected: int,
) -> None:
    """The end of an episode's loop, however it ended: the result takes its wall time, the scores
    and the count of rejected radio reports; every vehicle that ``may_land`` and is still flying
    and ours (armed, not already landing or returning) lands; every offboard stream stops."""
    result.episode_wall_s = time.monotonic() - started_wall if started_wall else 0.0
    result.take_scores(scores, loop_cfg.frames, pilot, rejected)
    for link, allowed in zip(links, may_land, strict=True):
        st = link.status
        if loop_cfg.land and allowed and st.armed and not ending_mode(st):
            land(link)
        link.stream_ned = None


def fly_vehicle(
    link: VehicleLink,
    pilot: PolicyPilot,
    cfg: EnvConfig,
    loop_cfg: LoopConfig,
    radio: RadioSource | None = None,
    status: Callable[[int, np.ndarray, float | None], None] | None = None,
) -> FlightResult:
    """Fly one episode: take control (arm and take off, or resume in the air), stream setpoints and
    enter OFFBOARD, make one decision per fresh radio frame until the episode ends, the operator or
    a failsafe takes over, or the link is lost; then land unless someone else is already ending the
    flight. Ctrl-C lands too. Never raises LinkError: the result says what went wrong."""
    result = FlightResult()
    return judged_episode(
        [link], loop_cfg, result, lambda: _fly(link, pilot, cfg, loop_cfg, radio, status, result)
    )


def judged_episode(
    links: Sequence[VehicleLink], loop_cfg: LoopConfig, result: ResultT, fly: Callable[[], None]
) -> ResultT:
    """``fly()`` the episode into ``result`` and judge it, one vehicle or a fleet alike: a LinkError
    becomes the result's failure (with what to do about signing, where that was the cause), and a
    Ctrl-C before the episode's loop (which lands by itself) lands every vehicle still flying."""
    try:
        fly()
    except LinkError as exc:
        result.failure, result.fix = str(exc), next(filter(None, map(signing_hint, links)), "")
    except KeyboardInterrupt:
        result.interrupted, result.ended_by = True, EndedBy.INTERRUPTED
        for link in links:
            if loop_cfg.land and link.status.armed and not ending_mode(link.status):
                land(link)
    judge(result, loop_cfg.frames)
    return result


def _fly(link, pilot, cfg, loop_cfg, radio, status, result: FlightResult) -> None:
    source = radio or MavlinkRadioSource(cfg.n_ues)
    simulated = isinstance(source, MavlinkRadioSource)  # the SITL's radio payload: lockstep-able
    if simulated:
        link.on_radio = source.feed
    scores: dict[int, ScoreReport] = {}
    link.on_score = lambda s: scores.__setitem__(s.frame, s)
    half = cfg.area.half_width_m

    _take_control(link, loop_cfg, cfg.area, result)
    if not result.resumed:
        result.met_start = to_start([link], [source], cfg)
        scores.clear()
    st = link.status
    target = np.array([st.east_m, st.north_m])  # env frame: x east, y north
    down = -cfg.area.uav_altitude_m

    def send(_: int = 0) -> None:
        link.stream_ned = (float(target[1]), float(target[0]), down)
        link.send_setpoint(*link.stream_ned)

    stream_then_offboard([link], send, loop_cfg)

    frames = _FrameTracker()
    last_reentry = -math.inf
    last_radio = time.monotonic()
    try:
        while True:
            link.poll(0.5)
            fresh = frames.fresh(source.take_reports(), result)
            if fresh:
                last_radio = time.monotonic()
                result.episode = result.episode or dict(link.radio_episode)
            # A backlog (the loop was held up, e.g. by a mode change) is history, not a string of
            # moves to make at once: only the newest frame is decided.
            for report, first in fresh[:-1]:
                result.stale_reports += 1  # undecided (frames_missed), but in the memory
                result.frames_missed += 1
                pilot.observe(report, np.array([st.east_m, st.north_m]), first)
            for report, first in fresh[-1:]:
                arrived = time.monotonic()
                if report.frame < loop_cfg.frames:
                    move = pilot.decide(report, np.array([st.east_m, st.north_m]), first)
                    target = np.clip(target + move, -half, half)
                    send()
                    result.decisions += 1
                    result.latencies_s.append(time.monotonic() - arrived)
                    if status:
                        frame_score = scores.get(report.frame)
                        status(
                            report.frame,
                            target,
                            frame_score.mean_rate_mbps if frame_score else None,
                        )
                if simulated:  # after the setpoint: a lockstep vehicle's time may go on
                    send_frame_decided(
                        link.conn.mav,
                        link.target_system,
                        report.frame,
                        report.frame < loop_cfg.frames,
                    )
            if episode_over(loop_cfg, scores, frames.last):
                result.ended_by = EndedBy.EPISODE_DONE
                break
            if not st.armed or ending_mode(st):
                result.ended_by = f"vehicle in {mode_name(st)}"
                log.warning(
                    "vehicle is now %s (operator or failsafe): ending the loop, "
                    "leaving the vehicle alone",
                    mode_name(st),
                )
                break
            now = time.monotonic()
            if not st.offboard and now - last_reentry >= loop_cfg.reenter_interval_s:
                last_reentry = now
                _reenter_offboard(link, result)
            if timed_out(loop_cfg, result, now - last_radio, now - link.last_rx_wall):
                break
    except KeyboardInterrupt:
        result.interrupted, result.ended_by = True, EndedBy.INTERRUPTED
    finally:
        close_episode(
            [link],
            [result.ended_by != EndedBy.LINK_LOST],
            loop_cfg,
            result,
            started_wall=frames.started_wall,
            scores=scores,
            pilot=pilot,
            rejected=getattr(source, "rejected", 0),
        )


class _FrameTracker:
    """Which radio reports are new: the episode's frames in order, each once."""

    def __init__(self) -> None:
        self.last = -1  # newest frame taken
        self.started_wall: float | None = None  # wall time of the first running frame

    def fresh(
        self, reports: list[RadioReport], result: FlightResult
    ) -> list[tuple[RadioReport, bool]]:
        """The new reports in order, each with whether it is the episode's first; counts gaps."""
        fresh = []
        for report in reports:
            if not report.running or report.frame <= self.last and self.last >= 0:
                continue  # waiting for the episode, or a duplicate / late (reordered) report
            if self.started_wall is None:
                self.started_wall = time.monotonic()
                result.first_frame = report.frame
            if self.last >= 0:
                result.frames_missed += report.frame - self.last - 1
            fresh.append((report, self.last < 0))
            self.last = result.last_frame = report.frame
        return fresh


def _take_control(
    link: VehicleLink, loop_cfg: LoopConfig, area: AreaConfig, result: FlightResult
) -> None:
    """Wait for the vehicle to be ready, give it the operating area as its geofence, then arm and
    take off, or resume a vehicle already flying (``uavlink.flight.vehicle_control``)."""
    wait_ready(link, loop_cfg.takeoff, loop_cfg.landing_wait_vehicle_s)
    result.resumed = take_off_or_resume(
        link, area.uav_altitude_m, area.half_width_m if loop_cfg.fence else None, loop_cfg.takeoff
    )


def _reenter_offboard(link: VehicleLink, result: FlightResult) -> None:
    """The vehicle left OFFBOARD (a failsafe hold, say) but is still ours: ask for it back once."""
    log.warning(
        "vehicle left OFFBOARD (now %s, failsafe hold?): re-entering", mode_name(link.status)
    )
    try:
        link.set_mode(PX4_MAIN_OFFBOARD, tries=3)
        result.offboard_reentries += 1
    except LinkError as exc:
        log.warning("could not re-enter OFFBOARD yet: %s", exc)
