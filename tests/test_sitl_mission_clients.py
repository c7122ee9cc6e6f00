"""Mission, fence and rally transfers with real clients over loopback UDP: the project's pymavlink
:class:`~uavlink.mavlink.mission.MissionClient` against the SITL vehicle (in-process, listening on
a free port), a lost item the vehicle asks for again, a client giving up on a silent vehicle, and
``uavlink fly`` uploading the operating area as the vehicle's fence (seen in its tlog)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from support.cli import run_uavlink

from sitl_stub.mavlink.server import ServerConfig, SitlServer
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink, mavutil
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.mission import (
    FENCE,
    MISSION,
    RALLY,
    MissionClient,
    MissionItem,
    MissionTransferError,
    pymavlink_recv,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(120)]

REL_INT = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
PLANS = {
    MISSION: [
        MissionItem(0, REL_INT, mavlink.MAV_CMD_NAV_TAKEOFF, z=20.0, x=473977420, y=85455940),
        MissionItem(
            1, REL_INT, mavlink.MAV_CMD_NAV_WAYPOINT, 1.0, 2.0, x=473978420, y=85456940, z=20.0
        ),
        MissionItem(2, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_DO_CHANGE_SPEED, 1.0, 5.0, -1.0),
        MissionItem(3, REL_INT, mavlink.MAV_CMD_NAV_LAND, x=473977420, y=85455940),
    ],
    FENCE: [
        MissionItem(
            i,
            mavlink.MAV_FRAME_GLOBAL_INT,
            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            4.0,
            x=473977420 + dx,
            y=85455940 + dy,
            mission_type=FENCE,
        )
        for i, (dx, dy) in enumerate(
            [(20000, 20000), (-20000, 20000), (-20000, -20000), (20000, -20000)]
        )
    ]
    + [
        MissionItem(
            4,
            mavlink.MAV_FRAME_GLOBAL_INT,
            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
            15.0,
            x=473978000,
            y=85456000,
            mission_type=FENCE,
        )
    ],
    RALLY: [
        MissionItem(
            0,
            REL_INT,
            mavlink.MAV_CMD_NAV_RALLY_POINT,
            x=473980000,
            y=85450000,
            z=30.0,
            mission_type=RALLY,
        )
    ],
}


@pytest.fixture()
def vehicle():
    with SitlServer(ServerConfig(connect="udpin:127.0.0.1:0", speed=1.0)) as server:
        yield server


def client_of(server: SitlServer, timeout_s: float = 1.5, retries: int = 5):
    conn = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{server.address[1]}",
        source_system=245,
        source_component=190,
        dialect="common",
    )
    return conn, MissionClient(conn.mav, pymavlink_recv(conn), 1, 1, timeout_s, retries)


def test_round_trips_for_mission_fence_and_rally(vehicle):
    conn, client = client_of(vehicle)
    try:
        for mission_type, items in PLANS.items():
            client.upload(items, mission_type)
            assert vehicle.vehicle.plans.items(mission_type) == tuple(items)
            assert client.download(mission_type) == items
        client.set_current(1)
        assert vehicle.vehicle.plans.current_seq == 1
        client.clear(FENCE)
        assert client.download(FENCE) == [] and vehicle.vehicle.plans.items(FENCE) == ()
        assert len(client.download(MISSION)) == 4  # the others are untouched
    finally:
        conn.close()


def test_lost_item_is_asked_for_again(vehicle):
    """The first MISSION_ITEM_INT never reaches the vehicle: its re-request (0.25 s) recovers."""
    conn, client = client_of(vehicle)
    sent = conn.mav.mission_item_int_send
    dropped = []

    def lossy(*args, **kwargs):
        if not dropped:
            dropped.append(args[2])  # its seq
            return None
        return sent(*args, **kwargs)

    conn.mav.mission_item_int_send = lossy
    try:
        client.upload(PLANS[MISSION], MISSION)
    finally:
        conn.close()
    assert dropped == [0]
    assert vehicle.vehicle.plans.items(MISSION) == tuple(PLANS[MISSION])


def test_refused_upload_raises_and_keeps_the_old_list(vehicle):
    conn, client = client_of(vehicle)
    try:
        client.upload(PLANS[RALLY], RALLY)
        bad = [
            MissionItem(
                0, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_CMD_NAV_RALLY_POINT, mission_type=RALLY
            )
        ]
        with pytest.raises(MissionTransferError, match="MAV_MISSION_UNSUPPORTED_FRAME"):
            client.upload(bad, RALLY)
    finally:
        conn.close()
    assert vehicle.vehicle.plans.items(RALLY) == tuple(PLANS[RALLY])


def test_client_gives_up_on_a_silent_vehicle():
    port = free_udp_port()  # nobody listens
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=245)
    client = MissionClient(conn.mav, pymavlink_recv(conn), 1, 1, timeout_s=0.2, retries=2)
    try:
        with pytest.raises(MissionTransferError, match="no answer .* after 2 retries"):
            client.download(FENCE)
    finally:
        conn.close()


@pytest.mark.timeout(180)
def test_fly_uploads_the_operating_area_as_fence(tmp_path: Path):
    proc = run_uavlink(
        "fly",
        "--no-picture",
        "--policy",
        "static",
        "--frames",
        "5",
        "--out",
        str(tmp_path),
        "--json",
        "--verbose",
        timeout=150,
    )
    assert proc.returncode == 0, proc.stderr
    assert "geofence uploaded" in proc.stderr
    summary = json.loads(proc.stdout)
    tlog = mavutil.mavlink_connection(summary["tlog"], dialect="common")
    counts, items, acks = [], [], []
    while (
        m := tlog.recv_match(
            type=[
                "MISSION_COUNT",
                "MISSION_ITEM_INT",
                "MISSION_ACK",
                "SET_POSITION_TARGET_LOCAL_NED",
            ]
        )
    ) is not None:
        if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED":
            assert acks, "the fence is uploaded before the flight"
            break
        {"MISSION_COUNT": counts, "MISSION_ITEM_INT": items, "MISSION_ACK": acks}[
            m.get_type()
        ].append(m)
    tlog.close()
    assert [(c.count, c.mission_type) for c in counts] == [(4, FENCE)]
    assert sorted({i.seq for i in items}) == [0, 1, 2, 3]
    assert {(i.command, i.frame, i.param1, i.mission_type) for i in items} == {
        (mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, mavlink.MAV_FRAME_GLOBAL, 4.0, FENCE)
    }
    # the vehicle's ACK (it stored the list): ACCEPTED for the fence
    assert [(a.get_srcSystem(), a.type, a.mission_type) for a in acks] == [
        (1, mavlink.MAV_MISSION_ACCEPTED, FENCE)
    ]
    # the corners lie 2 m outside the default 200 m half-width around the SITL's home
    north, east = zip(*(GeoOrigin().to_local(i.x * 1e-7, i.y * 1e-7) for i in items), strict=True)
    assert max(map(abs, north)) == pytest.approx(202.0, abs=0.05)
    assert max(map(abs, east)) == pytest.approx(202.0, abs=0.05)
    assert not any(math.isnan(v) for v in north + east)
