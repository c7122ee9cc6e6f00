"""AUTO.MISSION and the geofence over MAVLink: a stock pymavlink ground station against an
in-process SitlServer on loopback, whose mission and fence lists are filled in-process."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import pytest
from support.mavlink_gcs import FAST_CLIMB_PARAMS, Gcs

from sitl_stub.core.mission_store import FENCE, MISSION, MissionItem
from sitl_stub.flight.geofence import POLYGON_INCLUSION
from sitl_stub.flight.mission_executor import NAV_LAND, NAV_TAKEOFF, NAV_WAYPOINT
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from uavlink.mavlink.dialect import mavlink

pytestmark = [pytest.mark.slow, pytest.mark.waits, pytest.mark.timeout(180)]

MISSION_MODE = (4, 4)
HOLD_MODE = (4, 3)


class MissionGcs(Gcs):
    """A Gcs that also keeps every MISSION_ITEM_REACHED and MISSION_CURRENT."""

    def __init__(self, port: int) -> None:
        super().__init__(port)
        self.reached: list[int] = []
        self.currents: list[tuple[int, int, int, int]] = []

    def _record(self, m: Any) -> None:
        super()._record(m)
        if m.get_type() == "MISSION_ITEM_REACHED":
            self.reached.append(m.seq)
        elif m.get_type() == "MISSION_CURRENT":
            self.currents.append((m.seq, m.total, m.mission_state, m.mission_mode))

    def set_mode(self, main: int, sub: int) -> int | None:
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, 1 | 128, main, sub)


@pytest.fixture
def link() -> Iterator[tuple[SitlServer, MissionGcs]]:
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", speed=5.0, params=FAST_CLIMB_PARAMS)
    ).start()
    gcs = MissionGcs(server.address[1])
    try:
        gcs.wait(lambda: gcs.mode is not None, 20.0, "the vehicle's heartbeat")
        yield server, gcs
    finally:
        gcs.close()
        server.stop()
        assert server.error is None


def item(
    server: SitlServer,
    seq: int,
    command: int,
    n: float,
    e: float,
    z: float,
    *,
    p1: float = 0.0,
    p2: float = 0.0,
    mission_type: int = MISSION,
) -> MissionItem:
    lat, lon = server.config.home.to_global(n, e)
    return MissionItem(
        seq,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        command,
        param1=p1,
        param2=p2,
        x=round(lat * 1e7),
        y=round(lon * 1e7),
        z=z,
        mission_type=mission_type,
    )


def custom_mode(main: int, sub: int) -> int:
    return main << 16 | sub << 24


def test_mission_by_mode_switch_reports_progress_pauses_and_resumes(link):
    server, gcs = link
    server.vehicle.plans.replace(
        MISSION,
        (
            item(server, 0, NAV_TAKEOFF, 0.0, 0.0, 10.0),
            item(server, 1, NAV_WAYPOINT, 30.0, 0.0, 10.0, p2=2.0),
            item(server, 2, NAV_WAYPOINT, 30.0, 60.0, 10.0, p2=2.0),
            item(server, 3, NAV_LAND, 30.0, 60.0, 0.0),
        ),
    )
    gcs.wait(lambda: gcs.currents and gcs.currents[-1][1] == 4, 10.0, "MISSION_CURRENT total 4")
    assert gcs.currents[-1][2] == mavlink.MISSION_STATE_NOT_STARTED
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.set_mode(*MISSION_MODE) == mavlink.MAV_RESULT_ACCEPTED
    gcs.wait(lambda: gcs.mode == (custom_mode(*MISSION_MODE), True), 5.0, "AUTO.MISSION")
    gcs.wait(lambda: 1 in gcs.reached, 60.0, "waypoint 1 reached")
    assert gcs.set_mode(*HOLD_MODE) == mavlink.MAV_RESULT_ACCEPTED  # MAVSDK's pause_mission
    gcs.wait(lambda: gcs.currents[-1][2] == mavlink.MISSION_STATE_PAUSED, 5.0, "paused")
    assert gcs.currents[-1][0] == 2
    # the server's snapshot is refreshed after its loop iteration, which can trail the message
    gcs.wait(lambda: server.state().mode.px4_name == "AUTO.LOITER", 5.0, "AUTO.LOITER (hold)")
    assert gcs.set_mode(*MISSION_MODE) == mavlink.MAV_RESULT_ACCEPTED  # resume
    gcs.wait(lambda: gcs.currents[-1][2] == mavlink.MISSION_STATE_ACTIVE, 5.0, "active again")
    gcs.wait(lambda: 3 in gcs.reached, 120.0, "the landing reached")
    assert gcs.reached == [0, 1, 2, 3]
    gcs.wait(
        lambda: not server.state().in_air, 5.0, "the snapshot on the ground"
    )  # it trails, as above
    s = server.state()
    assert math.dist((s.north_m, s.east_m), (30.0, 60.0)) < 1.5


def test_mission_start_command_and_a_setpoint_outside_the_fence_stops_and_holds(link):
    server, gcs = link
    corners = ((-50.0, -50.0), (-50.0, 50.0), (50.0, 50.0), (50.0, -50.0))
    server.vehicle.plans.replace(
        FENCE,
        tuple(
            item(server, i, POLYGON_INCLUSION, n, e, 0.0, p1=4.0, mission_type=FENCE)
            for i, (n, e) in enumerate(corners)
        ),
    )
    server.vehicle.plans.replace(
        MISSION,
        (
            item(server, 0, NAV_TAKEOFF, 0.0, 0.0, 10.0),
            item(server, 1, NAV_WAYPOINT, 10.0, 0.0, 10.0),
        ),
    )
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.command(mavlink.MAV_CMD_MISSION_START, 0, 0) == mavlink.MAV_RESULT_ACCEPTED
    gcs.wait(lambda: 1 in gcs.reached, 60.0, "the mission's waypoint")

    def stream_setpoint() -> bool:  # 10 Hz wall, position (120, 0) is 70 m beyond the fence
        gcs.mav.set_position_target_local_ned_send(
            0, 1, 0, mavlink.MAV_FRAME_LOCAL_NED, 0xDF8, 120.0, 0.0, -10.0, 0, 0, 0, 0, 0, 0, 0, 0
        )
        return "Geofence violation" in gcs.texts

    stream_setpoint()
    assert gcs.set_mode(6, 0) == mavlink.MAV_RESULT_ACCEPTED  # OFFBOARD
    gcs.wait(stream_setpoint, 60.0, "the geofence violation")
    gcs.wait(lambda: stream_setpoint() and gcs.mode == (custom_mode(*HOLD_MODE), True), 5.0, "Hold")
    gcs.wait(lambda: stream_setpoint() and server.state().ground_speed_mps < 0.05, 30.0, "a stop")
    s = server.state()
    assert s.max_abs_xy_m <= 50.0 and s.north_m > 45.0 and s.mode.px4_name == "AUTO.LOITER"
    assert "Failsafe: geofence, activating Hold" in gcs.texts
