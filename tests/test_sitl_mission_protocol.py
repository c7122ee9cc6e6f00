"""The vehicle's mission microservice (:mod:`sitl_stub.mavlink.mission_protocol`) message by message, as
PX4's MavlinkMissionManager answers: real MAVLink bytes both ways, wall time given by the test so
PX4's re-request (0.25 s) and protocol (5 s) timeouts are checked exactly and at once."""

from __future__ import annotations

import logging
from typing import Any

import pytest

from sitl_stub.core.mission_store import FENCE, MISSION, RALLY, MissionItem, MissionStore
from sitl_stub.mavlink.mission_protocol import (
    PROTOCOL_TIMEOUT_S,
    RETRY_TIMEOUT_S,
    MissionProtocol,
    check_item,
)
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.mission import send_item
from uavlink.mavlink.rejects import RejectLog

GCS = (245, 190)
WP = mavlink.MAV_CMD_NAV_WAYPOINT
REL_INT = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
VERTEX_IN = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION


class Wire:
    """A MAVLink endpoint whose sends are kept as bytes and read back as messages."""

    def __init__(self, system: int, component: int) -> None:
        self.buf = bytearray()
        self.mav = mavlink.MAVLink(self, srcSystem=system, srcComponent=component)

    def write(self, data: bytes) -> None:
        self.buf += data

    def take(self) -> list[Any]:
        msgs = mavlink.MAVLink(None).parse_buffer(bytes(self.buf)) or []
        self.buf.clear()
        return msgs


class Harness:
    """One vehicle protocol and the ground stations talking to it, at a wall time the test sets."""

    def __init__(self, store: MissionStore | None = None) -> None:
        self.store = store or MissionStore()
        self.vehicle = Wire(1, 1)
        self.texts: list[str] = []
        self.rejects = RejectLog(
            logging.getLogger("sitl_stub")
        )  # the server's, as message_handler passes it
        self.proto = MissionProtocol(
            self.store,
            self.vehicle.mav,
            1,
            lambda severity, text: self.texts.append(text),
            reject=self.rejects.reject,
        )
        self.wall = 100.0

    def send(self, name: str, *args: Any, src: tuple[int, int] = GCS) -> list[Any]:
        """The GCS ``src`` sends ``name_send(*args)``; returns what the vehicle answered."""
        gcs = Wire(*src)
        getattr(gcs.mav, f"{name}_send")(*args)
        for msg in gcs.take():
            self.proto.handle(msg, self.wall)
        return self.vehicle.take()

    def item(
        self, item: MissionItem, int_mode: bool = True, src: tuple[int, int] = GCS
    ) -> list[Any]:
        gcs = Wire(*src)
        send_item(gcs.mav, item, 1, 1, int_mode)
        for msg in gcs.take():
            self.proto.handle(msg, self.wall)
        return self.vehicle.take()

    def advance(self, seconds: float, step: float = 0.01) -> list[Any]:
        """Let ``seconds`` of wall time pass, ticking as the server loop does."""
        out = []
        end = self.wall + seconds
        while self.wall < end - 1e-9:
            self.wall += step
            self.proto.tick(self.wall)
            out += self.vehicle.take()
        return out


def waypoints(n: int, mission_type: int = MISSION) -> list[MissionItem]:
    return [
        MissionItem(
            i,
            REL_INT,
            WP,
            0,
            2.0,
            0,
            0,
            473977420 + 100 * i,
            85455940,
            10.0,
            mission_type=mission_type,
        )
        for i in range(n)
    ]


def kinds(msgs: list[Any]) -> list[str]:
    return [m.get_type() for m in msgs]


def upload(h: Harness, items: list[MissionItem], mission_type: int = MISSION) -> list[Any]:
    out = h.send("mission_count", 1, 1, len(items), mission_type)
    for it in items:
        assert kinds(out) == ["MISSION_REQUEST_INT"] and out[0].seq == it.seq
        out = h.item(it)
    return out


