"""Kinematic multicopter with PX4-like modes, in simulated time. No MAVLink, no sockets.

Frame: LOCAL_NED, origin at the area centre on the ground (= home): north = env y, east = env x,
down = -altitude. Positions in metres, velocities in m/s, angles in radians, time in simulated
seconds advanced only by :meth:`Vehicle.step`.

The position controller is a velocity-limited P loop with an acceleration limit and a braking
curve (``v <= sqrt(2 a d)``), so it never overshoots a setpoint. Limits come from the PX4
parameters in :mod:`sitl_stub.params`, read every step so PARAM_SET takes effect at once.
Mode logic follows PX4 commander/navigator in the small: AUTO.TAKEOFF climbs to MIS_TAKEOFF_ALT
then holds in AUTO.LOITER; OFFBOARD needs a live setpoint stream and falls back to COM_OBL_ACT
after COM_OF_LOSS_T without one; RTL climbs to RTL_RETURN_ALT, returns at MPC_XY_CRUISE and lands;
a landed vehicle disarms after COM_DISARM_LAND. The area is a hard geofence: setpoints outside are
clamped onto it and the position never leaves it; altitude setpoints are clamped to
:data:`MAX_ALTITUDE_M` (a vertical fence, PX4's GF_MAX_VER_DIST).

Safety monitors for tests and logs (in :class:`VehicleState`): the largest horizontal distance from
the centre on either axis ever reached (``max_abs_xy_m``) and the oldest setpoint the vehicle ever
flew OFFBOARD on (``max_offboard_setpoint_age_s``; the failsafe keeps it at COM_OF_LOSS_T).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from enum import IntEnum

from sitl_stub.modes import FlightMode, LandedState
from sitl_stub.params import ParamStore
from uavlink.config import AreaConfig

GRAVITY_MPS2 = 9.81
SUBSTEP_S = 0.02  # integration step; step(dt) subdivides
ACC_Z_MPS2 = 3.0  # PX4 MPC_ACC_DOWN_MAX (and below MPC_ACC_UP_MAX 4)
POS_GAIN = 1.0  # PX4 MPC_XY_P / MPC_Z_P ~ 1 /s
YAW_RATE_RADPS = math.radians(45.0)  # PX4 MPC_YAWRAUTO_MAX
ALT_ACCEPT_M = 0.5  # takeoff / RTL climb done within this of the target altitude
XY_ACCEPT_M = 0.5  # RTL return done within this of home
GROUND_EPS_M = 0.05  # "on the ground" below this altitude
TAKEN_OFF_ALT_M = 1.0  # above this the vehicle counts as having flown
MAX_ALTITUDE_M = 500.0  # vertical fence: setpoints above are clamped (= the altitude params' max)

# MAV_SEVERITY values for vehicle events (reported as STATUSTEXT by the server).
SEVERITY_CRITICAL = 2
SEVERITY_WARNING = 4
SEVERITY_INFO = 6


class Result(IntEnum):
    """Outcome of a request, valued as MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4


@dataclass(frozen=True)
class Outcome:
    """A request's result and, when refused, PX4-style reason text."""

    result: Result
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.result is Result.ACCEPTED


ACCEPTED = Outcome(Result.ACCEPTED)


@dataclass(frozen=True)
class VehicleState:
    """Snapshot of the vehicle at ``time_s`` (simulated seconds since boot), LOCAL_NED."""

    time_s: float
    north_m: float
    east_m: float
    down_m: float
    vn_mps: float
    ve_mps: float
    vd_mps: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    yaw_rate_radps: float
    armed: bool
    mode: FlightMode
    landed_state: LandedState
    setpoint_ned: tuple[float, float, float] | None
    setpoints_accepted: int
    setpoints_rejected: int
    setpoints_clamped: int
    offboard_failsafes: int
    max_abs_xy_m: float = 0.0
    max_offboard_setpoint_age_s: float = 0.0

    @property
    def x_east_m(self) -> float:
        """Environment x (east)."""
        return self.east_m

    @property
    def y_north_m(self) -> float:
        """Environment y (north)."""
        return self.north_m

    @property
    def altitude_m(self) -> float:
        """Height above home (the ground), m."""
        return -self.down_m

    @property
    def ground_speed_mps(self) -> float:
        return math.hypot(self.vn_mps, self.ve_mps)

    @property
    def in_air(self) -> bool:
        return self.landed_state is not LandedState.ON_GROUND


