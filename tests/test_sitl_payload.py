"""The payload hook and the in-process server (SitlServer.start/stop), with a trivial payload."""

from __future__ import annotations

import time
from typing import Any

import pytest

from sitl_stub.core.vehicle_state import VehicleState
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import MAV_AUTOPILOT_INVALID
from uavlink.mavlink.dialect import mavutil

pytestmark = pytest.mark.timeout(60)

mavlink = mavutil.mavlink
PAYLOAD_ID = 200


class CountingPayload:
    """Publishes its frame number as NAMED_VALUE_FLOAT 'frame'; breaks on frame 10."""

    component_id = PAYLOAD_ID
    frame_s = 1.0

    def __init__(self) -> None:
        self.frames: list[tuple[float, VehicleState]] = []
        self.commands: list[int] = []

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        return (
            mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
            MAV_AUTOPILOT_INVALID,
            0,
            0,
            mavlink.MAV_STATE_ACTIVE,
        )

    def on_frame(self, sim_time_s: float, state: VehicleState, mav: Any) -> None:
        self.frames.append((sim_time_s, state))
        if len(self.frames) == 11:
            raise RuntimeError("a payload bug must not stop the vehicle")
        mav.named_value_float_send(int(sim_time_s * 1000), b"frame", float(len(self.frames) - 1))


class CommandablePayload(CountingPayload):
    component_id = PAYLOAD_ID + 1

    def on_command(self, msg: Any, mav: Any) -> int:
        self.commands.append(msg.command)
        return mavlink.MAV_RESULT_ACCEPTED


def _acks(gcs: Any, command: int, window_s: float) -> list[Any]:
    out = []
    deadline = time.monotonic() + window_s
    while time.monotonic() < deadline:
        m = gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.05)
        if m is not None and m.command == command:
            out.append(m)
    return out


@pytest.mark.slow
def test_payload_components_tick_per_frame_and_answer_commands():
    counting, commandable = CountingPayload(), CommandablePayload()
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", speed=20.0), [counting, commandable]
    )
    with server:
        host, port = server.address
        gcs = mavutil.mavlink_connection(
            f"udpout:{host}:{port}", source_system=255, source_component=190
        )
        try:
            gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            beats: dict[int, Any] = {}
            values: list[float] = []
            deadline = time.monotonic() + 10.0
            while (len(beats) < 3 or not values or values[-1] < 12) and time.monotonic() < deadline:
                m = gcs.recv_match(
                    type=["HEARTBEAT", "NAMED_VALUE_FLOAT"], blocking=True, timeout=0.1
                )
                if m is None:
                    continue
                if m.get_type() == "HEARTBEAT":
                    beats[m.get_srcComponent()] = m
                elif m.get_srcComponent() == PAYLOAD_ID:
                    values.append(m.value)
            assert beats[1].autopilot == mavlink.MAV_AUTOPILOT_PX4
            for cid in (PAYLOAD_ID, PAYLOAD_ID + 1):
                assert beats[cid].autopilot == MAV_AUTOPILOT_INVALID and beats[cid].base_mode == 0
            # frames reach the GCS once it has spoken (the vehicle listens); 10 raised
            assert 9.0 in values and 10.0 not in values and 11.0 in values
            assert values == [values[0] + i + (values[0] + i >= 10) for i in range(len(values))]

            # addressed to a payload without on_command: UNSUPPORTED from that component
            gcs.mav.command_long_send(
                1, PAYLOAD_ID, mavlink.MAV_CMD_DO_SET_SERVO, 0, 1, 1500, 0, 0, 0, 0, 0
            )
            acks = _acks(gcs, mavlink.MAV_CMD_DO_SET_SERVO, 1.0)
            assert [(a.get_srcComponent(), a.result) for a in acks] == [
                (PAYLOAD_ID, mavlink.MAV_RESULT_UNSUPPORTED)
            ]
            # addressed to a payload with on_command: its own result
            gcs.mav.command_long_send(
                1, PAYLOAD_ID + 1, mavlink.MAV_CMD_DO_SET_SERVO, 0, 1, 1500, 0, 0, 0, 0, 0
            )
            acks = _acks(gcs, mavlink.MAV_CMD_DO_SET_SERVO, 1.0)
            assert [(a.get_srcComponent(), a.result) for a in acks] == [
                (PAYLOAD_ID + 1, mavlink.MAV_RESULT_ACCEPTED)
            ]
            assert commandable.commands == [mavlink.MAV_CMD_DO_SET_SERVO]
            # broadcast: the autopilot alone answers
            gcs.mav.command_long_send(
                1, 0, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
            )
            acks = _acks(gcs, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
            assert [(a.get_srcComponent(), a.result) for a in acks] == [
                (1, mavlink.MAV_RESULT_ACCEPTED)
            ]
            assert server.state().armed
        finally:
            gcs.close()
    assert server.conn is None and server.error is None
    times = [t for t, _ in counting.frames]
    assert times == [float(k) for k in range(len(times))]  # sim times 0, 1, 2, ... exactly
    for t, state in counting.frames:
        assert state.time_s == pytest.approx(t, abs=1e-6)


def test_bad_payload_is_refused():
    class Impostor(CountingPayload):
        def heartbeat(self) -> tuple[int, int, int, int, int]:
            return (mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0, 4)

    with pytest.raises(ValueError, match="MAV_AUTOPILOT_INVALID"):
        SitlServer(ServerConfig(connect="udpin:127.0.0.1:0"), [Impostor()])


def test_run_returns_after_duration_s():
    server = SitlServer(ServerConfig(connect="udpin:127.0.0.1:0", speed=50.0, duration_s=5.0))
    t0 = time.monotonic()
    server.run()
    server.close()
    assert time.monotonic() - t0 < 3.0
    s = server.state()
    assert s.time_s >= 5.0 and not s.armed and s.altitude_m == 0.0
