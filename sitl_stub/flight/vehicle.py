"""Kinematic multicopter with PX4-like modes, in simulated time. No MAVLink, no sockets.

Frame: LOCAL_NED, origin at the area centre on the ground (= home): north = env y, east = env x,
down = -altitude. Positions in metres, velocities in m/s, angles in radians, time in simulated
seconds advanced only by :meth:`Vehicle.step`.

The position controller (:mod:`sitl_stub.flight.pos_control`) never overshoots a setpoint. Limits
come from the PX4 parameters in :mod:`sitl_stub.core.params`, read every step so PARAM_SET takes effect at once.
Mode logic follows PX4 commander/navigator in the small: AUTO.TAKEOFF climbs to MIS_TAKEOFF_ALT
then holds in AUTO.LOITER; OFFBOARD needs a live setpoint stream and falls back to COM_OBL_ACT
after COM_OF_LOSS_T without one; RTL climbs to RTL_RETURN_ALT, returns at MPC_XY_CRUISE and lands;
a landed vehicle disarms after COM_DISARM_LAND. The area is a hard geofence: setpoints outside are
clamped onto it and the position never leaves it; altitude setpoints are clamped to
:data:`MAX_ALTITUDE_M` (a vertical fence, PX4's GF_MAX_VER_DIST).

Its snapshot, request outcomes and safety monitors are in :mod:`sitl_stub.core.vehicle_state`; the
position controller is :mod:`sitl_stub.flight.pos_control`. AUTO.MISSION flies the stored mission
(:mod:`sitl_stub.flight.mission_executor`); the uploaded geofence is enforced with GF_ACTION
and a lost offboard stream with their failsafe reactions (:mod:`sitl_stub.flight.failsafe`); RTL returns to the nearest rally point or home (:mod:`sitl_stub.flight.rtl`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import RALLY, MissionStore
from sitl_stub.core.modes import FlightMode, LandedState
from sitl_stub.core.params import ParamStore
from sitl_stub.core.vehicle_state import (
    ACCEPTED,
    SEVERITY_CRITICAL,
    SEVERITY_INFO,
    SEVERITY_WARNING,
    Outcome,
    Result,
    VehicleState,
)
from sitl_stub.flight.failsafe import Action, Reaction, geofence_breach, offboard_lost
from sitl_stub.flight.failures import FailureState
from sitl_stub.flight.geofence import FenceGuard
from sitl_stub.flight.guidance import ControlCommand, Guidance, Motion
from sitl_stub.flight.land_detector import LandDetector
from sitl_stub.flight.mission_executor import Leg, MissionExecutor
from sitl_stub.flight.offboard import OffboardStream
from sitl_stub.flight.pos_control import (
    fall,
    hold_in_fence,
    stopping_point,
    tilt,
    track,
    turn,
    wrap,
)
from sitl_stub.flight.rtl import ReturnPhases, rally_points, return_destination
from uavlink.config import AreaConfig
from uavlink.config.position_loop import SUBSTEP_S

ALT_ACCEPT_M = 0.5  # takeoff done within this of the target altitude
MAX_ALTITUDE_M = 500.0  # vertical fence: setpoints above are clamped (= the altitude params' max)


class Vehicle:
    """The multicopter. Starts disarmed on the ground at home in AUTO.LOITER."""

    def __init__(
        self,
        params: ParamStore | None = None,
        area: AreaConfig | None = None,
        plans: MissionStore | None = None,
        origin: GeoOrigin | None = None,
        home_ne: tuple[float, float] = (0.0, 0.0),
    ) -> None:  # spawn point = home (a fleet's)
        self.params = params if params is not None else ParamStore()
        self.plans = plans if plans is not None else MissionStore()
        self.origin = origin or GeoOrigin()
        self.mission = MissionExecutor(self.plans, self.origin, self.params)
        self.fence = FenceGuard(self.plans, self.origin)
        self._leg: Leg | None = None  # what AUTO.MISSION flies now
        self.fence_m = (area or AreaConfig()).half_width_m
        self.t, self.home_ne = 0.0, (float(home_ne[0]), float(home_ne[1]))
        self.pos = [*self.home_ne, 0.0]
        self.vel = [0.0, 0.0, 0.0]
        self._acc_ne = (0.0, 0.0)
        self.yaw = 0.0
        self._yaw_rate = 0.0
        self._yaw_target: float | None = None
        self.armed, self.armings = False, 0  # armings: flights begun (PX4 logs one per arming)
        self.mode = FlightMode.LOITER
        self._target = (0.0, 0.0, 0.0)
        self._rtl = ReturnPhases()
        self.ground = LandDetector()
        self.offboard = OffboardStream()
        self.max_abs_xy_m = 0.0
        self._events: deque[tuple[int, str]] = deque(maxlen=32)
        self.guidance = Guidance()  # velocity setpoints, orbit, reposition and cruise speeds
        self.failures = FailureState()  # MAV_CMD_INJECT_FAILURE effects

    # ----------------------------------------------------------------- requests
    def arm(self) -> Outcome:
        """Arm on the ground (PX4: not in AUTO.LAND / AUTO.RTL, which prevent arming). A refusal is
        TEMPORARILY_REJECTED, as PX4's commander answers every arming or disarming it refuses
        (``Commander::handle_command``): the state, not the request, is what stands in the way."""
        if self.armed:
            return ACCEPTED
        if not self.ground.landed:
            return Outcome(Result.TEMPORARILY_REJECTED, "Arming denied: vehicle not landed")
        if self.mode in (FlightMode.LAND, FlightMode.RTL):
            return Outcome(
                Result.TEMPORARILY_REJECTED, f"Arming denied: not allowed in {self.mode.px4_name}"
            )
        if self.mode is FlightMode.OFFBOARD and not self.offboard_stream_ok():
            return Outcome(Result.TEMPORARILY_REJECTED, "Arming denied: no offboard setpoints")
        self.armed, self.armings = True, self.armings + 1
        self.ground.armed(self.t)
        if self.mode is FlightMode.LOITER:
            self._target = self._ground_point()
        self._event(SEVERITY_INFO, "Armed")
        return ACCEPTED

    def disarm(self, force: bool = False) -> Outcome:
        """Disarm when landed; in the air only when forced (the vehicle then falls)."""
        if not self.armed:
            return ACCEPTED
        if not self.ground.landed and not force:
            return Outcome(Result.TEMPORARILY_REJECTED, "Disarming denied: not landed")
        self._disarm("Disarmed")
        return ACCEPTED

    def takeoff(self, altitude_m: float | None = None) -> Outcome:
        """AUTO.TAKEOFF to ``altitude_m`` above home (MIS_TAKEOFF_ALT when None), then AUTO.LOITER.
        Refused while disarmed (TEMPORARILY_REJECTED, PX4's code for a refused mode change; PX4
        itself takes the mode and climbs once armed); a bad altitude is DENIED."""
        if not self.armed:
            return Outcome(Result.TEMPORARILY_REJECTED, "Takeoff denied: disarmed")
        alt = self.params["MIS_TAKEOFF_ALT"] if altitude_m is None else float(altitude_m)
        if not math.isfinite(alt) or alt <= 0.0:
            return Outcome(Result.DENIED, "Takeoff denied: invalid altitude")
        if alt > MAX_ALTITUDE_M:
            return Outcome(Result.DENIED, f"Takeoff denied: above the {MAX_ALTITUDE_M:g} m fence")
        alt = max(alt, -self.pos[2])
        self.mode = FlightMode.TAKEOFF
        self._target = self._clamp((self.pos[0], self.pos[1], -alt))
        return ACCEPTED

    def land(self, at_ne: tuple[float, float] | None = None) -> Outcome:
        """AUTO.LAND at the current horizontal position (or at ``at_ne``)."""
        self.mode = FlightMode.LAND
        n, e, _ = self._stopping_point()
        self._target = (*(at_ne or (n, e)), 1.0)  # 1 m below ground: descend to touchdown
        return ACCEPTED

    def return_to_launch(self) -> Outcome:
        """AUTO.RTL: climb to max(current, RTL_RETURN_ALT), return at MPC_XY_CRUISE to the nearest
        of home and the rally points (PX4 RTL_TYPE 0), land there."""
        self.mode = FlightMode.RTL
        rally = rally_points(self.plans.items(RALLY), self.origin)
        dest = self._clamp(
            (*return_destination(self.pos[0], self.pos[1], rally, self.home_ne), 0.0)
        )
        self._target = self._rtl.start(
            self._stopping_point(), self.ground.landed, self.params["RTL_RETURN_ALT"], dest[:2]
        )
        return ACCEPTED

    def hold(self, at_ne: tuple[float, float] | None = None) -> Outcome:
        """AUTO.LOITER: brake and hold where the vehicle stops (or at ``at_ne``, this altitude)."""
        self.mode = FlightMode.LOITER
        self._target = self._ground_point() if self.ground.landed else self._stopping_point()
        if at_ne is not None and not self.ground.landed:
            self._target = (*at_ne, self.pos[2])
        return ACCEPTED

    def start_offboard(self) -> Outcome:
        """OFFBOARD, refused unless a setpoint arrived within COM_OF_LOSS_T (PX4 commander: a refused
        mode change is TEMPORARILY_REJECTED)."""
        if not self.offboard_stream_ok():
            return Outcome(
                Result.TEMPORARILY_REJECTED, "Switching to Offboard denied: no setpoint stream"
            )
        assert self.offboard.setpoint is not None  # a live stream has a setpoint
        self.mode = FlightMode.OFFBOARD
        self._target, self._yaw_target = self.offboard.setpoint, self.offboard.yaw_rad
        return ACCEPTED

    def set_mode(self, mode: FlightMode) -> Outcome:
        """Enter ``mode`` as DO_SET_MODE would; re-entering the current mode is a no-op."""
        if mode is self.mode:
            return ACCEPTED
        enter: dict[FlightMode, Callable[[], Outcome]] = {
            FlightMode.TAKEOFF: self.takeoff,
            FlightMode.LOITER: self.hold,
            FlightMode.LAND: self.land,
            FlightMode.RTL: self.return_to_launch,
            FlightMode.OFFBOARD: self.start_offboard,
            FlightMode.MISSION: self.start_mission,
        }
        return enter[mode]()

    def start_mission(self, first_seq: int | None = None) -> Outcome:
        """AUTO.MISSION, resuming at the current item (MISSION_START: from ``first_seq``)."""
        if first_seq is not None and not self.mission.restart_at(first_seq):
            return Outcome(Result.DENIED, f"Mission start denied: no item {first_seq}")
        reason = self.mission.start(self.pos)
        if reason:
            return Outcome(Result.DENIED, reason)
        self.mode = FlightMode.MISSION
        self._leg = None
        return ACCEPTED

    def fly_to(
        self, mode: FlightMode, target: tuple[float, float, float], yaw_rad: float | None = None
    ) -> tuple[float, float, float] | None:
        """Enter ``mode`` (LOITER: DO_REPOSITION; ORBIT) flying to ``target`` (fenced), heading
        ``yaw_rad`` (None: keep); the fenced target, or None when landed (PX4 stays down)."""
        self.mode = mode
        if self.ground.landed:
            self._target = self._ground_point()
            return None
        self._target = self._fenced(target)
        self._yaw_target = None if yaw_rad is None else wrap(yaw_rad)
        return self._target

    def offer_setpoint(
        self,
        north_m: float,
        east_m: float,
        down_m: float,
        yaw_rad: float | None = None,
        motion: Motion | None = None,
    ) -> bool:
        """A position setpoint (LOCAL_NED). Non-finite ones are rejected (False); others are
        clamped into the geofence, above the ground and below :data:`MAX_ALTITUDE_M`, and refresh
        the offboard stream. ``motion`` adds a velocity (:class:`~sitl_stub.flight.guidance.Motion`)."""
        if motion is not None:
            north_m, east_m, down_m = motion.fill((north_m, east_m, down_m), self.pos)
        sp = self.offboard.offer((north_m, east_m, down_m), yaw_rad, self.t, self._fenced)
        if sp is None:
            return False
        self.guidance.motion = motion
        if self.mode is FlightMode.OFFBOARD:
            self._target, self._yaw_target = sp, self.offboard.yaw_rad
        return True

    def offboard_stream_ok(self) -> bool:
        """True while the last setpoint is no older than COM_OF_LOSS_T."""
        return self.offboard.alive(self.t, self.params["COM_OF_LOSS_T"])

    def drain_events(self) -> list[tuple[int, str]]:
        """(MAV_SEVERITY, text) events since the last call: failsafes, auto-disarm, ..."""
        out = list(self._events)
        self._events.clear()
        return out

    # -------------------------------------------------------------- simulation
    def step(self, dt_s: float) -> None:
        """Advance ``dt_s`` simulated seconds (integrated in <= 20 ms substeps)."""
        if not math.isfinite(dt_s) or dt_s < 0:
            raise ValueError(f"dt_s must be finite and >= 0, got {dt_s}")
        while dt_s > 1e-12:
            h = min(SUBSTEP_S, dt_s)
            self._substep(h)
            dt_s -= h

    def state(self) -> VehicleState:
        """Immutable snapshot."""
        roll, pitch = self._tilt()
        return VehicleState(
            time_s=self.t,
            north_m=self.pos[0],
            east_m=self.pos[1],
            down_m=self.pos[2],
            vn_mps=self.vel[0],
            ve_mps=self.vel[1],
            vd_mps=self.vel[2],
            roll_rad=roll,
            pitch_rad=pitch,
            yaw_rad=self.yaw,
            yaw_rate_radps=self._yaw_rate,
            armed=self.armed,
            mode=self.mode,
            landed_state=self._landed_state(),
            setpoint_ned=self.offboard.setpoint,
            setpoints_accepted=self.offboard.setpoints_accepted,
            setpoints_rejected=self.offboard.setpoints_rejected,
            setpoints_clamped=self.offboard.setpoints_clamped,
            offboard_failsafes=self.offboard.failsafes,
            max_abs_xy_m=self.max_abs_xy_m,
            max_offboard_setpoint_age_s=self.offboard.max_age_s,
            fence_breached=self.fence.breached,
            mission_current=self.mission.status(self.mode is FlightMode.MISSION),
            failures=frozenset(self.failures.active),
            armings=self.armings,
            orbit=self.guidance.orbit if self.mode is FlightMode.ORBIT else None,
        )

    def _substep(self, h: float) -> None:
        self.t += h
        if self.mode is FlightMode.OFFBOARD:
            if self.offboard_stream_ok():
                self.offboard.flown_at(self.t)
            else:  # lost: COM_OBL_ACT's reaction
                self.offboard.failsafes += 1
                self._react(
                    offboard_lost(
                        int(self.params["COM_OBL_ACT"]), self.armed and not self.ground.landed
                    )
                )
        if self.armed and not self.failures.motors_off:
            self._advance_mode()
            if not self.ground.landed:
                self._check_geofence()
            self._control(h)
        else:
            self._fall(h)
        self._enforce_limits()
        self.max_abs_xy_m = max(self.max_abs_xy_m, abs(self.pos[0]), abs(self.pos[1]))
        self._update_landed()

    def _check_geofence(self) -> None:
        """A breach predicted at the braking point is announced once, then GF_ACTION applied."""
        gf_action = int(self.params["GF_ACTION"])
        if gf_action == 0:
            self.fence.breached = False
        elif (
            safe := self.fence.check((self.pos[0], self.pos[1]), self._stopping_point()[:2])
        ) is not None:
            self._event(SEVERITY_CRITICAL, "Geofence violation")
            self._react(geofence_breach(gf_action, self.mode, safe))

    def _react(self, reaction: Reaction) -> None:  # a failsafe's (sitl_stub.flight.failsafe)
        if reaction.action in (Action.HOLD, Action.LAND):
            (self.hold if reaction.action is Action.HOLD else self.land)(at_ne=reaction.at_ne)
        elif reaction.action is Action.RETURN:
            self.return_to_launch()
        if reaction.announce:
            self._event(SEVERITY_WARNING, reaction.announce)

    def _advance_mode(self) -> None:
        alt = -self.pos[2]
        if self.mode is FlightMode.TAKEOFF and alt >= -self._target[2] - ALT_ACCEPT_M:
            self.mode = FlightMode.LOITER  # target stays the takeoff point
            self._event(SEVERITY_INFO, "Takeoff complete, holding")
        elif self.mode is FlightMode.RTL:
            self._target = self._rtl.advance(self.pos) or self._target
        elif self.mode is FlightMode.MISSION:
            self._leg = leg = self.mission.update(self.t, self.pos, self.ground.landed)
            if leg.return_home:
                self.return_to_launch()
            else:
                n, e, d = leg.target_ned
                self._target = self._clamp((n, e, max(d, -MAX_ALTITUDE_M)))

    def _limits(self) -> tuple[float, float, float]:
        """(horizontal speed, climb rate, descent rate) limits for the current mode, m/s."""
        p = self.params
        xy = self.guidance.xy_limit_mps(self.mode, self._target, p)
        up, down = p["MPC_Z_VEL_MAX_UP"], p["MPC_Z_VEL_MAX_DN"]
        leg = self._leg if self.mode is FlightMode.MISSION else None
        if self.mode is FlightMode.TAKEOFF or (leg is not None and leg.takeoff):
            up = min(up, p["MPC_TKO_SPEED"])
        if self._landing() and -self.pos[2] <= p["MPC_LAND_ALT2"]:
            down = min(down, p["MPC_LAND_SPEED"])
        if leg is not None:
            xy = min(xy, leg.speed_mps or self.guidance.cruise_speed_mps(p))
        return xy, up, down

    def _landing(self) -> bool:
        return (
            self.mode is FlightMode.LAND
            or (self.mode is FlightMode.RTL and self._rtl.landing)
            or (self.mode is FlightMode.MISSION and self._leg is not None and self._leg.landing)
        )

    def _command(self) -> ControlCommand:
        return self.guidance.command(
            self.mode,
            self.pos,
            self._target,
            self._yaw_target,
            self.fence_m,
            MAX_ALTITUDE_M,
            self.params["MPC_ACC_HOR_MAX"],
        )

    def _control(self, h: float) -> None:
        cmd = self._command()
        if self.ground.landed and not cmd.wants_up:
            self.vel = [0.0, 0.0, 0.0]  # sitting on the ground, nothing to do
            self._acc_ne = (0.0, 0.0)
            return
        self._acc_ne = track(
            self.pos,
            self.vel,
            cmd.target,
            self._limits(),
            self.params["MPC_ACC_HOR_MAX"],
            h,
            cmd.velocity_ff,
        )
        self.yaw, self._yaw_rate = turn(self.yaw, cmd.yaw_rad, h, cmd.yaw_rate_radps)

    def _fall(self, h: float) -> None:
        self._acc_ne = (0.0, 0.0)
        self._yaw_rate = 0.0
        fall(self.pos, self.vel, h)

    def _enforce_limits(self) -> None:
        hold_in_fence(self.pos, self.vel, self.fence_m)
        if self.pos[2] > 0.0:
            self.pos[2] = 0.0
            self.vel[2] = min(self.vel[2], 0.0)
            if not self.armed:
                self.vel = [0.0, 0.0, 0.0]

    def _update_landed(self) -> None:
        wants_up = self.armed and not self.failures.motors_off and self._command().wants_up
        if (
            self.ground.update(self.t, -self.pos[2], self.vel[2], self.armed, wants_up)
            and self.armed
        ):
            self.vel = [0.0, 0.0, 0.0]
            self._event(SEVERITY_INFO, "Landing detected")
        landing_mode = self.mode in (FlightMode.LAND, FlightMode.RTL)
        if self.armed and self.ground.disarm_due(
            self.t, self.params["COM_DISARM_LAND"], landing_mode
        ):
            self._disarm("Disarmed by landing")

    def _disarm(self, why: str) -> None:
        self.armed = False
        self.mode = FlightMode.LOITER
        self._target = self._ground_point()
        self._yaw_target = None
        self._event(SEVERITY_INFO, why)

    # ---------------------------------------------------------------- helpers
    def _landed_state(self) -> LandedState:
        if self.ground.landed:
            return LandedState.ON_GROUND
        if self.armed and self.mode is FlightMode.TAKEOFF:
            return LandedState.TAKEOFF
        if self.armed and self._landing():
            return LandedState.LANDING
        return LandedState.IN_AIR

    def _fenced(self, ned: tuple[float, float, float]) -> tuple[float, float, float]:
        """Inside the area, above the ground and below :data:`MAX_ALTITUDE_M`."""
        return self._clamp((ned[0], ned[1], max(min(ned[2], 0.0), -MAX_ALTITUDE_M)))

    def _clamp(self, ned: tuple[float, float, float]) -> tuple[float, float, float]:
        """Horizontal position clamped into the geofence; ``down`` unchanged."""
        f = self.fence_m
        n, e, d = ned
        return (max(-f, min(f, n)), max(-f, min(f, e)), d)

    def _ground_point(self) -> tuple[float, float, float]:
        return (self.pos[0], self.pos[1], 0.0)

    def _stopping_point(self) -> tuple[float, float, float]:
        """Where braking at 90 % of MPC_ACC_HOR_MAX ends, inside the geofence."""
        return self._clamp(stopping_point(self.pos, self.vel, self.params["MPC_ACC_HOR_MAX"]))

    def _tilt(self) -> tuple[float, float]:
        if not self.armed or self.ground.landed:
            return 0.0, 0.0
        return tilt(self._acc_ne, self.yaw)

    def _event(self, severity: int, text: str) -> None:
        self._events.append((severity, text))
