"""Guided commands over real MAVLink (pymavlink over loopback UDP) against an in-process SitlServer:
DO_REPOSITION (as MAVSDK's goto_location sends it), DO_CHANGE_SPEED, DO_ORBIT with
ORBIT_EXECUTION_STATUS, INJECT_FAILURE behind SYS_FAILURE_EN, and UNSUPPORTED for the rest."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import pytest
from support.mavlink_gcs import Gcs
from support.sitl_hover import LOITER_MODE, hovering

from sitl_stub.core.params import int_to_param_float
from sitl_stub.mavlink.server import SitlServer
from uavlink.mavlink.dialect import mavutil

pytestmark = [pytest.mark.slow, pytest.mark.waits, pytest.mark.timeout(120)]

mavlink = mavutil.mavlink
NAN = math.nan
A, D, U = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_UNSUPPORTED
ORBIT_MODE = 3 << 16 | 1 << 24  # POSCTL.ORBIT


@pytest.fixture
def flying() -> Iterator[tuple[SitlServer, Gcs]]:
    """Hovering at 10 m, speed 10."""
    with hovering(10.0) as (server, gcs):
        yield server, gcs


def command_int(
    gcs: Gcs,
    cmd: int,
    frame: int,
    p: tuple[float, float, float, float],
    x: int,
    y: int,
    z: float,
    wait_s: float = 5.0,
) -> int | None:
    """COMMAND_INT to the autopilot; the ACK's result or None."""
    before = len(gcs.acks)
    gcs.mav.command_int_send(1, 1, frame, cmd, 0, 0, *p, x, y, z)
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        gcs.pump()
        for ack in gcs.acks[before:]:
            if ack.command == cmd:
                return int(ack.result)
    return None


def goto(
    gcs: Gcs, server: SitlServer, north_m: float, east_m: float, alt_m: float, yaw_deg: float = 0.0
) -> int | None:
    """MAVSDK's goto_location: DO_REPOSITION as COMMAND_INT, GLOBAL_INT, AMSL, yaw in radians."""
    home = server.config.home
    lat, lon = home.to_global(north_m, east_m)
    return command_int(
        gcs,
        mavlink.MAV_CMD_DO_REPOSITION,
        mavlink.MAV_FRAME_GLOBAL_INT,
        (NAN, mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, NAN, math.radians(yaw_deg)),
        round(lat * 1e7),
        round(lon * 1e7),
        home.alt_amsl_m + alt_m,
    )


def test_goto_flies_to_the_point_and_holds(flying):
    server, gcs = flying
    assert goto(gcs, server, 40.0, -30.0, 25.0, yaw_deg=90.0) == A
    home = server.config.home
    lat, lon = home.to_global(40.0, -30.0)
    gcs.wait(
        lambda: (
            "GLOBAL_POSITION_INT" in gcs.last
            and abs(gcs.last["GLOBAL_POSITION_INT"].lat - lat * 1e7) < 20
            and abs(gcs.last["GLOBAL_POSITION_INT"].lon - lon * 1e7) < 20
            and abs(gcs.last["GLOBAL_POSITION_INT"].relative_alt - 25000) < 200
        ),
        30,
        "arrival",
    )
    time.sleep(1.0)  # 10 simulated seconds: it holds there
    s = server.state()
    assert gcs.mode == (LOITER_MODE, True)
    assert (s.north_m, s.east_m, s.altitude_m) == pytest.approx((40.0, -30.0, 25.0), abs=0.1)
    assert s.yaw_rad == pytest.approx(math.pi / 2, abs=0.01) and s.ground_speed_mps < 0.05


def test_change_speed_changes_the_cruise_speed(flying):
    server, gcs = flying
    assert goto(gcs, server, 180.0, 0.0, 10.0) == A
    gcs.wait(lambda: server.state().north_m > 30.0, 20, "cruising")
    assert gcs.last["VFR_HUD"].groundspeed == pytest.approx(5.0, abs=0.1)  # MPC_XY_CRUISE
    # MAVSDK's set_current_speed: param1 1 (ground speed), param2 the speed, param3 -1
    assert gcs.command(mavlink.MAV_CMD_DO_CHANGE_SPEED, 1, 9.0, -1, 0) == A
    gcs.wait(lambda: gcs.wait_message("VFR_HUD").groundspeed > 8.9, 10, "9 m/s")
    # the server's snapshot trails the loop's messages (8.94 m/s once, under load): wait for it too
    gcs.wait(
        lambda: server.state().ground_speed_mps == pytest.approx(9.0, abs=0.05),
        5,
        "9 m/s in the state",
    )
    assert server.state().ground_speed_mps == pytest.approx(9.0, abs=0.05)


