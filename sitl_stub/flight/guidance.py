"""What the SITL vehicle's position controller is asked to fly beyond a plain position: velocity
and position+velocity offboard setpoints, PX4's ORBIT, DO_REPOSITION's speed and DO_CHANGE_SPEED's
cruise speed. Pure Python, no MAVLink; LOCAL_NED metres, m/s, radians.

:class:`Guidance` is the per-vehicle state; :meth:`Guidance.command` turns the vehicle's mode and
position target into a :class:`ControlCommand` for :func:`sitl_stub.flight.pos_control.track`:
a position target whose NaN axes are flown on velocity alone, plus a velocity feed-forward, as
PX4's multicopter position controller takes them (``vel_sp = vel_ff + K * pos_err``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TypeVar

from sitl_stub.core.modes import FlightMode
from sitl_stub.flight.pos_control import (
    ACC_Z_MPS2,
    GROUND_EPS_M,
    wrap,
)
from uavlink.config.position_loop import BRAKE_FRACTION, POS_GAIN_PER_S

NAN = math.nan
ORBIT_RADIUS_MIN_M = 1.0  # PX4 FlightTaskOrbit _radius_min
ORBIT_RADIUS_MAX_M = 1000.0  # PX4 MC_ORBIT_RAD_MAX default
ORBIT_DEFAULT_SPEED_MPS = 1.0  # PX4 FlightTaskOrbit::activate

# MAV/ORBIT_YAW_BEHAVIOUR values PX4 flies.
YAW_FRONT_TO_CENTER = 0
YAW_HOLD_INITIAL = 1
YAW_UNCONTROLLED = 2
YAW_FRONT_TANGENT = 3

T = TypeVar("T")


def three(values: Iterable[T]) -> tuple[T, T, T]:
    """The three per-axis items of ``values`` (north, east, down) as a 3-tuple: what
    ``tuple(generator)`` over an NED vector builds, with its length known to the type checker."""
    north, east, down = values
    return north, east, down


@dataclass(frozen=True)
class Motion:
    """The velocity part of an offboard setpoint: feed-forward (NED, m/s), which position axes
    (north, east, down) are flown on velocity alone, and a yaw rate (rad/s) or None."""

    velocity_ned: tuple[float, float, float]
    free_axes: tuple[bool, bool, bool]
    yaw_rate_radps: float | None = None

    def fill(
        self, position: tuple[float, float, float], current: list[float]
    ) -> tuple[float, float, float]:
        """``position`` with its free axes replaced by the ``current`` position."""
        return three(
            c if free else p for p, c, free in zip(position, current, self.free_axes, strict=True)
        )


@dataclass(frozen=True)
class Orbit:
    """A PX4 orbit: centre (north, east), down of the circle, radius (> 0), signed speed
    (positive = clockwise seen from above, MAVLink's sign convention) and yaw behaviour."""

    center_north_m: float
    center_east_m: float
    down_m: float
    radius_m: float
    speed_mps: float
    yaw_behaviour: int = YAW_FRONT_TO_CENTER
    initial_yaw_rad: float = 0.0

    @property
    def signed_radius_m(self) -> float:
        """ORBIT_EXECUTION_STATUS.radius: positive clockwise."""
        return math.copysign(self.radius_m, self.speed_mps)

    def velocity(self, north_m: float, east_m: float) -> tuple[float, float]:
        """Horizontal velocity that follows the circle: tangential at the orbit speed plus a
        radial P correction towards the circle, limited to |speed| + the radial part."""
        rn, re = north_m - self.center_north_m, east_m - self.center_east_m
        dist = math.hypot(rn, re)
        if dist < 1e-6:  # at the centre: head out north
            return POS_GAIN_PER_S * self.radius_m, 0.0
        un, ue = rn / dist, re / dist
        tn, te = -ue, un  # clockwise (azimuth increasing) tangent in NED
        radial = POS_GAIN_PER_S * (self.radius_m - dist)
        return self.speed_mps * tn + radial * un, self.speed_mps * te + radial * ue

    def yaw(self, north_m: float, east_m: float) -> float | None:
        """Heading target for the yaw behaviour (None: uncontrolled)."""
        rn, re = north_m - self.center_north_m, east_m - self.center_east_m
        if self.yaw_behaviour == YAW_HOLD_INITIAL:
            return self.initial_yaw_rad
        if self.yaw_behaviour == YAW_UNCONTROLLED or math.hypot(rn, re) < 1e-6:
            return None
        if self.yaw_behaviour == YAW_FRONT_TANGENT:
            return wrap(math.atan2(re, rn) + math.copysign(math.pi / 2, self.speed_mps))
        return wrap(math.atan2(-re, -rn))  # front to centre (PX4's default, and RC-controlled)


def sanitize_orbit(
    radius_m: float, speed_mps: float, v_max_mps: float, acc_max_mps2: float
) -> tuple[float, float]:
    """(radius, signed speed) as PX4's FlightTaskOrbit::_sanitizeParams leaves them: radius in
    [1, 1000] m, |speed| <= v_max, and v^2 <= acc_max * radius (speed lowered, not radius)."""
    r = min(max(radius_m, ORBIT_RADIUS_MIN_M), ORBIT_RADIUS_MAX_M)
    v = max(-v_max_mps, min(v_max_mps, speed_mps))
    if v * v >= acc_max_mps2 * r:
        v = math.copysign(math.sqrt(acc_max_mps2 * r) * 0.999, v)
    return r, v


def body_to_ned(
    forward: float, right: float, down: float, yaw_rad: float
) -> tuple[float, float, float]:
    """A body-frame (FRD) vector in NED at heading ``yaw_rad``."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return forward * c - right * s, forward * s + right * c, down


def brake_before(pos_m: float, v_mps: float, low_m: float, high_m: float, acc_mps2: float) -> float:
    """``v_mps`` limited so braking at ``BRAKE_FRACTION * acc_mps2`` stops inside [low, high]:
    a velocity setpoint cannot carry the vehicle through the hard fence."""
    a = BRAKE_FRACTION * acc_mps2
    if v_mps > 0:
        return min(v_mps, math.sqrt(2.0 * a * max(0.0, high_m - pos_m)))
    if v_mps < 0:
        return max(v_mps, -math.sqrt(2.0 * a * max(0.0, pos_m - low_m)))
    return v_mps


@dataclass(frozen=True)
class ControlCommand:
    """What :func:`sitl_stub.flight.pos_control.track` flies: a target (NaN axes: velocity only),
    a velocity feed-forward, a heading (None: keep) and a yaw rate (None: none)."""

    target: tuple[float, float, float]
    velocity_ff: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw_rad: float | None = None
    yaw_rate_radps: float | None = None

    @property
    def wants_up(self) -> bool:
        """Asks to leave the ground (a target above it, or a climb rate)."""
        down = self.target[2]
        return (math.isfinite(down) and -down > GROUND_EPS_M) or (
            math.isnan(down) and self.velocity_ff[2] < 0.0
        )


class Guidance:
    """Per-vehicle guidance state beyond a position target: the offboard motion, the orbit,
    the reposition target and its speed, and DO_CHANGE_SPEED's cruise speed."""

    def __init__(self) -> None:
        self.motion: Motion | None = None
        self.orbit: Orbit | None = None
        self.reposition_target: tuple[float, float, float] | None = None
        self.reposition_speed_mps: float | None = None
        self.cruise_override_mps: float | None = None

    def cruise_speed_mps(self, params: Mapping[str, float]) -> float:
        """AUTO modes' horizontal speed: DO_CHANGE_SPEED's, else MPC_XY_CRUISE (PX4 navigator)."""
        return self.cruise_override_mps or params["MPC_XY_CRUISE"]

    def xy_limit_mps(
        self, mode: FlightMode, target: tuple[float, float, float], params: Mapping[str, float]
    ) -> float:
        """Horizontal speed limit: RTL and a reposition fly at the cruise speed (or
        DO_REPOSITION's ground speed), everything else up to MPC_XY_VEL_MAX."""
        xy = params["MPC_XY_VEL_MAX"]
        if mode is FlightMode.RTL:
            return min(xy, self.cruise_speed_mps(params))
        if mode is FlightMode.LOITER and target == self.reposition_target:
            return min(xy, self.reposition_speed_mps or self.cruise_speed_mps(params))
        return xy

    def command(
        self,
        mode: FlightMode,
        pos: list[float],
        target: tuple[float, float, float],
        yaw_target: float | None,
        fence_m: float,
        ceiling_m: float,
        acc_xy_mps2: float,
    ) -> ControlCommand:
        """The control command for ``mode``; velocities are braked before the hard fence
        (``|north|, |east| <= fence_m``, ``-ceiling_m <= down <= 0``)."""
        if mode is FlightMode.ORBIT and self.orbit is not None:
            o = self.orbit
            vn, ve = o.velocity(pos[0], pos[1])
            ff = (
                brake_before(pos[0], vn, -fence_m, fence_m, acc_xy_mps2),
                brake_before(pos[1], ve, -fence_m, fence_m, acc_xy_mps2),
                0.0,
            )
            return ControlCommand((NAN, NAN, o.down_m), ff, o.yaw(pos[0], pos[1]))
        if mode is FlightMode.OFFBOARD and self.motion is not None:
            m = self.motion
            tgt = three(NAN if free else t for free, t in zip(m.free_axes, target, strict=True))
            bounds = (
                (-fence_m, fence_m, acc_xy_mps2),
                (-fence_m, fence_m, acc_xy_mps2),
                (-ceiling_m, 0.0, ACC_Z_MPS2),
            )
            ff = three(
                brake_before(p, v, lo, hi, acc)
                for p, v, (lo, hi, acc) in zip(pos, m.velocity_ned, bounds, strict=True)
            )
            yaw = None if m.yaw_rate_radps is not None else yaw_target
            return ControlCommand(tgt, ff, yaw, m.yaw_rate_radps)
        return ControlCommand(target, (0.0, 0.0, 0.0), yaw_target)
