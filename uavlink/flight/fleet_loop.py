"""``uavlink fly`` with a fleet: D vehicles, one policy acting on D agent rows per radio frame.

Each vehicle is its own MAVLink system with its own link state and offboard stream (a
:class:`~uavlink.flight.link.group.LinkGroup` keeps every stream alive while the loop waits on one
vehicle). Every vehicle takes off at once (each holds when up), then each enters OFFBOARD;
the world's episode starts once all are in OFFBOARD. Per frame: the newest report of every vehicle
makes the D observation rows (as the env's: own readings, the others' positions, who serves each
UE), the policy acts on them, and :func:`~uavlink.mobility.fleet.fleet_setpoints` turns the moves
into setpoints with the env's own separation filter, so what was trained is what flies, then cuts
any move whose transit (the vehicles lag their setpoints) would bring two vehicles closer
(:mod:`uavlink.mobility.transit`); the env's ``uav_motion="px4"`` fleet moves its setpoints through
the same code, so a lockstep flight replays as that evaluation. A backlog of frames (the loop
held up) is decided at its newest frame only, its whole earlier frames put into the policy's
memory, as one vehicle's loop does.

A vehicle whose link is lost falls back to hold on its own (PX4's offboard-loss failsafe); the
others fly on (the loop does not wait for a vehicle not heard for :data:`LIVE_S`, and moves of a
vehicle that cannot be told are not made, its last setpoint staying where the filter keeps the
others away from). When its link returns, the loop asks it to re-enter OFFBOARD (one DO_SET_MODE
about once a second, without waiting, so the others' decisions are not held up) and it flies the
policy again.

As for one vehicle (:func:`~uavlink.flight.result.judge`), the result says whether the flight flew
the frames it set out to, and if not, why.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.observation import fleet_view_quantities
from uavlink.flight.link import VehicleLink
from uavlink.flight.loop import (
    LoopConfig,
    PolicyPilot,
    close_episode,
    episode_over,
    judged_episode,
    stream_then_offboard,
    timed_out,
    to_start,
)
from uavlink.flight.radio_source import MavlinkRadioSource
from uavlink.flight.result import EndedBy, FleetResult, VehicleRecord
from uavlink.flight.vehicle_control import (
    ending_mode,
    mode_name,
    take_off_or_resume,
    wait_ready,
)
from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD
from uavlink.mavlink.radio_codec import RadioReport, ScoreReport, send_frame_decided
from uavlink.mobility.fleet import fleet_setpoints, min_separation_m
from uavlink.mobility.uav_motion import PX4_MOTION

log = logging.getLogger(__name__)

LIVE_S = 0.5  # wall seconds: a vehicle not heard for longer is not waited for
# Free-running, the transit guard keeps the vehicles' predicted paths this much further apart than
# the separation: the prediction starts from a position whose age is estimated from wall time, and
# the new setpoints reach the vehicles some milliseconds (at 20x, a tenth of a second) after it.
# Without it the aoa rule's fleet of three (circular, seed 0) came to 19.64-19.99 m in the SITL's
# truth in 5 of 6 flights.
FREE_RUNNING_MARGIN_M = 1.0
# Of a frame's wall time: the longest wait for the other vehicles' reports, free-running.
GATHER_FRAME_FRACTION = 0.3


class FleetPilot(PolicyPilot):
    """The policy on a fleet's D agent rows: observation rows as the env builds them."""

    def observe(  # type: ignore[override]  # a fleet's frame is every vehicle's report
        self, reports: Sequence[RadioReport], uav_xy_m: np.ndarray, first: bool
    ) -> np.ndarray:
        """Add this frame to the observation history (no decision); returns its rows (D, obs)."""
        sinr = np.stack([r.sinr_db for r in reports])
        serving = sinr.argmax(axis=0)  # the strongest, where no cell flags came
        for d, r in enumerate(reports):
            if r.serves is not None:
                serving = np.where(r.serves, d, serving)
        aoa = np.stack([r.aoa_deg for r in reports])
        fleet = fleet_view_quantities(self.builder.layout, uav_xy_m[None], serving[None], aoa[None])
        step = self.builder.reset if first else self.builder.push
        return step(uav_xy_m, sinr, aoa, **fleet)

    def decide(  # type: ignore[override]  # a fleet's decide takes every vehicle's report
        self, reports: Sequence[RadioReport], uav_xy_m: np.ndarray, first: bool
    ) -> np.ndarray:
        """East/north moves (D, 2), m; holds (zero moves) if the policy misbehaves."""
        return self.guarded_moves(self.observe(reports, uav_xy_m, first), reports[0].frame)


