"""SET_POSITION_TARGET_* type masks read as PX4's mavlink_receiver reads them (pure, no MAVLink
I/O): what an offboard setpoint asks the vehicle to fly, or why it is refused.

Bits (POSITION_TARGET_TYPEMASK): 0-2 ignore x/y/z, 3-5 ignore vx/vy/vz, 6-8 ignore ax/ay/az,
9 force, 10 ignore yaw, 11 ignore yaw rate. An axis whose position is ignored is flown on its
velocity (which must then be given); north and east go together. Used velocities are a
feed-forward on top of the position. Accelerations are not flown: a setpoint with neither
position nor velocity is refused; alongside them they are ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sitl_stub.flight.guidance import Motion, body_to_ned, three
from uavlink.mavlink.typemask import IGNORE_POSITION, IGNORE_VELOCITY, IGNORE_YAW, IGNORE_YAW_RATE


@dataclass(frozen=True)
class Setpoint:
    """A usable setpoint: position (LOCAL_NED; free axes are NaN), yaw or None, motion or None
    (None: a plain position setpoint)."""

    position_ned: tuple[float, float, float]
    yaw_rad: float | None
    motion: Motion | None


@dataclass(frozen=True)
class Refusal:
    """Why a setpoint is not flown: a reject kind (for the server's counters) and the text."""

    kind: str
    text: str


def read_setpoint(
    type_mask: int,
    position_ned: tuple[float, float, float],
    velocity: tuple[float, float, float],
    yaw_rad: float,
    yaw_rate_radps: float,
    body_yaw_rad: float | None = None,
) -> Setpoint | Refusal:
    """The setpoint a SET_POSITION_TARGET_* message asks for. ``body_yaw_rad`` is the vehicle's
    heading when the frame is a body frame (velocity forward/right/down; positions refused)."""
    free = three(bool(type_mask & bit) for bit in IGNORE_POSITION)
    vel_used = tuple(not type_mask & bit for bit in IGNORE_VELOCITY)
    if all(free) and not any(vel_used):
        return Refusal(
            "setpoint_type_mask",
            f"setpoint type_mask 0x{type_mask:x} has neither "
            "position nor velocity: acceleration/force setpoints are not flown",
        )
    if free[0] != free[1]:
        return Refusal(
            "setpoint_type_mask",
            f"setpoint type_mask 0x{type_mask:x}: north and "
            "east positions must be used or ignored together",
        )
    if any(f and not v for f, v in zip(free, vel_used, strict=True)):
        return Refusal(
            "setpoint_type_mask",
            f"setpoint type_mask 0x{type_mask:x} leaves an axis with neither position nor velocity",
        )
    if body_yaw_rad is not None and not all(free):
        return Refusal(
            "setpoint_frame",
            "body-frame setpoints carry velocities only: send positions in MAV_FRAME_LOCAL_NED",
        )
    vel = three(v if used else 0.0 for v, used in zip(velocity, vel_used, strict=True))
    if not all(math.isfinite(v) for v in vel):  # positions: the vehicle checks (and counts)
        return Refusal("setpoint_not_finite", f"setpoint with a NaN/infinite velocity {velocity}")
    if body_yaw_rad is not None:
        vel = body_to_ned(*vel, body_yaw_rad)
    yaw = None if type_mask & IGNORE_YAW or not math.isfinite(yaw_rad) else yaw_rad
    rate = (
        yaw_rate_radps
        if yaw is None and not type_mask & IGNORE_YAW_RATE and math.isfinite(yaw_rate_radps)
        else None
    )
    pos = three(math.nan if f else p for p, f in zip(position_ned, free, strict=True))
    if not any(free) and not any(vel_used):
        return Setpoint(pos, yaw, None)
    return Setpoint(pos, yaw, Motion(vel, free, rate))
