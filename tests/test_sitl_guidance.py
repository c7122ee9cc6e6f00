"""Guidance beyond position setpoints, without sockets: type masks as PX4 reads them, body-frame
rotation, fence braking, orbit geometry, and the vehicle flying velocity setpoints, orbits,
repositions, speed changes and injected failures in simulated time."""

from __future__ import annotations

import math

import pytest

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.modes import FlightMode
from sitl_stub.core.params import ParamStore
from sitl_stub.core.vehicle_state import Result
from sitl_stub.flight.guidance import (
    YAW_FRONT_TANGENT,
    Motion,
    Orbit,
    body_to_ned,
    brake_before,
    sanitize_orbit,
)
from sitl_stub.flight.vehicle import Vehicle
from sitl_stub.mavlink import guided_commands as guided
from sitl_stub.mavlink.setpoints import Refusal, Setpoint, read_setpoint

NAN = math.nan
# MAVSDK offboard_impl.cpp's type masks
VELOCITY_NED, VELOCITY_BODY, POSITION_VELOCITY, ACCELERATION, POSITION = (
    0x9C7,
    0x5C7,
    0x9C0,
    0xC3F,
    0x9F8,
)
ORIGIN = GeoOrigin()


def flying(alt_m: float = 10.0, **params: float) -> Vehicle:
    v = Vehicle(
        ParamStore(
            {"MIS_TAKEOFF_ALT": alt_m, "MPC_TKO_SPEED": 5.0, "MPC_Z_VEL_MAX_UP": 5.0, **params}
        )
    )
    assert v.arm().ok and v.takeoff().ok
    v.step(alt_m / 5.0 + 5.0)
    assert v.mode is FlightMode.LOITER and abs(v.state().altitude_m - alt_m) < 0.5
    return v


def offboard_velocity(v: Vehicle, velocity_ned: tuple[float, float, float], seconds: float) -> None:
    motion = Motion(velocity_ned, (True, True, True))
    v.offer_setpoint(0.0, 0.0, 0.0, None, motion)
    if v.mode is not FlightMode.OFFBOARD:
        assert v.start_offboard().ok
    for _ in range(int(seconds / 0.05)):
        v.offer_setpoint(0.0, 0.0, 0.0, None, motion)
        v.step(0.05)


@pytest.mark.parametrize(
    ("mask", "free", "velocity"),
    [
        (VELOCITY_NED, (True, True, True), (1.0, 2.0, -0.5)),
        (POSITION_VELOCITY, (False, False, False), (1.0, 2.0, -0.5)),
        (0x9C3, (True, True, False), (1.0, 2.0, -0.5)),  # velocity north/east, position down
    ],
)
def test_masks_mavsdk_sends_become_motions(mask, free, velocity):
    sp = read_setpoint(mask, (5.0, 6.0, -7.0), (1.0, 2.0, -0.5), 0.3, 0.0)
    assert isinstance(sp, Setpoint) and sp.motion is not None
    assert sp.motion.free_axes == free and sp.motion.velocity_ned == velocity
    assert sp.yaw_rad == 0.3 and sp.motion.yaw_rate_radps is None
    assert [math.isnan(p) for p in sp.position_ned] == list(free)


def test_position_masks_stay_position_setpoints():
    for mask in (POSITION, 0xDF8, 0x1F8):
        sp = read_setpoint(mask, (5.0, 6.0, -7.0), (9.0, 9.0, 9.0), 0.3, 0.0)
        assert (
            isinstance(sp, Setpoint) and sp.motion is None and sp.position_ned == (5.0, 6.0, -7.0)
        )
    assert read_setpoint(0x1F8 | 0x400, (1, 2, 3), (0, 0, 0), 0.3, 0.0).yaw_rad is None


def test_body_velocity_is_rotated_by_heading_and_uses_yaw_rate():
    sp = read_setpoint(
        VELOCITY_BODY, (0, 0, 0), (2.0, 1.0, 0.5), 0.0, 0.2, body_yaw_rad=math.pi / 2
    )
    assert isinstance(sp, Setpoint) and sp.yaw_rad is None and sp.motion.yaw_rate_radps == 0.2
    assert sp.motion.velocity_ned == pytest.approx(
        (-1.0, 2.0, 0.5)
    )  # forward = east, right = south
    assert body_to_ned(1.0, 0.0, 0.0, math.pi) == pytest.approx((-1.0, 0.0, 0.0))