@pytest.mark.parametrize("mission_type", [MISSION, FENCE, RALLY])
def test_upload_then_download_round_trip(mission_type):
    h = Harness()
    cmd = {MISSION: WP, FENCE: VERTEX_IN, RALLY: mavlink.MAV_CMD_NAV_RALLY_POINT}[mission_type]
    items = [
        MissionItem(
            i,
            REL_INT,
            cmd,
            3.0,
            0,
            0,
            0,
            473977420 + i,
            85455940 - i,
            5.0,
            mission_type=mission_type,
        )
        for i in range(3)
    ]
    ack = upload(h, items, mission_type)
    assert kinds(ack) == ["MISSION_ACK"] and ack[0].type == mavlink.MAV_MISSION_ACCEPTED
    assert (
        ack[0].mission_type == mission_type
        and (ack[0].target_system, ack[0].target_component) == GCS
    )
    assert h.store.items(mission_type) == tuple(items)

    [count] = h.send("mission_request_list", 1, 1, mission_type)
    assert count.count == 3 and count.mission_type == mission_type
    for i in range(3):
        [item] = h.send("mission_request_int", 1, 1, i, mission_type)
        assert item.get_type() == "MISSION_ITEM_INT" and (item.seq, item.x, item.y) == (
            i,
            items[i].x,
            items[i].y,
        )
    assert h.send("mission_ack", 1, 1, 0, mission_type) == []
    assert h.proto.state.name == "IDLE"
    assert h.rejects.as_dict() == {}  # a clean round trip refuses nothing


def test_vehicle_re_requests_a_lost_item_then_gives_up_with_cancelled():
    h = Harness()
    old = tuple(waypoints(1))
    h.store.replace(MISSION, old)
    h.send("mission_count", 1, 1, 2, MISSION)
    h.item(waypoints(2)[0])
    again = h.advance(PROTOCOL_TIMEOUT_S - 0.05)  # item 1 is lost: asked again every 0.25 s
    assert set(kinds(again)) == {"MISSION_REQUEST_INT"} and {m.seq for m in again} == {1}
    assert len(again) == pytest.approx((PROTOCOL_TIMEOUT_S - 0.05) / RETRY_TIMEOUT_S, abs=2)
    end = h.advance(0.2)
    assert (
        kinds(end)[-1] == "MISSION_ACK" and end[-1].type == mavlink.MAV_MISSION_OPERATION_CANCELLED
    )
    assert "Operation timeout" in h.texts
    assert h.store.items(MISSION) == old  # a failed upload leaves the old list
    assert h.advance(1.0) == []


def test_count_sent_again_before_the_first_item_restarts_requests_and_later_is_refused():
    h = Harness()
    assert kinds(h.send("mission_count", 1, 1, 2, MISSION)) == ["MISSION_REQUEST_INT"]
    again = h.send("mission_count", 1, 1, 2, MISSION)  # our request was lost
    assert kinds(again) == ["MISSION_REQUEST_INT"] and again[0].seq == 0
    h.item(waypoints(2)[0])
    busy = h.send("mission_count", 1, 1, 2, MISSION)
    assert kinds(busy) == ["MISSION_ACK"] and busy[0].type == mavlink.MAV_MISSION_ERROR
    # PX4 answers ERROR but keeps receiving: the upload still completes
    assert h.item(waypoints(2)[1])[0].type == mavlink.MAV_MISSION_ACCEPTED


def test_second_ground_station_is_refused_while_an_upload_runs():
    h = Harness()
    h.send("mission_count", 1, 1, 2, MISSION)
    other = h.send("mission_count", 1, 1, 1, FENCE, src=(246, 190))
    assert kinds(other) == ["MISSION_ACK"] and other[0].type == mavlink.MAV_MISSION_ERROR
    assert other[0].target_system == 246
    # and another link of the same vehicle (its own protocol, the shared store) is refused too
    link2 = MissionProtocol(h.store, Wire(1, 1).mav, 1, lambda s, t: None)
    wire = Wire(247, 190)
    wire.mav.mission_count_send(1, 1, 1, FENCE)
    [msg] = wire.take()
    link2.handle(msg, h.wall)
    [ack] = mavlink.MAVLink(None).parse_buffer(bytes(link2.mav.file.buf))
    assert ack.type == mavlink.MAV_MISSION_ERROR


def test_out_of_sequence_item_is_ignored_and_re_requested():
    h = Harness()
    items = waypoints(3)
    h.send("mission_count", 1, 1, 3, MISSION)
    assert h.item(items[1]) == []  # not the awaited seq 0: ignored
    re = h.advance(RETRY_TIMEOUT_S + 0.02)
    assert kinds(re) == ["MISSION_REQUEST_INT"] and re[0].seq == 0
    for it in items[:2]:
        h.item(it)
    assert h.item(items[1]) == []  # a duplicate of the previous item: ignored
    assert h.item(items[2])[0].type == mavlink.MAV_MISSION_ACCEPTED


