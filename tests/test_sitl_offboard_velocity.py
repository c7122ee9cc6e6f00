"""Offboard beyond position over real MAVLink (pymavlink over loopback UDP) against an in-process
SitlServer: velocity setpoints in NED and body frames, position + velocity, SET_POSITION_TARGET_
GLOBAL_INT, and attitude setpoints refused. Type masks are the ones MAVSDK's offboard plugin sends."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator

import pytest
from support.mavlink_gcs import Gcs
from support.sitl_hover import LOITER_MODE, hovering

from sitl_stub.mavlink.server import SitlServer
from uavlink.mavlink.dialect import mavutil

pytestmark = [pytest.mark.slow, pytest.mark.waits, pytest.mark.timeout(120)]

mavlink = mavutil.mavlink
NAN = math.nan
A, REJECTED = mavlink.MAV_RESULT_ACCEPTED, mavlink.MAV_RESULT_TEMPORARILY_REJECTED
VELOCITY_NED, VELOCITY_BODY, POSITION_VELOCITY, POSITION = 0x9C7, 0x5C7, 0x9C0, 0x9F8
OFFBOARD_MODE = 6 << 16


class Streamer:
    """Sends ``send()`` every 50 ms of wall time (MAVSDK's 20 Hz) while pumping the GCS."""

    def __init__(self, gcs: Gcs) -> None:
        self.gcs = gcs
        self.send: Callable[[], None] | None = None
        self._last = 0.0

    def pump(self) -> None:
        now = time.monotonic()
        if self.send is not None and now - self._last >= 0.05:
            self._last = now
            self.send()
        self.gcs.pump()

    def run(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.pump()


@pytest.fixture
def flying() -> Iterator[tuple[SitlServer, Gcs, Streamer]]:
    """Hovering at 10 m, speed 4 (so MAVSDK's 20 Hz wall is 5 setpoints per simulated second)."""
    with hovering(4.0) as (server, gcs):
        yield server, gcs, Streamer(gcs)


def local(
    gcs: Gcs,
    frame: int,
    mask: int,
    pos=(0.0, 0.0, 0.0),
    vel=(0.0, 0.0, 0.0),
    yaw: float = 0.0,
    yaw_rate: float = 0.0,
) -> Callable[[], None]:
    return lambda: gcs.mav.set_position_target_local_ned_send(
        0, 1, 1, frame, mask, *pos, *vel, 0, 0, 0, yaw, yaw_rate
    )


def start_offboard(gcs: Gcs, streamer: Streamer) -> None:
    """MAVSDK's offboard.start(): stream first, then DO_SET_MODE OFFBOARD."""
    streamer.run(0.3)
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 129, 6, 0) == A
    gcs.wait(lambda: (streamer.pump() or True) and gcs.mode == (OFFBOARD_MODE, True), 5, "OFFBOARD")


def test_velocity_ned_moves_at_the_commanded_velocity(flying):
    server, gcs, streamer = flying
    streamer.send = local(
        gcs, mavlink.MAV_FRAME_LOCAL_NED, VELOCITY_NED, vel=(2.0, -3.0, -0.5), yaw=math.radians(90)
    )
    start_offboard(gcs, streamer)
    streamer.run(2.0)  # 8 simulated seconds
    s = server.state()
    assert (s.vn_mps, s.ve_mps, s.vd_mps) == pytest.approx((2.0, -3.0, -0.5), abs=0.05)
    assert s.yaw_rad == pytest.approx(math.pi / 2, abs=0.01)
    m = gcs.wait_message("LOCAL_POSITION_NED")
    assert (m.vx, m.vy) == pytest.approx((2.0, -3.0), abs=0.05)
    streamer.send = None  # the stream stops: offboard-loss failsafe to Hold, no drift
    gcs.wait(lambda: gcs.mode == (LOITER_MODE, True), 5, "failsafe to hold")
    time.sleep(2.0)
    assert server.state().ground_speed_mps < 0.05 and server.state().offboard_failsafes == 1


def test_velocity_body_follows_the_heading(flying):
    server, gcs, streamer = flying
    # heading east first (a NED velocity setpoint with yaw), then forward in the body frame
    streamer.send = local(gcs, mavlink.MAV_FRAME_LOCAL_NED, VELOCITY_NED, yaw=math.radians(90))
    start_offboard(gcs, streamer)
    streamer.run(1.5)
    assert server.state().yaw_rad == pytest.approx(math.pi / 2, abs=0.01)
    streamer.send = local(gcs, mavlink.MAV_FRAME_BODY_NED, VELOCITY_BODY, vel=(4.0, 0.0, 0.0))
    streamer.run(2.0)
    s = server.state()
    assert (s.vn_mps, s.ve_mps) == pytest.approx((0.0, 4.0), abs=0.05)  # forward = east
    streamer.send = local(
        gcs,
        mavlink.MAV_FRAME_BODY_FRD,
        VELOCITY_BODY,
        vel=(0.0, 0.0, 0.0),
        yaw_rate=math.radians(20),
    )
    streamer.run(1.0)
    assert server.state().yaw_rate_radps == pytest.approx(math.radians(20), abs=1e-3)


def test_position_with_velocity_feed_forward_arrives_and_stops(flying):
    server, gcs, streamer = flying
    streamer.send = local(
        gcs,
        mavlink.MAV_FRAME_LOCAL_NED,
        POSITION_VELOCITY,
        pos=(30.0, 20.0, -15.0),
        vel=(0.0, 0.0, 0.0),
    )
    start_offboard(gcs, streamer)
    gcs.wait(
        lambda: (
            (streamer.pump() or True)
            and math.dist(
                (server.state().north_m, server.state().east_m, server.state().down_m),
                (30.0, 20.0, -15.0),
            )
            < 0.2
        ),
        30,
        "arrival",
    )
    assert server.state().setpoints_accepted > 0


def test_global_int_setpoint_flies_to_lat_lon(flying):
    server, gcs, streamer = flying
    home = server.config.home
    lat, lon = home.to_global(-25.0, 35.0)
    # MAVSDK's set_position_global, altitude relative to home
    streamer.send = lambda: gcs.mav.set_position_target_global_int_send(
        0,
        1,
        1,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        POSITION,
        round(lat * 1e7),
        round(lon * 1e7),
        18.0,
        0,
        0,
        0,
        0,
        0,
        0,
        0.0,
        0.0,
    )
    start_offboard(gcs, streamer)
    gcs.wait(
        lambda: (
            (streamer.pump() or True)
            and math.dist(
                (server.state().north_m, server.state().east_m, server.state().altitude_m),
                (-25.0, 35.0, 18.0),
            )
            < 0.2
        ),
        30,
        "arrival at the global setpoint",
    )
    # AMSL altitude (MAV_FRAME_GLOBAL_INT)
    streamer.send = lambda: gcs.mav.set_position_target_global_int_send(
        0,
        1,
        1,
        mavlink.MAV_FRAME_GLOBAL_INT,
        POSITION,
        round(lat * 1e7),
        round(lon * 1e7),
        home.alt_amsl_m + 12.0,
        0,
        0,
        0,
        0,
        0,
        0,
        0.0,
        0.0,
    )
    gcs.wait(
        lambda: (streamer.pump() or True) and abs(server.state().altitude_m - 12.0) < 0.2,
        20,
        "12 m above home",
    )


def test_attitude_setpoints_are_refused(flying):
    server, gcs, streamer = flying
    # MAVSDK's set_attitude: SET_ATTITUDE_TARGET, body rates ignored
    streamer.send = lambda: gcs.mav.set_attitude_target_send(
        0, 1, 1, 0x07, [1, 0, 0, 0], 0, 0, 0, 0.5
    )
    streamer.run(0.5)
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 129, 6, 0) == REJECTED  # no usable stream
    gcs.wait(lambda: server.report()["rejected"].get("setpoint_attitude", 0) > 3, 5, "counted")
    accel = local(gcs, mavlink.MAV_FRAME_LOCAL_NED, 0xC3F, vel=(1.0, 0.0, 0.0))
    streamer.send = accel  # MAVSDK's set_acceleration_ned: refused too
    streamer.run(0.5)
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 129, 6, 0) == REJECTED
    assert server.report()["rejected"]["setpoint_type_mask"] > 3
    assert gcs.mode == (LOITER_MODE, True) and server.state().setpoints_accepted == 0
