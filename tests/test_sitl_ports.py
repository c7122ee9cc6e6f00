"""PX4 SITL's ports: with no flags the vehicle is instance 0 (system 1; API link from UDP 14580 to
127.0.0.1:14540, GCS link from 18570 to 127.0.0.1:14550), ``--instance N`` shifts both, and
``--connect`` (now repeatable) replaces them. Every link gets the telemetry; a reply goes back on
the link its request came on; signing covers every link. Real pymavlink over loopback UDP.

The fixed-port tests need PX4's ports free on 127.0.0.1 (no PX4 SITL, QGroundControl or other
vehicle running) and skip, saying which port is taken, when they are not.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from typing import Any

import pytest
from support.cli import PX4_PORTS, require_free_ports

from sitl_stub.launcher import vehicle_process
from sitl_stub.mavlink.links import Fanout, Route, px4_links
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavutil
from uavlink.mavlink.signing import SigningGuard

pytestmark = [pytest.mark.timeout(90), PX4_PORTS]

mavlink = mavutil.mavlink
GCS_SYS, GCS_COMP = 245, 190
KEY = bytes(range(32))


class Listener:
    """A pymavlink endpoint listening on 127.0.0.1:``port``, as MAVSDK (udpin://0.0.0.0:14540) and
    QGroundControl (14550) wait for a vehicle; it answers whoever sent to it."""

    def __init__(self, port: int, key: bytes | None = None) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", source_system=GCS_SYS, source_component=GCS_COMP
        )
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.seen: list[Any] = []

    def close(self) -> None:
        self.conn.close()

    def drain(self, seconds: float) -> list[Any]:
        """Everything that arrives within ``seconds`` (wall)."""
        end = time.monotonic() + seconds
        out = []
        while (left := end - time.monotonic()) > 0:
            m = self.conn.recv_match(blocking=True, timeout=min(left, 0.1))
            if m is not None and m.get_type() != "BAD_DATA":
                out.append(m)
        self.seen += out
        return out

    def wait(self, kind: str, pred: Any = lambda m: True, timeout: float = 15.0) -> Any:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(type=kind, blocking=True, timeout=0.2)
            if m is not None and pred(m):
                return m
        raise AssertionError(f"no {kind} on port {self.port} within {timeout} s")

    @property
    def port(self) -> int:
        return self.conn.port.getsockname()[1]

    def senders(self) -> set[tuple[str, int]]:
        return set(self.conn.clients)


@pytest.fixture
def listeners(request: pytest.FixtureRequest) -> Iterator[list[Listener]]:
    ports = request.param
    opened = [Listener(p) for p in ports]
    yield opened
    for listener in opened:
        listener.close()


def _heartbeat_from(listener: Listener, system_id: int) -> Any:
    return listener.wait(
        "HEARTBEAT",
        lambda m: (
            (m.get_srcSystem(), m.get_srcComponent()) == (system_id, 1)
            and m.autopilot == mavlink.MAV_AUTOPILOT_PX4
        ),
    )


def test_px4_port_table() -> None:
    api, gcs = px4_links(0)
    assert (api.local_port, api.connect) == (14580, "udpout:127.0.0.1:14540")
    assert (gcs.local_port, gcs.connect) == (18570, "udpout:127.0.0.1:14550")
    api3, gcs3 = px4_links(3)
    assert (api3.local_port, api3.connect, gcs3.local_port) == (
        14583,
        "udpout:127.0.0.1:14543",
        18573,
    )
    assert px4_links(12)[0].connect == "udpout:127.0.0.1:14549"  # PX4: instances > 9 share 14549
    with pytest.raises(ValueError, match="instance"):
        px4_links(255)


@pytest.mark.slow
def test_no_flags_serves_px4_instance_0_api_and_gcs_links() -> None:
    require_free_ports(14540, 14550, 14580, 18570)
    api, gcs = Listener(14540), Listener(14550)
    try:
        with vehicle_process(None, speed=5.0, extra_args=["--no-payload"]) as v:
            _heartbeat_from(api, 1)
            _heartbeat_from(gcs, 1)
            assert api.senders() == {("127.0.0.1", 14580)}, "the API link sends from 14580"
            assert gcs.senders() == {("127.0.0.1", 18570)}, "the GCS link sends from 18570"
            # MAVSDK's first request on the API link; the ACK and AUTOPILOT_VERSION come back there
            api.conn.mav.command_long_send(
                1,
                1,
                mavlink.MAV_CMD_REQUEST_MESSAGE,
                0,
                mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                0,
                0,
                0,
                0,
                0,
                0,
            )
            ack = api.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_REQUEST_MESSAGE)
            assert ack.result == mavlink.MAV_RESULT_ACCEPTED
            assert (ack.target_system, ack.target_component) == (GCS_SYS, GCS_COMP)
            api.wait("AUTOPILOT_VERSION")
            on_gcs = {m.get_type() for m in gcs.drain(2.0)}
            assert "HEARTBEAT" in on_gcs and "GLOBAL_POSITION_INT" in on_gcs  # telemetry on both
            assert not on_gcs & {"COMMAND_ACK", "AUTOPILOT_VERSION"}, (
                "a reply leaked to the GCS link"
            )
            assert v.proc.poll() is None
            assert "vehicle 1 on api udp 127.0.0.1:14580->127.0.0.1:14540" in v.output()
    finally:
        api.close()
        gcs.close()


@pytest.mark.slow
def test_instance_1_is_system_2_on_the_next_ports() -> None:
    require_free_ports(14541, 14550, 14581, 18571)
    api, gcs = Listener(14541), Listener(14550)
    try:
        with vehicle_process(None, speed=5.0, extra_args=["--no-payload", "--instance", "1"]):
            _heartbeat_from(api, 2)
            _heartbeat_from(gcs, 2)
            assert api.senders() == {("127.0.0.1", 14581)}
            assert gcs.senders() == {("127.0.0.1", 18571)}
    finally:
        api.close()
        gcs.close()


@pytest.mark.slow
def test_a_taken_port_exits_1_naming_it_with_a_hint() -> None:
    instance = 37  # ports 14617 and 18607: clear of the instances people run
    api, _ = px4_links(instance)
    require_free_ports(api.local_port, api.local_port + 3990)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", api.local_port))
        with vehicle_process(None, extra_args=["--no-payload", "--instance", str(instance)]) as v:
            assert v.proc.wait(30) == 1
            out = v.output()
    assert f"cannot open api udp 127.0.0.1:{api.local_port}->127.0.0.1:14549" in out
    assert "try --instance" in out


class FramePayload:
    """A payload component that publishes its frame time as NAMED_VALUE_FLOAT."""

    component_id = 200
    frame_s = 1.0

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        return (
            mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
            mavlink.MAV_AUTOPILOT_INVALID,
            0,
            0,
            mavlink.MAV_STATE_ACTIVE,
        )

    def on_frame(self, sim_time_s: float, state: Any, mav: Any) -> None:
        mav.named_value_float_send(int(sim_time_s * 1000), b"frame", sim_time_s)


@pytest.mark.slow
def test_repeated_connect_serves_each_link_and_answers_on_the_asking_one() -> None:
    a, b = Listener(free_udp_port()), Listener(free_udp_port())
    config = ServerConfig(
        connect=[f"udpout:127.0.0.1:{a.port}", f"udpout:127.0.0.1:{b.port}"], speed=5.0, system_id=7
    )
    try:
        with SitlServer(config, [FramePayload()]) as server:
            for listener in (a, b):  # the autopilot and the payload on every link
                _heartbeat_from(listener, 7)
                listener.wait("HEARTBEAT", lambda m: m.get_srcComponent() == 200)
                listener.wait("NAMED_VALUE_FLOAT", lambda m: m.get_srcComponent() == 200)
            b.conn.mav.param_request_read_send(7, 1, b"MIS_TAKEOFF_ALT", -1)
            assert b.wait("PARAM_VALUE").param_id == "MIS_TAKEOFF_ALT"
            b.conn.mav.command_long_send(7, 0, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
            b.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_NAV_LAND)
            kinds = {m.get_type() for m in a.drain(1.5)}
            assert "HEARTBEAT" in kinds and not {"PARAM_VALUE", "COMMAND_ACK"} & kinds
            assert server.report()["links"] == config.connect
    finally:
        a.close()
        b.close()


@pytest.mark.slow
def test_signing_covers_every_link_with_its_own_link_id() -> None:
    a, b = Listener(free_udp_port(), KEY), Listener(free_udp_port(), KEY)
    config = ServerConfig(
        connect=[f"udpout:127.0.0.1:{a.port}", f"udpout:127.0.0.1:{b.port}"],
        speed=5.0,
        signing_key=KEY,
    )
    try:
        with SitlServer(config) as server:
            link_ids = []
            for listener in (a, b):
                hb = _heartbeat_from(listener, 1)
                assert hb.get_signed()
                link_ids.append(hb.get_link_id())
            assert link_ids == [0, 1]
            b.conn.mav.command_long_send(
                1,
                0,
                mavlink.MAV_CMD_REQUEST_MESSAGE,
                0,
                mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                0,
                0,
                0,
                0,
                0,
                0,
            )
            assert b.wait("COMMAND_ACK").result == mavlink.MAV_RESULT_ACCEPTED
            unsigned = mavlink.MAVLink(a.conn, srcSystem=GCS_SYS, srcComponent=GCS_COMP)
            unsigned.command_long_send(1, 0, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
            assert "COMMAND_ACK" not in {m.get_type() for m in a.drain(1.5)}
            assert isinstance(server.signing, SigningGuard)
            assert server.signing.accepted >= 1 and server.signing.rejected["unsigned"] >= 1
    finally:
        a.close()
        b.close()


@pytest.mark.slow
def test_unmodified_mavsdk_app_on_14540_finds_the_no_flags_vehicle() -> None:
    """MAVSDK's examples listen on udpin://0.0.0.0:14540 (here 127.0.0.1): with no flags the vehicle
    is discovered, healthy, commandable, and its battery drains in BATTERY_STATUS while armed."""
    pytest.importorskip("mavsdk.asyncio")
    require_free_ports(14540, 14580, 18570)
    import asyncio

    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    async def app() -> None:
        config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with Mavsdk(config) as mavsdk:
            await mavsdk.add_any_connection("udpin://127.0.0.1:14540")
            drone = await mavsdk.first_autopilot(timeout_s=20.0)
            assert drone is not None
            tel, action = TelemetryAsync(drone), ActionAsync(drone)
            async for health in tel.subscribe_health():
                if health.is_home_position_ok and health.is_armable:
                    break
            async for home in tel.subscribe_home():
                assert home.latitude_deg == pytest.approx(47.397742, abs=1e-6)
                break
            async for battery in tel.subscribe_battery():
                assert battery.remaining_percent == pytest.approx(100.0)
                assert battery.voltage_v == pytest.approx(16.2, abs=0.01)
                break
            await action.arm()
            async for battery in tel.subscribe_battery():
                if battery.remaining_percent < 99.0:
                    break

    with vehicle_process(None, speed=5.0, extra_args=["--no-payload"]) as v:
        asyncio.run(asyncio.wait_for(app(), 60.0))
        assert v.proc.poll() is None


def test_fanout_sends_on_every_link_or_only_the_one_being_answered() -> None:
    """Fast: three encoders writing to captures; x_send, encode + send, and the route."""

    class Capture:
        def __init__(self) -> None:
            self.parser, self.got = mavlink.MAVLink(None), []

        def write(self, buf: bytes) -> None:
            self.got += [m.get_type() for m in self.parser.parse_buffer(bytes(buf)) or []]

    captures = [Capture() for _ in range(3)]
    route = Route()
    fan = Fanout([mavlink.MAVLink(c, srcSystem=1, srcComponent=1) for c in captures], route)
    fan.heartbeat_send(2, 12, 0, 0, 3)
    with route.answering_link(1):
        fan.send(fan.ping_encode(0, 0, 0, 0))
        fan.everyone().statustext_send(4, b"to all")
    assert [c.got for c in captures] == [
        ["HEARTBEAT", "STATUSTEXT"],
        ["HEARTBEAT", "PING", "STATUSTEXT"],
        ["HEARTBEAT", "STATUSTEXT"],
    ]
