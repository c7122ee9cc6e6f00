"""Small pure parts of sitl_stub: params, mode encoding, connections, geo, streams, clock, FTP."""

from __future__ import annotations

import math
import socket
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.modes import FlightMode
from sitl_stub.core.params import ParamStore, ParamType, int_to_param_float, param_float_to_int
from sitl_stub.mavlink.ftp import ERR_FILE_NOT_FOUND, OP_ACK, OP_NAK, ftp_reply
from sitl_stub.mavlink.server import ServerConfig
from sitl_stub.mavlink.streams import StreamScheduler
from sitl_stub.sim.clock import SimClock
from sitl_stub.sim.payload import check_payload
from uavlink.mavlink import connection
from uavlink.mavlink.connection import free_udp_port, free_udp_ports, normalize_connection
from uavlink.mavlink.px4_modes import decode_custom_mode, encode_custom_mode, px4_mode_name

pytestmark = pytest.mark.timeout(30)


# ------------------------------------------------------------------ modes
@pytest.mark.parametrize(
    ("mode", "main", "sub"),
    [
        (FlightMode.OFFBOARD, 6, 0),
        (FlightMode.TAKEOFF, 4, 2),
        (FlightMode.LOITER, 4, 3),
        (FlightMode.RTL, 4, 5),
        (FlightMode.LAND, 4, 6),
        (FlightMode.MISSION, 4, 4),
    ],
)
def test_px4_custom_mode_encoding(mode, main, sub):
    assert mode.custom_mode == main << 16 | sub << 24
    assert decode_custom_mode(mode.custom_mode) == (main, sub)
    assert FlightMode.from_main_sub(main, sub) is mode


def test_unflown_modes_are_not_members():
    assert FlightMode.from_main_sub(4, 1) is None  # AUTO.READY
    assert FlightMode.from_main_sub(3, 0) is None  # POSCTL
    assert FlightMode.from_main_sub(6, 9) is FlightMode.OFFBOARD
    assert encode_custom_mode(4, 3) == 50593792
    assert FlightMode.LOITER.px4_name == "AUTO.LOITER"


# ----------------------------------------------------------------- params
def test_int_param_bytewise_encoding_matches_px4():
    f = int_to_param_float(1)
    assert f == struct.unpack("<f", struct.pack("<i", 1))[0]
    assert 0.0 < f < 1e-44  # a float cast would read 1065353216 ...
    assert param_float_to_int(f) == 1


@given(st.integers(min_value=-(2**31), max_value=2**31 - 1))
def test_int_param_encoding_round_trips(n):
    f = int_to_param_float(n)
    if not math.isnan(f):  # NaN payloads may not survive a double round trip
        assert param_float_to_int(f) == n


def test_param_store_defaults_types_and_validation():
    p = ParamStore()
    assert p["COM_OF_LOSS_T"] == 1.0 and p["MPC_XY_VEL_MAX"] == 12.0
    assert p["MIS_TAKEOFF_ALT"] == 95.0 and "RTL_RETURN_ALT" in p
    assert p.definition("COM_OBL_ACT").type is ParamType.INT32 and p["COM_OBL_ACT"] == 1
    assert p.encode("COM_OBL_ACT") == (int_to_param_float(1), ParamType.INT32)
    assert p.encode("MPC_XY_VEL_MAX") == (12.0, ParamType.REAL32)
    assert not p.set("MPC_XY_VEL_MAX", math.nan)
    assert not p.set("MPC_XY_VEL_MAX", -1.0)
    assert not p.set("COM_OBL_ACT", 1.5)
    assert not p.set("NOPE", 1.0)
    assert p.set_from_wire("COM_OBL_ACT", int_to_param_float(2)) and p["COM_OBL_ACT"] == 2
    assert not p.set_from_wire("COM_OBL_ACT", 1.0)  # float cast of 1 is 1065353216: refused
    assert p.name_at(p.index_of("RTL_RETURN_ALT")) == "RTL_RETURN_ALT"
    assert p.name_at(len(p)) is None
    assert all(len(name) <= 16 for name in p)