def fly_fleet(
    links: Sequence[VehicleLink],
    pilot: FleetPilot,
    cfg: EnvConfig,
    loop_cfg: LoopConfig,
    status: Callable[[int, np.ndarray, float | None], None] | None = None,
) -> FleetResult:
    """Fly one episode with every vehicle (links in UAV order); land them at the end. Never
    raises LinkError: the result says what went wrong."""
    result = FleetResult()
    return judged_episode(
        links, loop_cfg, result, lambda: _fly_fleet(links, pilot, cfg, loop_cfg, status, result)
    )


def _fly_fleet(links, pilot, cfg, loop_cfg, status, result: FleetResult) -> None:
    sources = [MavlinkRadioSource(cfg.n_ues) for _ in links]
    scores: dict[int, ScoreReport] = {}
    for link, source in zip(links, sources, strict=True):
        link.on_radio = source.feed
        link.on_score = lambda s: scores.setdefault(s.frame, s)
    for link in links:  # every vehicle ready before any arms: the first arming begins the episode
        wait_ready(link, loop_cfg.takeoff, loop_cfg.landing_wait_vehicle_s)
    # Every vehicle climbs at once (MAVSDK's examples/multiple_drones "take off and land in parallel"):
    # PX4's take-off is vertical, so vehicles standing apart stay apart, and the fleet is up in
    # one climb's time, not D.
    altitude_m = cfg.area.uav_altitude_m
    fence_m = cfg.area.half_width_m if loop_cfg.fence else None
    resumed = [
        take_off_or_resume(link, altitude_m, fence_m, loop_cfg.takeoff, wait=False)
        for link in links
    ]
    for link, up in zip(links, resumed, strict=True):
        if loop_cfg.takeoff and not up:
            link.wait_altitude(altitude_m)
    result.resumed = any(resumed)
    if not result.resumed:
        result.met_start = to_start(links, sources, cfg)
        scores.clear()
    result.vehicles = [VehicleRecord(link.target_system) for link in links]
    targets = np.array([[link.status.east_m, link.status.north_m] for link in links])
    down = -cfg.area.uav_altitude_m

    def send(i: int) -> None:
        links[i].stream_ned = (float(targets[i, 1]), float(targets[i, 0]), down)
        links[i].send_setpoint(*links[i].stream_ned)

    stream_then_offboard(links, send, loop_cfg)
    _Loop(links, pilot, cfg, loop_cfg, result, sources, scores, targets, send, status).run()