@pytest.mark.parametrize(
    ("mask", "body", "kind"),
    [
        (ACCELERATION, None, "setpoint_type_mask"),  # acceleration only: not flown
        (0xFFF, None, "setpoint_type_mask"),
        (0x9C1, None, "setpoint_type_mask"),  # north free, east not
        (0x9FF & ~0x8, None, "setpoint_type_mask"),  # position ignored, only vx given
        (POSITION, 0.0, "setpoint_frame"),  # positions in a body frame
    ],
)
def test_unusable_masks_are_refused(mask, body, kind):
    sp = read_setpoint(mask, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0), 0.0, 0.0, body_yaw_rad=body)
    assert isinstance(sp, Refusal) and sp.kind == kind and sp.text


def test_nan_velocity_is_refused():
    sp = read_setpoint(VELOCITY_NED, (0, 0, 0), (NAN, 0.0, 0.0), 0.0, 0.0)
    assert isinstance(sp, Refusal) and sp.kind == "setpoint_not_finite"


def test_braking_keeps_a_velocity_inside_the_fence():
    assert brake_before(0.0, 5.0, -100.0, 100.0, 5.0) == 5.0
    assert brake_before(99.0, 5.0, -100.0, 100.0, 5.0) == pytest.approx(math.sqrt(2 * 0.9 * 5.0))
    assert brake_before(100.0, 5.0, -100.0, 100.0, 5.0) == 0.0
    assert brake_before(100.0, -5.0, -100.0, 100.0, 5.0) == -5.0  # inwards: free


def test_orbit_limits_and_geometry():
    assert sanitize_orbit(0.2, 3.0, 12.0, 5.0)[0] == 1.0
    r, v = sanitize_orbit(5.0, -12.0, 12.0, 5.0)
    assert r == 5.0 and v < 0 and v * v < 5.0 * r  # speed lowered for the centripetal limit
    o = Orbit(0.0, 0.0, -10.0, 20.0, 5.0)  # clockwise
    vn, ve = o.velocity(20.0, 0.0)  # north of the centre: clockwise heads east
    assert (vn, ve) == pytest.approx((0.0, 5.0))
    assert o.velocity(30.0, 0.0)[0] < 0  # outside the circle: pulled in
    assert o.yaw(20.0, 0.0) == pytest.approx(-math.pi)  # front to the centre: south
    assert Orbit(0, 0, -10, 20, 5, YAW_FRONT_TANGENT).yaw(20.0, 0.0) == pytest.approx(math.pi / 2)
    assert o.signed_radius_m == 20.0 and Orbit(0, 0, -10, 20, -5).signed_radius_m == -20.0


def test_velocity_setpoint_flies_the_commanded_velocity():
    v = flying()
    offboard_velocity(v, (3.0, -4.0, -1.0), 6.0)
    s = v.state()
    assert (s.vn_mps, s.ve_mps, s.vd_mps) == pytest.approx((3.0, -4.0, -1.0), abs=1e-6)
    offboard_velocity(v, (30.0, 0.0, 0.0), 6.0)  # over MPC_XY_VEL_MAX: limited
    assert v.state().ground_speed_mps == pytest.approx(12.0)


def test_velocity_setpoint_stops_at_the_fence():
    v = flying()
    offboard_velocity(v, (0.0, 12.0, 0.0), 40.0)
    s = v.state()
    assert s.east_m == pytest.approx(v.fence_m, abs=0.05) and abs(s.ve_mps) < 0.05
    assert s.max_abs_xy_m <= v.fence_m


def test_velocity_setpoints_are_an_offboard_stream():
    v = flying(COM_OF_LOSS_T=1.0)
    offboard_velocity(v, (2.0, 0.0, 0.0), 2.0)
    v.step(1.5)  # stream stops
    assert v.mode is FlightMode.LOITER and v.state().offboard_failsafes == 1
    v.step(5.0)
    assert v.state().ground_speed_mps < 0.01  # holding, not drifting on the old velocity


def test_velocity_up_takes_off_in_offboard():
    v = Vehicle()
    motion = Motion((0.0, 0.0, -2.0), (True, True, True))
    v.offer_setpoint(0.0, 0.0, 0.0, None, motion)
    assert v.start_offboard().ok and v.arm().ok
    for _ in range(60):
        v.offer_setpoint(0.0, 0.0, 0.0, None, motion)
        v.step(0.05)
    assert v.state().in_air and v.state().vd_mps == pytest.approx(-2.0, abs=0.05)


