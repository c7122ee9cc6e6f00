"""A SitlServer (in process, udpin loopback) hovering at 10 m with a pymavlink ground station on
it: the start of every guided-command and offboard test."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager

from sitl_stub.mavlink.server import ServerConfig, SitlServer
from support.mavlink_gcs import FAST_CLIMB_PARAMS, Gcs
from uavlink.mavlink.dialect import mavutil

mavlink = mavutil.mavlink
HOVER_ALT_M = 10.0
LOITER_MODE = 4 << 16 | 3 << 24


@contextmanager
def hovering(speed: float) -> Iterator[tuple[SitlServer, Gcs]]:
    """Arm, take off (NAV_TAKEOFF, all NaN, as MAVSDK) and wait in AUTO.LOITER at 10 m."""
    server = SitlServer(
        ServerConfig(
            connect="udpin:127.0.0.1:0",
            speed=speed,
            params={**FAST_CLIMB_PARAMS, "MIS_TAKEOFF_ALT": HOVER_ALT_M},
        )
    )
    with server:
        gcs = Gcs(server.address[1])
        try:
            gcs.wait(lambda: gcs.mode is not None, 20, "the vehicle's heartbeat")
            ok = mavlink.MAV_RESULT_ACCEPTED
            assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, wait_s=10) == ok
            assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 7, wait_s=10) == ok
            gcs.wait(
                lambda: (
                    gcs.mode == (LOITER_MODE, True)
                    and server.state().altitude_m > HOVER_ALT_M - 0.5
                ),
                30,
                "takeoff to 10 m",
            )
            yield server, gcs
        finally:
            gcs.close()