def test_orbit_circles_at_the_radius(flying):
    server, gcs = flying
    lat, lon = server.config.home.to_global(0.0, 0.0)
    # MAVSDK's do_orbit: COMMAND_INT, centre lat/lon, absolute altitude; radius 15 m clockwise
    assert (
        command_int(
            gcs,
            mavlink.MAV_CMD_DO_ORBIT,
            mavlink.MAV_FRAME_GLOBAL_INT,
            (15.0, 3.0, 0.0, NAN),
            round(lat * 1e7),
            round(lon * 1e7),
            server.config.home.alt_amsl_m + 12.0,
        )
        == A
    )
    gcs.wait(lambda: gcs.mode == (ORBIT_MODE, True), 5, "POSCTL.ORBIT in the heartbeat")
    status = gcs.wait_message("ORBIT_EXECUTION_STATUS")
    assert status.radius == pytest.approx(15.0) and status.frame == mavlink.MAV_FRAME_GLOBAL
    assert (status.x, status.y) == (round(lat * 1e7), round(lon * 1e7))
    assert status.z == pytest.approx(server.config.home.alt_amsl_m + 12.0)
    time.sleep(4.0)  # 40 simulated seconds: on the circle
    radii = []
    for _ in range(20):
        m = gcs.wait_message("LOCAL_POSITION_NED")
        radii.append(math.hypot(m.x, m.y))
        assert math.hypot(m.vx, m.vy) == pytest.approx(3.0, abs=0.1) and m.z == pytest.approx(
            -12.0, abs=0.2
        )
    assert min(radii) > 14.5 and max(radii) < 15.5
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 129, 4, 3) == A  # MAVSDK's hold() ends it
    gcs.wait(lambda: gcs.mode == (LOITER_MODE, True), 5, "hold")


def test_inject_failure_needs_sys_failure_en(flying):
    server, gcs = flying
    gps = mavlink.MAV_SYS_STATUS_SENSOR_GPS
    # MAVSDK's failure.inject: COMMAND_LONG unit, type, instance
    assert (
        gcs.command(
            mavlink.MAV_CMD_INJECT_FAILURE,
            mavlink.FAILURE_UNIT_SENSOR_GPS,
            mavlink.FAILURE_TYPE_OFF,
            0,
        )
        == D
    )
    assert gcs.wait_message("GPS_RAW_INT").fix_type == mavlink.GPS_FIX_TYPE_3D_FIX
    gcs.mav.param_set_send(
        1, 1, b"SYS_FAILURE_EN", int_to_param_float(1), mavlink.MAV_PARAM_TYPE_INT32
    )
    gcs.wait(lambda: server.params["SYS_FAILURE_EN"] == 1, 5, "SYS_FAILURE_EN = 1")
    assert (
        gcs.command(
            mavlink.MAV_CMD_INJECT_FAILURE,
            mavlink.FAILURE_UNIT_SENSOR_GPS,
            mavlink.FAILURE_TYPE_OFF,
            0,
        )
        == A
    )
    assert gcs.wait_message("GPS_RAW_INT", pred=lambda m: m.fix_type == 0).satellites_visible == 0
    assert not gcs.wait_message("SYS_STATUS").onboard_control_sensors_health & gps
    assert (
        gcs.command(
            mavlink.MAV_CMD_INJECT_FAILURE,
            mavlink.FAILURE_UNIT_SENSOR_GPS,
            mavlink.FAILURE_TYPE_OK,
            0,
        )
        == A
    )
    gcs.wait_message("GPS_RAW_INT", pred=lambda m: m.fix_type == mavlink.GPS_FIX_TYPE_3D_FIX)
    assert (
        gcs.command(
            mavlink.MAV_CMD_INJECT_FAILURE,
            mavlink.FAILURE_UNIT_SENSOR_BARO,
            mavlink.FAILURE_TYPE_STUCK,
            0,
        )
        == U
    )
    assert (
        gcs.command(
            mavlink.MAV_CMD_INJECT_FAILURE,
            mavlink.FAILURE_UNIT_SYSTEM_MOTOR,
            mavlink.FAILURE_TYPE_OFF,
            0,
        )
        == A
    )
    gcs.wait(lambda: gcs.mode is not None and not gcs.mode[1], 20, "the vehicle falls and disarms")
    assert not server.state().in_air


def test_unknown_command_is_unsupported_at_once(flying):
    server, gcs = flying
    t0 = time.monotonic()
    assert gcs.command(31000, 1, 2, 3) == U  # MAV_CMD_USER_1
    assert (
        command_int(
            gcs,
            mavlink.MAV_CMD_DO_SET_ROI_LOCATION,
            mavlink.MAV_FRAME_GLOBAL_INT,
            (NAN, NAN, NAN, NAN),
            0,
            0,
            NAN,
        )
        == U
    )
    assert (
        time.monotonic() - t0 < 2.0
    )  # answered, not left to the 3 s ACK waits (a loaded machine's margin)
    gcs.wait(
        lambda: server.report()["rejected"].get("command_unsupported") == 2, 2, "both counted"
    )  # counted just after the ACK is sent