def test_reposition_flies_to_the_point_at_the_cruise_speed_and_holds():
    v = flying()
    lat, lon = ORIGIN.to_global(60.0, -80.0)
    p = (NAN, 1.0, NAN, 0.5, lat * 1e7, lon * 1e7, ORIGIN.alt_amsl_m + 20.0)
    assert guided.reposition(v, ORIGIN, p, 5).ok  # COMMAND_INT in MAV_FRAME_GLOBAL_INT
    peak = 0.0
    for _ in range(600):
        v.step(0.1)
        peak = max(peak, v.state().ground_speed_mps)
    s = v.state()
    assert s.mode is FlightMode.LOITER and peak == pytest.approx(5.0, abs=0.01)  # MPC_XY_CRUISE
    assert (s.north_m, s.east_m, s.altitude_m) == pytest.approx((60.0, -80.0, 20.0), abs=0.05)
    assert s.yaw_rad == pytest.approx(0.5)
    assert guided.change_speed(v, (1.0, 8.0, -1.0, 0.0, 0, 0, 0)).ok
    assert guided.reposition(v, ORIGIN, (NAN, 1.0, NAN, NAN, 0.0, 0.0, NAN), None).ok  # LONG
    v.step(30.0)
    assert v.state().ground_speed_mps == pytest.approx(8.0, abs=0.01)


def test_orbit_circles_at_the_radius_and_speed():
    v = flying()
    lat, lon = ORIGIN.to_global(0.0, 0.0)
    p = (-25.0, 4.0, 0.0, NAN, lat * 1e7, lon * 1e7, NAN)  # counter-clockwise
    assert guided.orbit(v, ORIGIN, p, 5).ok and v.mode is FlightMode.ORBIT
    v.step(40.0)
    angles, radii = [], []
    for _ in range(100):
        v.step(0.1)
        s = v.state()
        radii.append(math.hypot(s.north_m, s.east_m))
        angles.append(math.atan2(s.east_m, s.north_m))
    assert (
        min(radii) > 24.5
        and max(radii) < 25.5
        and s.ground_speed_mps == pytest.approx(4.0, abs=0.05)
    )
    assert math.remainder(angles[-1] - angles[0], 2 * math.pi) < 0  # azimuth decreasing
    assert s.orbit is not None and s.orbit.signed_radius_m == -25.0
    assert s.altitude_m == pytest.approx(10.0, abs=0.1)


def test_orbit_needs_a_flying_vehicle():
    assert (
        guided.orbit(Vehicle(), ORIGIN, (10.0, 2.0, 0, 0, NAN, NAN, NAN), None).result
        is Result.TEMPORARILY_REJECTED
    )


def test_failure_injection_needs_sys_failure_en():
    v = flying()
    assert guided.inject_failure(v, (101, 1, 0, 0, 0, 0, 0)).result is Result.DENIED
    v.params.set("SYS_FAILURE_EN", 1)
    assert guided.inject_failure(v, (1, 1, 0, 0, 0, 0, 0)).result is Result.UNSUPPORTED  # accel
    assert guided.inject_failure(v, (4, 1, 0, 0, 0, 0, 0)).ok
    assert v.state().failures == frozenset({"gps"})
    assert guided.inject_failure(v, (4, 0, 0, 0, 0, 0, 0)).ok and not v.state().failures
    assert guided.inject_failure(v, (101, 1, 0, 0, 0, 0, 0)).ok  # motors off: it falls
    v.step(8.0)
    s = v.state()
    assert not s.in_air and not s.armed


def test_global_points_and_heights():
    assert guided.global_point((0, 0, 0, 0, 2**31 - 1, 2**31 - 1, 0), 5) is None
    assert guided.global_point((0, 0, 0, 0, -(2**31), -(2**31), 0), 5) is None
    assert guided.global_point((0, 0, 0, 0, 473977420, 85455940, 0), 5) == pytest.approx(
        (47.397742, 8.545594)
    )
    assert isinstance(guided.global_point((0, 0, 0, 0, 95.0, 0.0, 0), None), str)
    assert guided.height_m(508.0, 5, ORIGIN) == 20.0 and guided.height_m(20.0, 6, ORIGIN) == 20.0
    assert guided.height_m(508.0, None, ORIGIN) == 20.0 and guided.height_m(NAN, 6, ORIGIN) is None