def test_param_overrides():
    assert ParamStore({"MIS_TAKEOFF_ALT": 10})["MIS_TAKEOFF_ALT"] == 10.0
    with pytest.raises(ValueError, match="unknown"):
        ParamStore({"NOPE": 1})
    with pytest.raises(ValueError, match="MPC_XY_VEL_MAX"):
        ParamStore({"MPC_XY_VEL_MAX": 0})


# ------------------------------------------------------------ connections
@pytest.mark.parametrize(
    ("given_url", "expected"),
    [
        ("udpout:127.0.0.1:14550", "udpout:127.0.0.1:14550"),
        ("udp:127.0.0.1:14550", "udpin:127.0.0.1:14550"),
        ("udp:14550", "udpin:0.0.0.0:14550"),
        ("udpin:14550", "udpin:0.0.0.0:14550"),
        ("udpin://0.0.0.0:14540", "udpin:0.0.0.0:14540"),
        ("udp://:14540", "udpin:0.0.0.0:14540"),
        ("udpout://10.0.0.2:14550", "udpout:10.0.0.2:14550"),
        ("tcp:127.0.0.1:5760", "tcp:127.0.0.1:5760"),
        ("tcpin://0.0.0.0:5760", "tcpin:0.0.0.0:5760"),
        ("UDP:127.0.0.1:0", "udpin:127.0.0.1:0"),
    ],
)
def test_connection_normalisation(given_url, expected):
    assert normalize_connection(given_url) == expected


@pytest.mark.parametrize(
    "bad",
    [
        "",
        "14550",
        "serial:/dev/ttyUSB0",
        "udpout:14550",
        "udp:host:port",
        "udp:1.2.3.4:70000",
        "udpout:1.2.3.4:0",
    ],
)
def test_bad_connections_are_one_line_errors(bad):
    with pytest.raises(ValueError) as err:
        normalize_connection(bad)
    assert "\n" not in str(err.value)


def test_free_udp_port_is_bindable_and_outside_the_ephemeral_range(monkeypatch):
    ports = {free_udp_port() for _ in range(20)}
    assert all(p in connection._PICK_PORTS for p in ports)
    assert all(p < 32768 for p in ports)  # below Linux's ephemeral ports: bind(0) cannot take them
    busy = ports.pop()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", busy))  # free as promised
        # Every port it may pick is taken: the kernel's pick, still a free port.
        monkeypatch.setattr(connection, "_PICK_PORTS", range(busy, busy + 1))
        fallback = free_udp_port()
    assert fallback != busy and 0 < fallback <= 65535
    monkeypatch.undo()
    fleet = free_udp_ports(4)  # a fleet's vehicles, one port each
    assert len(set(fleet)) == 4 and all(p in connection._PICK_PORTS for p in fleet)


# -------------------------------------------------------------------- geo
def test_geo_round_trip_and_scale():
    o = GeoOrigin()
    assert o.to_global(0.0, 0.0) == (o.lat_deg, o.lon_deg)
    lat, lon = o.to_global(200.0, -150.0)
    assert o.to_local(lat, lon) == pytest.approx((200.0, -150.0), abs=1e-6)
    lat1, _ = o.to_global(111_194.9, 0.0)  # one degree of latitude on PX4's sphere
    assert lat1 - o.lat_deg == pytest.approx(1.0, abs=1e-4)
    _, lon1 = o.to_global(0.0, 100.0)
    assert lon1 > o.lon_deg


def test_geo_validation():
    with pytest.raises(ValueError, match="latitude"):
        GeoOrigin(lat_deg=91.0).validate()
    with pytest.raises(ValueError, match="longitude"):
        GeoOrigin(lon_deg=math.nan).validate()


@pytest.mark.parametrize(
    ("settings", "message"),
    [
        ({"speed": 0.0}, "speed must be a positive number"),
        ({"speed": math.inf}, "speed must be a positive number"),
        ({"system_id": 256}, "system_id must be in 1..255"),
        ({"system_id": 0}, "system_id must be in 1..255"),
        ({"home": GeoOrigin(lat_deg=91.0)}, "latitude"),
        ({"connect": []}, "give at least one connection"),
    ],
)
def test_a_server_config_says_what_is_wrong(settings: dict, message: str) -> None:
    assert ServerConfig(instance=3).validate().vehicle_id == 4
    with pytest.raises(ValueError, match=message):
        ServerConfig(**settings).validate()


