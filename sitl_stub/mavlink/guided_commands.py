"""The guided commands a ground station or MAVSDK app sends a flying PX4 multicopter:
DO_REPOSITION (MAVSDK's goto_location), DO_CHANGE_SPEED, DO_ORBIT and INJECT_FAILURE, each read
as PX4's commander/navigator/flight tasks read it and applied to the vehicle.

Params arrive as :class:`~sitl_stub.mavlink.commands.CommandRequest` params: COMMAND_LONG's seven floats,
or COMMAND_INT's with x/y the latitude/longitude in degrees * 1e7 (``frame`` not None).
Altitudes (param7/z) are AMSL in global frames and COMMAND_LONG, as PX4 reads them; the relative
frames give a height above home (PX4 ignores the frame here; MAVLink says it means this).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.modes import FlightMode
from sitl_stub.core.vehicle_state import ACCEPTED, Outcome, Result
from sitl_stub.flight.failures import FAILURE_TYPE_OFF
from sitl_stub.flight.guidance import (
    ORBIT_DEFAULT_SPEED_MPS,
    ORBIT_RADIUS_MIN_M,
    YAW_FRONT_TO_CENTER,
    Orbit,
    sanitize_orbit,
)
from sitl_stub.flight.vehicle import Vehicle
from uavlink.mavlink.frames import LOCAL_NED, RELATIVE_ALT_FRAMES, e7_to_deg

INT32_MAX = 2**31 - 1
INT32_MIN = -(2**31)  # what a NaN latitude cast to int32 becomes (MAVSDK's do_orbit with NaN)
REPOSITION_CHANGE_MODE = 1  # MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
SPEED_TYPES_XY = (0.0, 1.0)  # SPEED_TYPE_AIRSPEED, SPEED_TYPE_GROUNDSPEED
ORBIT_YAW_BEHAVIOURS = range(5)  # ORBIT_YAW_BEHAVIOUR_* 0..4
ORBIT_YAW_RC_CONTROLLED = 4


def height_m(z: float, frame: int | None, origin: GeoOrigin) -> float | None:
    """Height above home of param7/z (None when NaN): relative and terrain frames give a height
    (the world is flat at home), MAV_FRAME_LOCAL_NED a down coordinate, others AMSL."""
    if not math.isfinite(z):
        return None
    if frame in RELATIVE_ALT_FRAMES:
        return z
    if frame == LOCAL_NED:
        return -z
    return z - origin.alt_amsl_m


def global_point(params: Sequence[float], frame: int | None) -> tuple[float, float] | None | str:
    """(lat, lon) in degrees from params 5/6; None when unset (NaN, or INT32_MAX/INT32_MIN in
    COMMAND_INT); a reason string when out of range."""
    x, y = params[4], params[5]
    if frame is not None:
        if x in (INT32_MAX, INT32_MIN) or y in (INT32_MAX, INT32_MIN):
            return None
        x, y = e7_to_deg(x), e7_to_deg(y)
    if math.isnan(x) or math.isnan(y):
        return None
    if not (-90.0 <= x <= 90.0 and -180.0 <= y <= 180.0):
        return f"latitude/longitude ({x}, {y}) out of range"
    return x, y


def reposition(v: Vehicle, origin: GeoOrigin, p: Sequence[float], frame: int | None) -> Outcome:
    """DO_REPOSITION: with the change-mode flag (or already in Hold) AUTO.LOITER flies to the point
    at param1 m/s (<= 0 or NaN: the cruise speed), heading param4 (NaN: keep), and holds there.
    Unset lat/lon keep the current position, an unset altitude the current altitude."""
    point = global_point(p, frame)
    if isinstance(point, str):
        return Outcome(Result.DENIED, f"Reposition denied: {point}")
    flags = int(p[1]) if math.isfinite(p[1]) and 0 <= p[1] < 2**31 else 0
    if not flags & REPOSITION_CHANGE_MODE and v.mode is not FlightMode.LOITER:
        return Outcome(Result.ACCEPTED, "Reposition ignored: not in Hold (set change-mode flag)")
    s = v.state()
    north, east = (s.north_m, s.east_m) if point is None else origin.to_local(*point)
    height = height_m(p[6], frame, origin)
    down = s.down_m if height is None else -height
    yaw = p[3] if math.isfinite(p[3]) else None
    target = v.fly_to(FlightMode.LOITER, (north, east, down), yaw)
    if target is not None:
        v.guidance.reposition_target = target
        v.guidance.reposition_speed_mps = p[0] if math.isfinite(p[0]) and p[0] > 0 else None
    return ACCEPTED


def change_speed(v: Vehicle, p: Sequence[float]) -> Outcome:
    """DO_CHANGE_SPEED: param2 > 0 sets the AUTO modes' horizontal cruise speed (capped by
    MPC_XY_VEL_MAX), anything else (-1) restores MPC_XY_CRUISE; as PX4's navigator."""
    if math.isfinite(p[0]) and p[0] not in SPEED_TYPES_XY:
        return Outcome(Result.UNSUPPORTED, "Change speed: only air/ground speed (types 0, 1)")
    speed = p[1]
    v.guidance.cruise_override_mps = speed if math.isfinite(speed) and speed > 0 else None
    v.guidance.reposition_speed_mps = None  # the latest speed command wins
    return ACCEPTED