class _Loop:
    """The per-frame loop of :func:`fly_fleet` (state shared by its steps)."""

    def __init__(self, links, pilot, cfg, loop_cfg, result, sources, scores, targets, send, status):
        self.links, self.pilot, self.cfg, self.loop_cfg, self.result = (
            links,
            pilot,
            cfg,
            loop_cfg,
            result,
        )
        self.sources, self.scores, self.targets, self.send, self.status = (
            sources,
            scores,
            targets,
            send,
            status,
        )
        self.newest: list[RadioReport | None] = [None] * len(links)
        # every vehicle's reports of the frames not yet decided, by frame: a backlog's whole frames
        # go into the policy's memory, as one UAV's loop puts its late reports there
        self.held: dict[int, list[RadioReport | None]] = {}
        self.decided = -1  # the last frame decided
        self.seen_at: dict[int, float] = {}
        self.last_request = [-math.inf] * len(links)
        self.was_offboard = [True] * len(links)
        self.one_clock = False  # the vehicles' LOCAL_POSITION_NED times have been seen equal
        self.last_radio = time.monotonic()

    def run(self) -> None:
        links, result, loop_cfg = self.links, self.result, self.loop_cfg
        started = None
        try:
            while True:
                links[0].poll(0.01)
                now = time.monotonic()
                self._take_reports(now)
                frame = self._frame_to_decide(now)
                if frame is not None:
                    started = started or now
                    self._decide(frame, now)
                if self._episode_done():
                    result.ended_by = EndedBy.EPISODE_DONE
                    break
                if all(v.released for v in result.vehicles):
                    result.ended_by = EndedBy.EVERY_VEHICLE_RELEASED
                    break
                self._watch(now, started is not None)
                silence_s = min(now - link.last_rx_wall for link in links)
                if timed_out(loop_cfg, result, now - self.last_radio, silence_s, "any vehicle"):
                    break
        except KeyboardInterrupt:
            result.interrupted, result.ended_by = True, EndedBy.INTERRUPTED
        finally:
            # a vehicle released to an operator or a failsafe, or not heard lately, is not told
            # to land
            heard = [time.monotonic() - link.last_rx_wall < LIVE_S * 4 for link in links]
            close_episode(
                links,
                [h and not v.released for h, v in zip(heard, result.vehicles, strict=True)],
                loop_cfg,
                result,
                started_wall=started,
                scores=self.scores,
                pilot=self.pilot,
                rejected=sum(s.rejected for s in self.sources),
            )

    def _take_reports(self, now: float) -> None:
        for i, source in enumerate(self.sources):
            for r in source.take_reports():
                last = self.newest[i]
                if not r.running or (last is not None and r.frame <= last.frame):
                    continue
                self.newest[i] = r
                if r.frame > self.decided:
                    self.held.setdefault(r.frame, [None] * len(self.links))[i] = r
                self.seen_at.setdefault(r.frame, now)
                self.last_radio = now
                self.result.last_frame = max(r.frame, self.result.last_frame or 0)
                if self.result.first_frame is None:
                    self.result.first_frame = r.frame
                    self.result.episode = dict(self.links[i].radio_episode)

    def _reports(self) -> list[RadioReport] | None:
        """Every vehicle's newest report; None while one has sent none yet."""
        reports = [r for r in self.newest if r is not None]
        return reports if len(reports) == len(self.newest) else None

    def _frame_to_decide(self, now: float) -> int | None:
        """The newest frame, once every live vehicle has reported it (or waiting is over)."""
        reports = self._reports()
        if reports is None:
            return None  # every UAV's readings are needed once, for the first observation
        frame = max(r.frame for r in reports)
        if frame <= self.decided:
            return None
        if (
            frame >= self.loop_cfg.frames
        ):  # past the flight's frames: nothing to decide, nothing to wait for
            self._count_skipped(self.loop_cfg.frames)
            self._decided(frame)
            return None
        live = [now - link.last_rx_wall < LIVE_S for link in self.links]
        have = [r.frame == frame for r in reports]
        # Free-running, a late report must not hold up the others' decisions; in lockstep the world
        # waits for this frame's decision, so the loop waits for every report of it (a busy machine
        # delivered two of three 15 ms late at 20x, and those vehicles lost the frame's move), up to
        # LIVE_S for one that was lost.
        if any(r.waits for r in reports):
            gather_s = LIVE_S
        else:
            gather_s = GATHER_FRAME_FRACTION * self.cfg.frame_s / self.links[0].speed_factor()
        if (
            all(h or not alive for h, alive in zip(have, live, strict=True))
            or now - self.seen_at[frame] > gather_s
        ):
            return frame
        return None

    def _decide(self, frame: int, arrived: float) -> None:
        links, result = self.links, self.result
        positions = np.array([[link.status.east_m, link.status.north_m] for link in links])
        reports = self._reports()
        assert reports is not None  # _frame_to_decide waited for every vehicle's first report
        self._observe_backlog(frame, positions)
        moves = self.pilot.decide(reports, positions, self.decided < 0)
        movable = np.array(
            [
                reports[i].frame == frame
                and not result.vehicles[i].released
                and links[i].status.offboard
                for i in range(len(links))
            ]
        )
        velocity = np.array([[link.status.east_mps, link.status.north_mps] for link in links])
        free_running = not any(r.waits for r in reports)
        if free_running:
            positions, velocity = self._flown_on(positions, velocity)
        self.targets[:] = fleet_setpoints(
            self.targets,
            moves,
            self.cfg,
            movable,
            positions,
            velocity,
            FREE_RUNNING_MARGIN_M if free_running else 0.0,
        )
        result.setpoint_min_separation_m = min(
            result.setpoint_min_separation_m, float(min_separation_m(self.targets[None])[0])
        )
        for i in np.flatnonzero(movable):
            self.send(int(i))
            result.vehicles[i].decisions += 1
        self._count_skipped(frame)
        self._decided(frame, movable)
        result.decisions += 1
        result.latencies_s.append(time.monotonic() - arrived)
        if self.status:
            score = self.scores.get(frame)
            self.status(frame, self.targets[0], score.mean_rate_mbps if score else None)

    def _observe_backlog(self, frame: int, positions: np.ndarray) -> None:
        """Put the whole frames between the last decision and ``frame`` into the policy's memory
        (no decisions: a backlog is history, not moves to make at once); counted as
        ``stale_reports`` among the frames missed. Before the first decision the memory starts at
        the frame decided, as the env's does at its reset."""
        if self.decided < 0:
            return
        for f in sorted(f for f in self.held if f < frame):
            whole = [r for r in self.held[f] if r is not None]
            if len(whole) == len(self.links):
                self.pilot.observe(whole, positions, first=False)
                self.result.stale_reports += 1

    def _flown_on(
        self, xy_m: np.ndarray, velocity_mps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where the vehicles are now, flown on (PX4's position loop, towards the setpoints they
        have, as sent in float32) from their newest LOCAL_POSITION_NED for its age (wall seconds
        since it arrived times the vehicle's speed): a vehicle whose time does not wait for our
        decision flies on while we decide, a quarter of a second at 20x (median; up to 0.5 s),
        3 m at full speed, and the transit guard predicts from where it is."""
        now, half = time.monotonic(), self.cfg.area.half_width_m
        xy_m, velocity_mps = xy_m.copy(), velocity_mps.copy()
        sent = self.targets.astype(np.float32).astype(float)
        for i, link in enumerate(self.links):
            if link.status.boot_samples:
                age_s = (now - link.status.boot_samples[-1][0]) * link.speed_factor()
                xy_m[i], velocity_mps[i] = PX4_MOTION.fly(
                    xy_m[i], velocity_mps[i], sent[i], age_s, half
                )
        return xy_m, velocity_mps

    def _count_skipped(self, frame: int) -> None:
        """Count the flight's frames before ``frame`` that went by undecided: since the last decision
        (``frames_missed``), or since the first report before the first decision
        (``frames_before_first_decision``: that decision needs every vehicle's readings, and a
        free-running world goes on meanwhile)."""
        result = self.result
        if self.decided >= 0:
            result.frames_missed += max(0, frame - self.decided - 1)
        elif result.first_frame is not None:
            result.frames_before_first_decision += max(0, frame - result.first_frame)

    def _decided(self, frame: int, moved: Sequence[bool] | np.ndarray | None = None) -> None:
        """Frame ``frame`` is decided (every setpoint sent): a lockstep world may go on. ``moved``:
        which vehicles the policy steered in it (None: none, the frame is only let go)."""
        self.decided = frame
        self.held = {f: r for f, r in self.held.items() if f > frame}
        for i, link in enumerate(self.links):
            send_frame_decided(
                link.conn.mav, link.target_system, frame, moved is not None and bool(moved[i])
            )

    def _episode_done(self) -> bool:
        last = max((r.frame for r in self.newest if r is not None), default=-1)
        return episode_over(self.loop_cfg, self.scores, last)

    def _watch(self, now: float, flying: bool) -> None:
        """Per vehicle: its mode (hold, rejoin, released), its silence; the separation flown."""
        links, result = self.links, self.result
        times = {link.status.time_boot_ms for link in links}
        self.one_clock |= len(times) == 1
        # at an instant every vehicle reported: vehicles on one clock (sitl-stub --fleet's) report
        # together; the newest positions of vehicles on their own clocks may be a quarter of a
        # second apart, metres at full speed, and are paired as they are
        if flying and (len(times) == 1 or not self.one_clock):
            xy = np.array([[link.status.east_m, link.status.north_m] for link in links])
            result.min_separation_flown_m = min(
                result.min_separation_flown_m, float(min_separation_m(xy[None])[0])
            )
        for i, (link, record) in enumerate(zip(links, result.vehicles, strict=True)):
            st = link.status
            record.max_silence_s = max(record.max_silence_s, now - link.last_rx_wall)
            if record.released:
                continue
            if not st.armed or ending_mode(st):
                record.released = f"vehicle in {mode_name(st)}"
                link.stream_ned = None
                log.warning(
                    "system %s is now %s (operator or failsafe): leaving it alone",
                    link.target_system,
                    mode_name(st),
                )
                continue
            if st.offboard != self.was_offboard[i]:
                if st.offboard:
                    record.offboard_reentries += 1
                    log.warning(
                        "system %s is back in OFFBOARD: flying the policy again", link.target_system
                    )
                else:
                    record.holds += 1
                    log.warning(
                        "system %s left OFFBOARD (now %s): asking it back",
                        link.target_system,
                        mode_name(st),
                    )
                self.was_offboard[i] = st.offboard
            if not st.offboard and now - self.last_request[i] >= self.loop_cfg.reenter_interval_s:
                self.last_request[i] = now
                link.request_mode(PX4_MAIN_OFFBOARD)
        result.offboard_reentries = sum(v.offboard_reentries for v in result.vehicles)