# ---------------------------------------------------------------- streams
def test_streams_follow_simulated_time_with_a_wall_cap():
    s = StreamScheduler(max_wall_hz=50.0)
    sent = 0
    for i in range(100):  # 1 s of wall time at 10 ms steps, 20x speed
        sent += "LOCAL_POSITION_NED" in s.due(sim_s=i * 0.2, wall_s=i * 0.01)
    assert 45 <= sent <= 51  # 10 Hz sim = 200 Hz wall, capped to 50 Hz wall


def test_stream_intervals():
    s = StreamScheduler()
    assert s.set_interval("ATTITUDE", 500_000) and s.interval_us("ATTITUDE") == 500_000
    assert s.set_interval("ATTITUDE", -1) and s.interval_us("ATTITUDE") == -1
    assert s.set_interval("ATTITUDE", 0) and s.interval_us("ATTITUDE") == 100_000
    assert not s.set_interval("NOT_A_STREAM", 1000)
    assert not s.set_interval("ATTITUDE", -5)


def test_heartbeat_has_a_wall_time_floor_at_slow_speed():
    s = StreamScheduler()
    beats = [w / 10 for w in range(50) if s.heartbeat_due(sim_s=w / 10 * 0.1, wall_s=w / 10)]
    assert beats == [0.0, 1.0, 2.0, 3.0, 4.0]  # 0.1x speed: 1 sim s is 10 wall s


def test_heartbeat_follows_sim_time_at_high_speed():
    s = StreamScheduler()
    beats = sum(s.heartbeat_due(sim_s=i * 0.1, wall_s=i * 0.005) for i in range(200))
    assert beats == 20  # 20 sim s in 1 wall s


# ------------------------------------------------------------------ clock
def test_clock_speed_and_stall_cap():
    now = [0.0]
    c = SimClock(speed=20.0, wall=lambda: now[0])
    now[0] = 0.1
    assert c.advance() == pytest.approx(2.0)
    now[0] = 10.0  # a 9.9 s stall advances at most 0.25 wall s
    assert c.advance() == pytest.approx(7.0)
    with pytest.raises(ValueError):
        SimClock(speed=0.0)


# -------------------------------------------------------------------- ftp
def test_ftp_refuses_opens_and_acks_session_resets():
    req = bytes([5, 0, 1, 4, 0, 0, 0, 0]) + bytes(4) + b"@PARAM/param.pck"
    reply = ftp_reply(req)
    assert reply is not None and len(reply) == 251
    assert reply[0:2] == [6, 0] and reply[3] == OP_NAK and reply[5] == 4
    assert reply[4] == 1 and reply[12] == ERR_FILE_NOT_FOUND
    assert ftp_reply(bytes([1, 0, 0, 8]) + bytes(8))[3] == OP_ACK
    assert ftp_reply(bytes([1, 0, 0, OP_ACK]) + bytes(8)) is None


# ---------------------------------------------------------------- payload
class _Payload:
    def __init__(self, hb: tuple, component_id: int = 200) -> None:
        self.component_id = component_id
        self.frame_s = 1.0
        self._hb = hb

    def heartbeat(self) -> tuple:
        return self._hb

    def on_frame(self, sim_time_s, state, mav) -> None:
        pass


def test_payload_contract_is_checked():
    check_payload(_Payload((18, 8, 0, 0, 4)), {1})
    with pytest.raises(ValueError, match="MAV_AUTOPILOT_INVALID"):
        check_payload(_Payload((18, 12, 0, 0, 4)), {1})
    with pytest.raises(ValueError, match="MAV_AUTOPILOT_INVALID"):
        check_payload(_Payload((18, 8, 1, 0, 4)), {1})
    with pytest.raises(ValueError, match="component_id"):
        check_payload(_Payload((18, 8, 0, 0, 4), component_id=1), {1})


@pytest.mark.parametrize(
    "main, sub, name",
    [
        (4, 3, "AUTO.LOITER"),
        (4, 6, "AUTO.LAND"),
        (6, 0, "OFFBOARD"),
        (3, 0, "POSCTL"),
        (4, 9, "AUTO.9"),
        (12, 1, "mode 12.1"),
    ],
)
def test_px4_mode_names(main, sub, name):
    assert px4_mode_name(main, sub) == name