def orbit(v: Vehicle, origin: GeoOrigin, p: Sequence[float], frame: int | None) -> Outcome:
    """DO_ORBIT: radius param1 (sign = direction, positive clockwise), speed param2, yaw
    behaviour param3, centre x/y and altitude z; NaN keeps the orbit's current value (a new orbit:
    1 m, 1 m/s, front to centre, here), as PX4's FlightTaskOrbit."""
    s = v.state()
    if not s.armed or not s.in_air:
        return Outcome(Result.TEMPORARILY_REJECTED, "Orbit denied: vehicle not flying")
    point = global_point(p, frame)
    if isinstance(point, str):
        return Outcome(Result.DENIED, f"Orbit denied: {point}")
    if math.isfinite(p[2]) and int(p[2]) not in ORBIT_YAW_BEHAVIOURS:
        return Outcome(Result.DENIED, f"Orbit denied: yaw behaviour {p[2]:g} unknown")
    old = v.guidance.orbit if s.mode is FlightMode.ORBIT else None
    # A new orbit starts as PX4's FlightTaskOrbit does: at its smallest radius and default speed.
    radius = (
        abs(p[0])
        if math.isfinite(p[0]) and p[0] != 0
        else (old.radius_m if old else ORBIT_RADIUS_MIN_M)
    )
    clockwise = (
        p[0] > 0 if math.isfinite(p[0]) and p[0] != 0 else (old.speed_mps >= 0 if old else True)
    )
    speed = (
        abs(p[1])
        if math.isfinite(p[1])
        else (abs(old.speed_mps) if old else ORBIT_DEFAULT_SPEED_MPS)
    )
    radius, speed = sanitize_orbit(
        radius,
        speed if clockwise else -speed,
        v.params["MPC_XY_VEL_MAX"],
        v.params["MPC_ACC_HOR_MAX"],
    )
    yaw_mode = (
        int(p[2]) if math.isfinite(p[2]) else (old.yaw_behaviour if old else YAW_FRONT_TO_CENTER)
    )
    if point is not None:
        cn, ce = origin.to_local(*point)
    else:
        cn, ce = (old.center_north_m, old.center_east_m) if old else (s.north_m, s.east_m)
    height = height_m(p[6], frame, origin)
    down = (old.down_m if old else s.down_m) if height is None else -height
    if yaw_mode == ORBIT_YAW_RC_CONTROLLED:  # no RC here: PX4's default behaviour
        yaw_mode = YAW_FRONT_TO_CENTER
    v.guidance.orbit = Orbit(cn, ce, down, radius, speed, yaw_mode, s.yaw_rad)
    v.fly_to(FlightMode.ORBIT, (cn, ce, down))
    return ACCEPTED


def inject_failure(v: Vehicle, p: Sequence[float]) -> Outcome:
    """INJECT_FAILURE: DENIED unless SYS_FAILURE_EN is 1 (PX4 runs no failure injector then);
    param1 the FAILURE_UNIT, param2 the FAILURE_TYPE (see :mod:`sitl_stub.flight.failures`)."""
    if int(v.params["SYS_FAILURE_EN"]) != 1:
        return Outcome(Result.DENIED, "Failure injection disabled (SYS_FAILURE_EN 0)")
    if not all(math.isfinite(x) and x == int(x) for x in p[:2]):
        return Outcome(Result.DENIED, "Failure injection: unit and type must be integers")
    outcome = v.failures.inject(int(p[0]), int(p[1]))
    if outcome.ok and int(p[1]) == FAILURE_TYPE_OFF:
        return Outcome(Result.ACCEPTED, f"Failure injected: unit {int(p[0])} off")
    return outcome