def test_last_item_sent_again_after_the_ack_is_acknowledged_again():
    h = Harness()
    items = waypoints(2)
    upload(h, items)
    [ack] = h.item(items[1])  # the GCS lost our ACK
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED
    [err] = h.item(items[0])
    assert err.type == mavlink.MAV_MISSION_ERROR and "IGN MISSION_ITEM: No transfer" in h.texts


@pytest.mark.parametrize(
    "item,result",
    [
        (MissionItem(0, REL_INT, 31337), mavlink.MAV_MISSION_UNSUPPORTED),
        (MissionItem(0, mavlink.MAV_FRAME_LOCAL_NED, WP), mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
        (
            MissionItem(0, REL_INT, VERTEX_IN),
            mavlink.MAV_MISSION_ERROR,
        ),  # a fence item in a mission
        (
            MissionItem(0, REL_INT, mavlink.MAV_CMD_DO_SET_ROI, 7.0),
            mavlink.MAV_MISSION_INVALID_PARAM1,
        ),
    ],
)
def test_item_px4_refuses_ends_the_upload_and_keeps_the_old_list(item, result):
    h = Harness()
    old = tuple(waypoints(2))
    h.store.replace(MISSION, old)
    h.send("mission_count", 1, 1, 1, MISSION)
    [ack] = h.item(item)
    assert ack.type == result
    assert h.store.items(MISSION) == old and h.proto.state.name == "IDLE"
    assert h.rejects.as_dict() == {"mission_item_refused": 1}


def test_a_refused_item_is_counted_and_logged_once_naming_command_frame_and_result(caplog):
    """RTL in a global frame: PX4 answers MISSION_ACK UNSUPPORTED (RTL takes MAV_FRAME_MISSION only);
    the vehicle counts it in the exit stats' "rejected" section and logs it once."""
    caplog.set_level(logging.WARNING, logger="sitl_stub")
    h = Harness()
    rtl = MissionItem(0, REL_INT, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH)
    for _ in range(2):
        h.send("mission_count", 1, 1, 1, MISSION)
        [ack] = h.item(rtl)
        assert ack.type == mavlink.MAV_MISSION_UNSUPPORTED
    assert h.rejects.as_dict() == {"mission_item_refused": 2}
    [line] = [r.getMessage() for r in caplog.records if "rejected input" in r.getMessage()]
    assert (
        "MISSION_ITEM_INT 0: MAV_CMD_NAV_RETURN_TO_LAUNCH in frame "
        "MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: MAV_MISSION_UNSUPPORTED" in line
    ), line
    assert "'mission_item_refused'" in line
    h.send("mission_count", 1, 1, 1, MISSION)
    h.item(MissionItem(0, mavlink.MAV_FRAME_MISSION, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH))
    assert h.rejects.as_dict() == {"mission_item_refused": 2}  # in MAV_FRAME_MISSION it is accepted


def test_every_kind_of_refused_mission_message_is_counted():
    h = Harness()
    h.store.replace(MISSION, tuple(waypoints(3)))
    h.send("mission_count", 1, 1, 33, RALLY)  # NO_SPACE
    h.send("mission_count", 1, 1, 1, 7)  # no such mission_type: INVALID
    h.send("mission_clear_all", 1, 1, 7)  # ERROR
    h.send("mission_set_current", 1, 1, 9)  # not in the list
    h.item(waypoints(1)[0])  # no upload running
    h.send("mission_request_list", 1, 1, MISSION)
    h.send("mission_request_int", 1, 1, 2, MISSION)  # a jump: ends the download
    h.send("mission_count", 1, 1, 2, MISSION)
    h.send("mission_request_list", 1, 1, MISSION)  # busy: an upload runs
    h.send("mission_count", 1, 1, 2, FENCE, src=(246, 190))  # a second station
    h.item(waypoints(1)[0], src=(246, 190))  # not the uploading station
    h.send("mission_clear_all", 1, 1, MISSION)  # busy
    h.send("mission_set_current", 1, 1, 0)  # busy
    assert h.rejects.as_dict() == {
        "mission_clear_refused": 2,
        "mission_count_refused": 3,
        "mission_current_refused": 2,
        "mission_item_refused": 2,
        "mission_request_refused": 2,
    }


def test_feasibility_as_px4():
    assert check_item(MissionItem(0, 2, mavlink.MAV_CMD_DO_CHANGE_SPEED), True) == 0
    assert check_item(MissionItem(0, 2, mavlink.MAV_CMD_DO_JUMP, 1, 2), True) == 0
    assert check_item(MissionItem(0, REL_INT, WP), False) == mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    two_vertices = MissionItem(0, 0, VERTEX_IN, 2.0, mission_type=FENCE)
    assert check_item(two_vertices, True) == mavlink.MAV_MISSION_ERROR


def test_too_many_items_and_count_zero():
    h = Harness()
    h.store.replace(RALLY, tuple(waypoints(1, RALLY)))
    [ack] = h.send("mission_count", 1, 1, 33, RALLY)
    assert ack.type == mavlink.MAV_MISSION_NO_SPACE
    [ack] = h.send("mission_count", 1, 1, 0, RALLY)
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED and h.store.items(RALLY) == ()


def test_download_answers_the_same_seq_again_and_refuses_a_jump():
    h = Harness()
    h.store.replace(MISSION, tuple(waypoints(3)))
    h.send("mission_request_list", 1, 1, MISSION)
    first = h.send("mission_request_int", 1, 1, 0, MISSION)
    again = h.send("mission_request_int", 1, 1, 0, MISSION)
    assert kinds(again) == ["MISSION_ITEM_INT"] and again[0].seq == first[0].seq == 0
    [err] = h.send("mission_request_int", 1, 1, 2, MISSION)
    assert err.get_type() == "MISSION_ACK" and err.type == mavlink.MAV_MISSION_ERROR


def test_legacy_float_messages_and_frame_of_the_request_kind():
    h = Harness()
    item = MissionItem(
        0, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, WP, 0, 0, 0, 0, 473977420, 85455940, 20.0
    )
    h.send("mission_count", 1, 1, 1, MISSION)
    [ack] = h.item(item, int_mode=False)  # MAVProxy with wp_use_mission_int off
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED
    stored = h.store.items(MISSION)[0]
    # float32 degrees on the wire: about 4e-6 degrees (0.4 m) apart
    assert abs(stored.x - item.x) <= 40 and abs(stored.y - item.y) <= 40
    h.send("mission_request_list", 1, 1, MISSION)
    [as_float] = h.send("mission_request", 1, 1, 0, MISSION)
    assert (
        as_float.get_type() == "MISSION_ITEM"
        and as_float.frame == mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
    )
    h.send("mission_request_list", 1, 1, MISSION)
    [as_int] = h.send("mission_request_int", 1, 1, 0, MISSION)
    assert as_int.frame == REL_INT and as_int.current == 1


def test_download_request_from_another_gcs_while_busy_is_ignored():
    h = Harness()
    h.store.replace(FENCE, tuple(waypoints(2, FENCE)))
    h.send("mission_request_list", 1, 1, FENCE)
    assert h.send("mission_request_list", 1, 1, FENCE, src=(246, 190)) == []
    assert "Mission download request ignored, already active" in h.texts
    # all items sent without the GCS's ACK (MAVProxy): the next list request is served
    for i in range(2):
        h.send("mission_request_int", 1, 1, i, FENCE)
    assert kinds(h.send("mission_request_list", 1, 1, RALLY, src=(246, 190))) == ["MISSION_COUNT"]
    h.send("mission_request_list", 1, 1, FENCE)
    for i in range(2):
        h.send("mission_request_int", 1, 1, i, FENCE)
    again = h.send("mission_request_int", 1, 1, 1, FENCE)  # the last item asked for again
    assert kinds(again) == ["MISSION_ITEM_INT"]
    # and an upload right after it is served too (MAVProxy's `wp list`, then `fence load`)
    assert kinds(h.send("mission_count", 1, 1, 1, RALLY)) == ["MISSION_REQUEST_INT"]


def test_clear_all_and_set_current():
    h = Harness()
    for t in (MISSION, FENCE, RALLY):
        h.store.replace(t, tuple(waypoints(3, t)))
    [cur] = h.send("mission_set_current", 1, 1, 2)
    assert cur.get_type() == "MISSION_CURRENT" and (cur.seq, cur.total) == (2, 3)
    assert h.store.current_seq == 2
    assert (
        h.send("mission_set_current", 1, 1, 9) == [] and "WPM: WP CURR CMD: Not in list" in h.texts
    )
    [ack] = h.send("mission_clear_all", 1, 1, FENCE)
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED and ack.mission_type == FENCE
    assert h.store.items(FENCE) == () and len(h.store.items(MISSION)) == 3
    [ack] = h.send("mission_clear_all", 1, 1, 255)
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED
    assert all(h.store.items(t) == () for t in (MISSION, FENCE, RALLY))


def test_messages_for_another_vehicle_are_not_handled():
    h = Harness()
    assert h.send("mission_request_list", 2, 1, MISSION) == []
    assert h.send("mission_request_list", 1, 50, MISSION) == []