class Vehicle:
    """The multicopter. Starts disarmed on the ground at home in AUTO.LOITER."""

    def __init__(self, params: ParamStore | None = None, area: AreaConfig | None = None) -> None:
        self.params = params if params is not None else ParamStore()
        self.fence_m = (area or AreaConfig()).half_width_m
        self.t = 0.0
        self.pos = [0.0, 0.0, 0.0]
        self.vel = [0.0, 0.0, 0.0]
        self._acc_ne = (0.0, 0.0)
        self.yaw = 0.0
        self._yaw_rate = 0.0
        self._yaw_target: float | None = None
        self.armed = False
        self.mode = FlightMode.LOITER
        self._target = (0.0, 0.0, 0.0)
        self._rtl_alt = 0.0
        self._rtl_phase = "climb"
        self._landed = True
        self._landed_since = 0.0
        self._has_flown = False
        self._sp: tuple[float, float, float] | None = None
        self._sp_yaw: float | None = None
        self._sp_time = -math.inf
        self.setpoints_accepted = 0
        self.setpoints_rejected = 0
        self.setpoints_clamped = 0
        self.offboard_failsafes = 0
        self.max_abs_xy_m = 0.0
        self.max_offboard_setpoint_age_s = 0.0
        self._events: deque[tuple[int, str]] = deque(maxlen=32)

    # ----------------------------------------------------------------- requests
    def arm(self) -> Outcome:
        """Arm on the ground (PX4: not in AUTO.LAND / AUTO.RTL, which prevent arming)."""
        if self.armed:
            return ACCEPTED
        if not self._landed:
            return Outcome(Result.DENIED, "Arming denied: vehicle not landed")
        if self.mode in (FlightMode.LAND, FlightMode.RTL):
            return Outcome(Result.DENIED, f"Arming denied: not allowed in {self.mode.px4_name}")
        if self.mode is FlightMode.OFFBOARD and not self.offboard_stream_ok():
            return Outcome(Result.DENIED, "Arming denied: no offboard setpoints")
        self.armed = True
        self._has_flown = False
        self._landed_since = self.t
        if self.mode is FlightMode.LOITER:
            self._target = self._ground_point()
        self._event(SEVERITY_INFO, "Armed")
        return ACCEPTED

    def disarm(self, force: bool = False) -> Outcome:
        """Disarm when landed; in the air only when forced (the vehicle then falls)."""
        if not self.armed:
            return ACCEPTED
        if not self._landed and not force:
            return Outcome(Result.DENIED, "Disarming denied: not landed")
        self._disarm("Disarmed")
        return ACCEPTED

    def takeoff(self, altitude_m: float | None = None) -> Outcome:
        """AUTO.TAKEOFF to ``altitude_m`` above home (MIS_TAKEOFF_ALT when None), then AUTO.LOITER."""
        if not self.armed:
            return Outcome(Result.DENIED, "Takeoff denied: disarmed")
        alt = self.params["MIS_TAKEOFF_ALT"] if altitude_m is None else float(altitude_m)
        if not math.isfinite(alt) or alt <= 0.0:
            return Outcome(Result.DENIED, "Takeoff denied: invalid altitude")
        if alt > MAX_ALTITUDE_M:
            return Outcome(Result.DENIED, f"Takeoff denied: above the {MAX_ALTITUDE_M:g} m fence")
        alt = max(alt, -self.pos[2])
        self.mode = FlightMode.TAKEOFF
        self._target = self._clamp((self.pos[0], self.pos[1], -alt))
        return ACCEPTED

    def land(self) -> Outcome:
        """AUTO.LAND at the current horizontal position."""
        self.mode = FlightMode.LAND
        n, e, _ = self._stopping_point()
        self._target = (n, e, 1.0)  # 1 m below ground: descend at landing speed to touchdown
        return ACCEPTED

    def return_to_launch(self) -> Outcome:
        """AUTO.RTL: climb to max(current, RTL_RETURN_ALT), return to home at MPC_XY_CRUISE, land."""
        self.mode = FlightMode.RTL
        self._rtl_alt = max(-self.pos[2], self.params["RTL_RETURN_ALT"])
        n, e, _ = self._stopping_point()
        if self._landed:  # PX4: RTL on the ground just stays landed
            self._rtl_phase = "land"
            self._target = (n, e, 1.0)
        else:
            self._rtl_phase = "climb"
            self._target = (n, e, -self._rtl_alt)
        return ACCEPTED

    def hold(self) -> Outcome:
        """AUTO.LOITER: brake and hold where the vehicle stops."""
        self.mode = FlightMode.LOITER
        self._target = self._ground_point() if self._landed else self._stopping_point()
        return ACCEPTED

    def start_offboard(self) -> Outcome:
        """OFFBOARD, refused unless a setpoint arrived within COM_OF_LOSS_T (PX4 commander)."""
        if not self.offboard_stream_ok():
            return Outcome(Result.DENIED, "Switching to Offboard denied: no setpoint stream")
        self.mode = FlightMode.OFFBOARD
        assert self._sp is not None
        self._target = self._sp
        self._yaw_target = self._sp_yaw
        return ACCEPTED

    def set_mode(self, mode: FlightMode) -> Outcome:
        """Enter ``mode`` as DO_SET_MODE would; re-entering the current mode is a no-op."""
        if mode is self.mode:
            return ACCEPTED
        return {
            FlightMode.TAKEOFF: self.takeoff,
            FlightMode.LOITER: self.hold,
            FlightMode.LAND: self.land,
            FlightMode.RTL: self.return_to_launch,
            FlightMode.OFFBOARD: self.start_offboard,
        }[mode]()

    def offer_setpoint(self, north_m: float, east_m: float, down_m: float,
                       yaw_rad: float | None = None) -> bool:
        """A position setpoint (LOCAL_NED). Non-finite ones are rejected (False); others are
        clamped into the geofence, above the ground and below :data:`MAX_ALTITUDE_M`, and refresh
        the offboard stream."""
        if not all(math.isfinite(v) for v in (north_m, east_m, down_m)):
            self.setpoints_rejected += 1
            return False
        sp = self._clamp((float(north_m), float(east_m),
                          max(min(float(down_m), 0.0), -MAX_ALTITUDE_M)))
        if sp != (north_m, east_m, down_m):
            self.setpoints_clamped += 1
        self._sp = sp
        self._sp_yaw = _wrap(yaw_rad) if yaw_rad is not None and math.isfinite(yaw_rad) else None
        self._sp_time = self.t
        self.setpoints_accepted += 1
        if self.mode is FlightMode.OFFBOARD:
            self._target = sp
            self._yaw_target = self._sp_yaw
        return True

    def offboard_stream_ok(self) -> bool:
        """True while the last setpoint is no older than COM_OF_LOSS_T."""
        return self._sp is not None and self.t - self._sp_time <= self.params["COM_OF_LOSS_T"]

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
            time_s=self.t, north_m=self.pos[0], east_m=self.pos[1], down_m=self.pos[2],
            vn_mps=self.vel[0], ve_mps=self.vel[1], vd_mps=self.vel[2],
            roll_rad=roll, pitch_rad=pitch, yaw_rad=self.yaw, yaw_rate_radps=self._yaw_rate,
            armed=self.armed, mode=self.mode, landed_state=self._landed_state(),
            setpoint_ned=self._sp, setpoints_accepted=self.setpoints_accepted,
            setpoints_rejected=self.setpoints_rejected, setpoints_clamped=self.setpoints_clamped,
            offboard_failsafes=self.offboard_failsafes, max_abs_xy_m=self.max_abs_xy_m,
            max_offboard_setpoint_age_s=self.max_offboard_setpoint_age_s,
        )

    def _substep(self, h: float) -> None:
        self.t += h
        if self.mode is FlightMode.OFFBOARD:
            if self.offboard_stream_ok():
                self.max_offboard_setpoint_age_s = max(self.max_offboard_setpoint_age_s,
                                                       self.t - self._sp_time)
            else:
                self._offboard_lost()
        if self.armed:
            self._advance_mode()
            self._control(h)
        else:
            self._fall(h)
        self._enforce_limits()
        self.max_abs_xy_m = max(self.max_abs_xy_m, abs(self.pos[0]), abs(self.pos[1]))
        self._update_landed()

    def _offboard_lost(self) -> None:
        self.offboard_failsafes += 1
        action = int(self.params["COM_OBL_ACT"])
        if not self.armed or self._landed or action == 1:
            self.hold()
            name = "Hold"
        elif action == 0:
            self.land()
            name = "Land"
        else:
            self.return_to_launch()
            name = "Return"
        self._event(SEVERITY_WARNING, f"Failsafe: offboard lost, activating {name}")

    def _advance_mode(self) -> None:
        alt = -self.pos[2]
        if self.mode is FlightMode.TAKEOFF and alt >= -self._target[2] - ALT_ACCEPT_M:
            self.mode = FlightMode.LOITER  # target stays the takeoff point
            self._event(SEVERITY_INFO, "Takeoff complete, holding")
        elif self.mode is FlightMode.RTL:
            if self._rtl_phase == "climb" and alt >= self._rtl_alt - ALT_ACCEPT_M:
                self._rtl_phase = "return"
                self._target = (0.0, 0.0, -self._rtl_alt)
            elif self._rtl_phase == "return" and math.hypot(self.pos[0], self.pos[1]) < XY_ACCEPT_M:
                self._rtl_phase = "land"
                self._target = (0.0, 0.0, 1.0)

    def _limits(self) -> tuple[float, float, float]:
        """(horizontal speed, climb rate, descent rate) limits for the current mode, m/s."""
        p = self.params
        xy = p["MPC_XY_VEL_MAX"]
        up, down = p["MPC_Z_VEL_MAX_UP"], p["MPC_Z_VEL_MAX_DN"]
        if self.mode is FlightMode.TAKEOFF:
            up = min(up, p["MPC_TKO_SPEED"])
        landing = self.mode is FlightMode.LAND or (
            self.mode is FlightMode.RTL and self._rtl_phase == "land")
        if landing and -self.pos[2] <= p["MPC_LAND_ALT2"]:
            down = min(down, p["MPC_LAND_SPEED"])
        if self.mode is FlightMode.RTL:
            xy = min(xy, p["MPC_XY_CRUISE"])
        return xy, up, down

    def _control(self, h: float) -> None:
        xy_max, up_max, down_max = self._limits()
        acc_xy = self.params["MPC_ACC_HOR_MAX"]
        tn, te, td = self._target
        if self._landed and -td <= GROUND_EPS_M:
            self.vel = [0.0, 0.0, 0.0]  # sitting on the ground, nothing to do
            self._acc_ne = (0.0, 0.0)
            return
        # Horizontal: braking-curve P control, acceleration-limited.
        en, ee = tn - self.pos[0], te - self.pos[1]
        dist = math.hypot(en, ee)
        speed = min(xy_max, POS_GAIN * dist, math.sqrt(2.0 * 0.9 * acc_xy * dist))
        vdn, vde = (en / dist * speed, ee / dist * speed) if dist > 1e-9 else (0.0, 0.0)
        dvn, dve = vdn - self.vel[0], vde - self.vel[1]
        dv = math.hypot(dvn, dve)
        if dv > acc_xy * h:
            dvn, dve = dvn * acc_xy * h / dv, dve * acc_xy * h / dv
        self.vel[0] += dvn
        self.vel[1] += dve
        self._acc_ne = (dvn / h, dve / h)
        hs = math.hypot(self.vel[0], self.vel[1])
        if hs > xy_max:  # a lowered MPC_XY_VEL_MAX applies at once
            self.vel[0] *= xy_max / hs
            self.vel[1] *= xy_max / hs
        # Vertical (down positive).
        ed = td - self.pos[2]
        vmax = down_max if ed > 0 else up_max
        vd_des = math.copysign(min(vmax, POS_GAIN * abs(ed), math.sqrt(2.0 * 0.9 * ACC_Z_MPS2 * abs(ed))), ed)
        dvd = max(-ACC_Z_MPS2 * h, min(ACC_Z_MPS2 * h, vd_des - self.vel[2]))
        self.vel[2] = max(-up_max, min(down_max, self.vel[2] + dvd))
        for i in range(3):
            self.pos[i] += self.vel[i] * h
        self._turn(h)

    def _turn(self, h: float) -> None:
        if self._yaw_target is None:
            self._yaw_rate = 0.0
            return
        err = _wrap(self._yaw_target - self.yaw)
        step = max(-YAW_RATE_RADPS * h, min(YAW_RATE_RADPS * h, err))
        self.yaw = _wrap(self.yaw + step)
        self._yaw_rate = step / h

    def _fall(self, h: float) -> None:
        self._acc_ne = (0.0, 0.0)
        self._yaw_rate = 0.0
        if -self.pos[2] > GROUND_EPS_M or self.vel[2] < 0:
            self.vel[2] += GRAVITY_MPS2 * h
            for i in range(3):
                self.pos[i] += self.vel[i] * h
        else:
            self.vel = [0.0, 0.0, 0.0]

    def _enforce_limits(self) -> None:
        for i in (0, 1):
            if abs(self.pos[i]) > self.fence_m:
                self.pos[i] = math.copysign(self.fence_m, self.pos[i])
                self.vel[i] = 0.0
        if self.pos[2] > 0.0:
            self.pos[2] = 0.0
            self.vel[2] = min(self.vel[2], 0.0)
            if not self.armed:
                self.vel = [0.0, 0.0, 0.0]

    def _update_landed(self) -> None:
        alt = -self.pos[2]
        wants_up = self.armed and -self._target[2] > GROUND_EPS_M
        landed = alt <= GROUND_EPS_M and not wants_up and abs(self.vel[2]) < 0.3
        if landed and not self._landed:
            self._landed_since = self.t
            if self.armed:
                self.vel = [0.0, 0.0, 0.0]
                self._event(SEVERITY_INFO, "Landing detected")
        self._landed = landed
        if self.armed and alt > TAKEN_OFF_ALT_M:
            self._has_flown = True
        disarm_after = self.params["COM_DISARM_LAND"]
        landing_mode = self.mode in (FlightMode.LAND, FlightMode.RTL)
        if (self.armed and landed and disarm_after > 0 and (self._has_flown or landing_mode)
                and self.t - self._landed_since >= disarm_after):
            self._disarm("Disarmed by landing")

    def _disarm(self, why: str) -> None:
        self.armed = False
        self._has_flown = False
        self.mode = FlightMode.LOITER
        self._target = self._ground_point()
        self._yaw_target = None
        self._event(SEVERITY_INFO, why)

    # ---------------------------------------------------------------- helpers
    def _landed_state(self) -> LandedState:
        if self._landed:
            return LandedState.ON_GROUND
        if self.armed and self.mode is FlightMode.TAKEOFF:
            return LandedState.TAKEOFF
        if self.armed and (self.mode is FlightMode.LAND or (
                self.mode is FlightMode.RTL and self._rtl_phase == "land")):
            return LandedState.LANDING
        return LandedState.IN_AIR

    def _clamp(self, ned: tuple[float, float, float]) -> tuple[float, float, float]:
        """Horizontal position clamped into the geofence; ``down`` unchanged."""
        f = self.fence_m
        n, e, d = ned
        return (max(-f, min(f, n)), max(-f, min(f, e)), d)

    def _ground_point(self) -> tuple[float, float, float]:
        return (self.pos[0], self.pos[1], 0.0)

    def _stopping_point(self) -> tuple[float, float, float]:
        """Where braking at 90 % of MPC_ACC_HOR_MAX from the current velocity ends."""
        a = 0.9 * self.params["MPC_ACC_HOR_MAX"]
        vn, ve = self.vel[0], self.vel[1]
        s = math.hypot(vn, ve) / (2.0 * a)
        return self._clamp((self.pos[0] + vn * s, self.pos[1] + ve * s, self.pos[2]))

    def _tilt(self) -> tuple[float, float]:
        if not self.armed or self._landed:
            return 0.0, 0.0
        an, ae = self._acc_ne
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        fwd, right = an * c + ae * s, -an * s + ae * c
        return math.atan2(right, GRAVITY_MPS2), -math.atan2(fwd, GRAVITY_MPS2)

    def _event(self, severity: int, text: str) -> None:
        self._events.append((severity, text))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
