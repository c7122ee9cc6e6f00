"""QGroundControl's connect sequence, played by a pymavlink ground station against the SITL vehicle.

What QGC does on connect (src/Vehicle/InitialConnectStateMachine.cc, Vehicle.cc): heartbeats;
MAV_CMD_REQUEST_MESSAGE for AUTOPILOT_VERSION (whose capability bits decide whether it downloads
fence and rally), AVAILABLE_MODES (standard modes), COMPONENT_METADATA (component information),
PROTOCOL_VERSION and HOME_POSITION; PARAM_REQUEST_LIST (the full list); MISSION_REQUEST_LIST for the
mission, the fence and the rally points. Every request must be answered within QGC's timeouts: a
COMMAND_ACK within 3 s (Vehicle::_mavCommandAckTimeoutMSecs), each mission-protocol answer within
1.5 s (PlanManager::_ackTimeoutMilliseconds), here on the first try.
"""

from __future__ import annotations

import time

import pytest

from sitl_stub.core.mission_store import FENCE, MISSION, RALLY, MissionItem
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from uavlink.mavlink.dialect import mavlink, mavutil
from uavlink.mavlink.mission import MissionClient, pymavlink_recv

pytestmark = [pytest.mark.slow, pytest.mark.timeout(90)]

COMMAND_ACK_S = 3.0
PLAN_ANSWER_S = 1.5
QGC = (255, 190)  # QGC's own system and component ids
REQUESTED = {  # message id: whether the vehicle must send it (else any COMMAND_ACK result will do)
    mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: True,
    435: False,  # AVAILABLE_MODES
    397: False,  # COMPONENT_METADATA
    300: False,  # PROTOCOL_VERSION
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: True,
}


def _wait(conn, kinds, pred, timeout_s: float):
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        m = conn.recv_match(type=kinds, blocking=True, timeout=left)
        if m is not None and m.get_srcSystem() == 1 and pred(m):
            return m
    return None


def test_qgc_connect_sequence_is_answered_in_time():
    config = ServerConfig(connect="udpin:127.0.0.1:0", speed=1.0)
    with SitlServer(config) as server:
        plans = server.vehicle.plans
        plans.replace(
            MISSION,
            (MissionItem(0, 6, mavlink.MAV_CMD_NAV_TAKEOFF, z=20.0, x=473977420, y=85455940),),
        )
        plans.replace(
            FENCE,
            tuple(
                MissionItem(
                    i,
                    5,
                    mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                    3.0,
                    x=473977420 + 1000 * (i == 1),
                    y=85455940 + 1000 * (i == 2),
                    mission_type=FENCE,
                )
                for i in range(3)
            ),
        )
        gcs = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{server.address[1]}",
            source_system=QGC[0],
            source_component=QGC[1],
            dialect="common",
        )
        try:
            gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            assert _wait(gcs, "HEARTBEAT", lambda m: m.autopilot == mavlink.MAV_AUTOPILOT_PX4, 5.0)

            for msg_id, must_send in REQUESTED.items():
                gcs.mav.command_long_send(
                    1, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, msg_id, 0, 0, 0, 0, 0, 0
                )
                ack = _wait(
                    gcs,
                    "COMMAND_ACK",
                    lambda m: (
                        m.command == mavlink.MAV_CMD_REQUEST_MESSAGE
                        and (m.target_system, m.target_component) in (QGC, (0, 0))
                    ),
                    COMMAND_ACK_S,
                )
                assert ack is not None, f"no COMMAND_ACK for REQUEST_MESSAGE {msg_id}"
                if must_send:
                    assert ack.result == mavlink.MAV_RESULT_ACCEPTED
                    sent = _wait(
                        gcs, mavlink.mavlink_map[msg_id].msgname, lambda m: True, COMMAND_ACK_S
                    )
                    assert sent is not None, f"message {msg_id} not sent"
                    if msg_id == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                        wanted = (
                            mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
                            | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                            | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
                        )
                        assert sent.capabilities & wanted == wanted

            gcs.mav.param_request_list_send(1, 1)
            first = _wait(gcs, "PARAM_VALUE", lambda m: True, COMMAND_ACK_S)
            assert first is not None
            seen = {first.param_index}
            while len(seen) < first.param_count:
                value = _wait(gcs, "PARAM_VALUE", lambda m: True, COMMAND_ACK_S)
                assert value is not None, (
                    f"parameter list stopped at {len(seen)} of {first.param_count}"
                )
                seen.add(value.param_index)

            client = MissionClient(
                gcs.mav, pymavlink_recv(gcs), 1, 1, timeout_s=PLAN_ANSWER_S, retries=0
            )
            assert client.download(MISSION) == list(plans.items(MISSION))
            assert [(i.x, i.y) for i in client.download(FENCE)] == [
                (i.x, i.y) for i in plans.items(FENCE)
            ]
            assert client.download(RALLY) == []
        finally:
            gcs.close()
