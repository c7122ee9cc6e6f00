"""The SITL vehicle's position controller and point-mass kinematics, one integration substep at a
time. Positions (LOCAL_NED) and velocities are 3-lists updated in place; angles in radians.

The controller is a velocity-limited P loop with an acceleration limit and a braking curve
(``v <= sqrt(2 a d)``), so it never overshoots a setpoint; yaw turns at a limited rate. The mode
logic that picks targets and limits is :class:`sitl_stub.flight.vehicle.Vehicle`'s.
"""

from __future__ import annotations

import math

from uavlink.config.position_loop import BRAKE_FRACTION, POS_GAIN_PER_S

GRAVITY_MPS2 = 9.81
ACC_Z_MPS2 = 3.0  # PX4 MPC_ACC_DOWN_MAX (and below MPC_ACC_UP_MAX 4)
YAW_RATE_RADPS = math.radians(45.0)  # PX4 MPC_YAWRAUTO_MAX
GROUND_EPS_M = 0.05  # "on the ground" below this altitude


def track(
    pos: list[float],
    vel: list[float],
    target: tuple[float, float, float],
    limits: tuple[float, float, float],
    acc_xy_mps2: float,
    h: float,
    velocity_ff: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[float, float]:
    """Fly ``h`` seconds towards ``target`` within ``limits`` (horizontal speed, climb rate,
    descent rate, m/s); returns the horizontal acceleration (north, east) it used.

    As PX4's position controller: the velocity setpoint is ``velocity_ff`` plus the braking-curve
    P term of the position error; a NaN target axis is flown on ``velocity_ff`` alone (north and
    east are NaN together)."""
    xy_max, up_max, down_max = limits
    tn, te, td = target
    # Horizontal: braking-curve P control plus feed-forward, acceleration-limited.
    vdn, vde = velocity_ff[0], velocity_ff[1]
    if not (math.isnan(tn) or math.isnan(te)):
        en, ee = tn - pos[0], te - pos[1]
        dist = norm(en, ee)
        speed = min(
            xy_max, POS_GAIN_PER_S * dist, math.sqrt(2.0 * BRAKE_FRACTION * acc_xy_mps2 * dist)
        )
        if dist > 1e-9:
            vdn, vde = vdn + en / dist * speed, vde + ee / dist * speed
    vdn, vde = _limit_norm(vdn, vde, xy_max)
    dvn, dve = _limit_norm(vdn - vel[0], vde - vel[1], acc_xy_mps2 * h)
    vel[0] += dvn
    vel[1] += dve
    vel[0], vel[1] = _limit_norm(vel[0], vel[1], xy_max)  # a lowered MPC_XY_VEL_MAX applies at once
    # Vertical (down positive).
    vd_des = velocity_ff[2]
    if not math.isnan(td):
        ed = td - pos[2]
        vmax = down_max if ed > 0 else up_max
        vd_des += math.copysign(
            min(
                vmax,
                POS_GAIN_PER_S * abs(ed),
                math.sqrt(2.0 * BRAKE_FRACTION * ACC_Z_MPS2 * abs(ed)),
            ),
            ed,
        )
    vd_des = max(-up_max, min(down_max, vd_des))
    dvd = max(-ACC_Z_MPS2 * h, min(ACC_Z_MPS2 * h, vd_des - vel[2]))
    vel[2] = max(-up_max, min(down_max, vel[2] + dvd))
    for i in range(3):
        pos[i] += vel[i] * h
    return dvn / h, dve / h


def hold_in_fence(pos: list[float], vel: list[float], fence_m: float) -> None:
    """The hard fence ``|north|, |east| <= fence_m``: a horizontal axis past it is put back on it
    and its velocity stopped (in place)."""
    for i in (0, 1):
        if abs(pos[i]) > fence_m:
            pos[i] = math.copysign(fence_m, pos[i])
            vel[i] = 0.0


def _limit_norm(a: float, b: float, max_norm: float) -> tuple[float, float]:
    n = norm(a, b)
    return (a * max_norm / n, b * max_norm / n) if n > max_norm else (a, b)


def norm(a: float, b: float) -> float:
    """The length of (a, b) as ``sqrt(a a + b b)``, not ``math.hypot``: the env's model of this
    loop (``uavlink.mobility.uav_motion.PositionLoop``) computes the same operations in numpy,
    whose ``hypot`` rounds differently from Python's in about 0.6 % of cases, and a lockstep flight
    is to equal its evaluation to the bit (a policy's episode can turn on the last bits)."""
    return math.sqrt(a * a + b * b)


def turn(
    yaw_rad: float, yaw_target_rad: float | None, h: float, yaw_rate_radps: float | None = None
) -> tuple[float, float]:
    """(yaw, yaw rate) after turning ``h`` seconds towards the target at the limited rate, or at
    ``yaw_rate_radps`` (limited the same) when given."""
    if yaw_rate_radps is not None:
        rate = max(-YAW_RATE_RADPS, min(YAW_RATE_RADPS, yaw_rate_radps))
        return wrap(yaw_rad + rate * h), rate
    if yaw_target_rad is None:
        return yaw_rad, 0.0
    err = wrap(yaw_target_rad - yaw_rad)
    step = max(-YAW_RATE_RADPS * h, min(YAW_RATE_RADPS * h, err))
    return wrap(yaw_rad + step), step / h


def fall(pos: list[float], vel: list[float], h: float) -> None:
    """Unpowered: fall under gravity until on the ground, then rest."""
    if -pos[2] > GROUND_EPS_M or vel[2] < 0:
        vel[2] += GRAVITY_MPS2 * h
        for i in range(3):
            pos[i] += vel[i] * h
    else:
        vel[:] = [0.0, 0.0, 0.0]


def stopping_point(
    pos: list[float], vel: list[float], acc_xy_mps2: float
) -> tuple[float, float, float]:
    """Where braking at 90 % of ``acc_xy_mps2`` from the current velocity ends (not clamped)."""
    a = BRAKE_FRACTION * acc_xy_mps2
    vn, ve = vel[0], vel[1]
    s = math.hypot(vn, ve) / (2.0 * a)
    return (pos[0] + vn * s, pos[1] + ve * s, pos[2])


def tilt(acc_ne: tuple[float, float], yaw_rad: float) -> tuple[float, float]:
    """(roll, pitch) of a multicopter accelerating at ``acc_ne`` with heading ``yaw_rad``."""
    an, ae = acc_ne
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    fwd, right = an * c + ae * s, -an * s + ae * c
    return math.atan2(right, GRAVITY_MPS2), -math.atan2(fwd, GRAVITY_MPS2)


def wrap(a: float) -> float:
    """An angle wrapped to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi
