"""A pymavlink ground station against ``python -m sitl_stub`` in a child process (loopback only).

The GCS sends target_component 0 (broadcast), as pymavlink ground stations do.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator

import pytest

from sitl_stub.core.params import int_to_param_float, param_float_to_int
from sitl_stub.launcher import vehicle_process
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavutil

pytestmark = [pytest.mark.slow, pytest.mark.timeout(90)]

mavlink = mavutil.mavlink
GCS_SYS, GCS_COMP = 245, 190
SPEED = 5.0
NAN = math.nan
POSITION_ONLY = 0xDF8  # velocity, acceleration and yaw rate ignored, yaw used
OFFBOARD = 6 << 16
LOITER = 4 << 16 | 3 << 24
TAKEOFF = 4 << 16 | 2 << 24
LAND = 4 << 16 | 6 << 24


class Gcs:
    """A minimal ground station on ``udpout`` to a listening vehicle."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=GCS_SYS, source_component=GCS_COMP
        )
        self.mav = self.conn.mav
        self.setpoint: tuple[float, float, float] | None = None
        self._last_sp = 0.0

    def close(self) -> None:
        self.conn.close()

    def pump(self) -> None:
        """Keep the vehicle aware of us and stream the setpoint at 20 Hz wall, as MAVSDK does."""
        now = time.monotonic()
        if self.setpoint is not None and now - self._last_sp >= 0.05:
            self._last_sp = now
            n, e, d = self.setpoint
            self.mav.set_position_target_local_ned_send(
                0,
                1,
                0,
                mavlink.MAV_FRAME_LOCAL_NED,
                POSITION_ONLY,
                n,
                e,
                d,
                0,
                0,
                0,
                0,
                0,
                0,
                0.0,
                0.0,
            )

    def wait(
        self,
        kind: str | list[str],
        pred: Callable[[object], bool] = lambda m: True,
        timeout: float = 10.0,
    ):
        """First message of ``kind`` from the vehicle (system 1) satisfying ``pred``."""
        deadline = time.monotonic() + timeout
        kinds = [kind] if isinstance(kind, str) else kind
        while time.monotonic() < deadline:
            self.pump()
            m = self.conn.recv_match(type=kinds, blocking=True, timeout=0.02)
            if m is not None and m.get_srcSystem() == 1 and pred(m):
                return m
        raise AssertionError(f"no {kind} matching within {timeout} s")

    def drain(self) -> None:
        """Drop what is queued, so the next wait() sees fresh messages."""
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def heartbeat(self, pred: Callable[[object], bool] = lambda m: True, timeout: float = 10.0):
        return self.wait("HEARTBEAT", lambda m: m.get_srcComponent() == 1 and pred(m), timeout)

    def command(self, cmd: int, *params: float, confirmation: int = 0) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(1, 0, cmd, confirmation, *p)
        ack = self.wait("COMMAND_ACK", lambda m: m.command == cmd, timeout=5.0)
        assert (ack.target_system, ack.target_component) == (GCS_SYS, GCS_COMP)
        return int(ack.result)

    def param(self, name: str):
        self.mav.param_request_read_send(1, 0, name.encode(), -1)
        return self.wait("PARAM_VALUE", lambda m: m.param_id == name, timeout=5.0)


@pytest.fixture
def gcs() -> Iterator[Gcs]:
    port = free_udp_port()
    with vehicle_process(f"udp:127.0.0.1:{port}", SPEED, ["--no-payload"]) as vehicle:
        g = Gcs(port)
        try:
            g.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            deadline = time.monotonic() + 15.0
            while g.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is None:
                assert vehicle.proc.poll() is None, vehicle.output()
                assert time.monotonic() < deadline, "vehicle never answered"
                g.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            yield g
        finally:
            g.close()


def test_identifies_as_px4_quadrotor_with_healthy_telemetry(gcs: Gcs):
    hb = gcs.heartbeat()
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_PX4 and hb.type == mavlink.MAV_TYPE_QUADROTOR
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == LOITER
    assert mavutil.interpret_px4_mode(hb.base_mode, hb.custom_mode) == "LOITER"
    st = gcs.wait("SYS_STATUS")
    for bit in (
        mavlink.MAV_SYS_STATUS_SENSOR_GPS,
        mavlink.MAV_SYS_STATUS_PREARM_CHECK,
        mavlink.MAV_SYS_STATUS_GEOFENCE,
    ):
        assert st.onboard_control_sensors_present & bit
        assert st.onboard_control_sensors_enabled & bit
        assert st.onboard_control_sensors_health & bit
    assert gcs.wait("EXTENDED_SYS_STATE").landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND
    g1 = gcs.wait("GLOBAL_POSITION_INT")
    assert (g1.lat, g1.lon, g1.alt, g1.relative_alt) == (473977420, 85455940, 488000, 0)
    assert gcs.wait("GPS_RAW_INT").fix_type == mavlink.GPS_FIX_TYPE_3D_FIX
    home = gcs.wait("HOME_POSITION", timeout=6.0)
    assert (home.latitude, home.longitude, home.altitude) == (473977420, 85455940, 488000)
    lp = gcs.wait("LOCAL_POSITION_NED")
    gcs.wait("ATTITUDE")
    time.sleep(1.0)
    gcs.drain()
    g2 = gcs.wait("GLOBAL_POSITION_INT")
    # time_boot_ms is simulated time: about SPEED x the wall time that passed
    assert (g2.time_boot_ms - g1.time_boot_ms) / 1000.0 > 0.8 * SPEED
    assert (lp.x, lp.y, lp.z) == (0.0, 0.0, 0.0)


def test_params_read_list_set_and_int_encoding(gcs: Gcs):
    p = gcs.param("COM_OF_LOSS_T")
    assert p.param_type == mavlink.MAV_PARAM_TYPE_REAL32 and p.param_value == pytest.approx(1.0)
    assert gcs.param("MPC_XY_VEL_MAX").param_value == pytest.approx(12.0)
    assert gcs.param("MIS_TAKEOFF_ALT").param_value == pytest.approx(95.0)
    obl = gcs.param("COM_OBL_ACT")
    assert obl.param_type == mavlink.MAV_PARAM_TYPE_INT32
    assert param_float_to_int(obl.param_value) == 1  # bytewise, not a float cast
    gcs.mav.param_request_read_send(1, 0, b"", obl.param_index)
    by_index = gcs.wait("PARAM_VALUE", lambda m: m.param_index == obl.param_index)
    assert by_index.param_id == "COM_OBL_ACT"
    gcs.mav.param_set_send(
        1, 0, b"COM_OBL_ACT", int_to_param_float(2), mavlink.MAV_PARAM_TYPE_INT32
    )
    echo = gcs.wait("PARAM_VALUE", lambda m: m.param_id == "COM_OBL_ACT")
    assert param_float_to_int(echo.param_value) == 2
    gcs.mav.param_set_send(1, 0, b"MPC_XY_VEL_MAX", -3.0, mavlink.MAV_PARAM_TYPE_REAL32)
    refused = gcs.wait("PARAM_VALUE", lambda m: m.param_id == "MPC_XY_VEL_MAX")
    assert refused.param_value == pytest.approx(12.0)  # out of range: old value answered
    said = gcs.wait("STATUSTEXT", lambda m: "MPC_XY_VEL_MAX" in m.text)
    assert said.text == "[pm] MPC_XY_VEL_MAX -3 refused: 0.5..20"
    # A name the vehicle does not have: no PARAM_VALUE, PX4's STATUSTEXT says so.
    gcs.mav.param_set_send(1, 0, b"NAV_RCL_ACT", 0.0, mavlink.MAV_PARAM_TYPE_INT32)
    assert gcs.wait("STATUSTEXT", lambda m: "NAV_RCL_ACT" in m.text).text == (
        "[pm] unknown param: NAV_RCL_ACT"
    )
    gcs.mav.param_request_list_send(1, 0)
    seen: set[str] = set()
    count = None
    deadline = time.monotonic() + 5.0
    while count is None or len(seen) < count:
        assert time.monotonic() < deadline
        m = gcs.wait("PARAM_VALUE")
        seen.add(m.param_id)
        count = m.param_count
    assert {"COM_OF_LOSS_T", "MPC_XY_VEL_MAX", "MIS_TAKEOFF_ALT", "RTL_RETURN_ALT"} <= seen


def test_every_command_long_gets_an_ack(gcs: Gcs):
    A, D, U = (
        mavlink.MAV_RESULT_ACCEPTED,
        mavlink.MAV_RESULT_DENIED,
        mavlink.MAV_RESULT_UNSUPPORTED,
    )
    assert (
        gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == A
    )
    ver = gcs.wait("AUTOPILOT_VERSION")
    assert ver.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert ver.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    assert gcs.command(mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1) == A
    assert gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION) == A
    gcs.wait("HOME_POSITION")
    assert (
        gcs.command(
            mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 1e6
        )
        == A
    )
    assert gcs.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 9999, 1e6) == D
    assert (
        gcs.command(mavlink.MAV_CMD_GET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE)
        == A
    )
    assert gcs.wait("MESSAGE_INTERVAL").interval_us == 1_000_000
    # A request the vehicle's state refuses is TEMPORARILY_REJECTED (PX4's Commander.cpp: try
    # again once the state allows it); a request that can never be met is DENIED.
    later = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 3, 0) == later  # POSCTL needs RC
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 4, 1) == D  # never AUTO.READY
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 6, 0) == later  # offboard without stream
    assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, *[NAN] * 7) == later  # disarmed
    assert gcs.command(mavlink.MAV_CMD_DO_SET_SERVO, 1, 1500) == U
    assert gcs.command(31999) == U  # not a command anyone knows
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, NAN, NAN, NAN, NAN, NAN, NAN) == A
    # a retry with confirmation > 0 is answered the same way and stays idempotent
    assert (
        gcs.command(
            mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, NAN, NAN, NAN, NAN, NAN, NAN, confirmation=1
        )
        == A
    )
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0) == A
    # COMMAND_INT is acknowledged too
    gcs.mav.command_int_send(
        1, 0, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_DO_SET_SERVO, 0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    ack = gcs.wait("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_DO_SET_SERVO)
    assert ack.result == U and ack.target_system == GCS_SYS


def test_ping_set_mode_message_and_mission_list(gcs: Gcs):
    gcs.mav.ping_send(123456, 7, 0, 0)
    pong = gcs.wait("PING")
    assert (pong.time_usec, pong.seq, pong.target_system, pong.target_component) == (
        123456,
        7,
        GCS_SYS,
        GCS_COMP,
    )
    gcs.mav.set_mode_send(1, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, LAND)
    gcs.heartbeat(lambda m: m.custom_mode == LAND)
    gcs.mav.mission_request_list_send(1, 0)
    count = gcs.wait("MISSION_COUNT")
    assert count.count == 0 and count.target_system == GCS_SYS


def test_flight_arm_takeoff_offboard_loss_and_land(gcs: Gcs):
    gcs.mav.param_set_send(1, 0, b"MIS_TAKEOFF_ALT", 10.0, mavlink.MAV_PARAM_TYPE_REAL32)
    assert gcs.wait("PARAM_VALUE", lambda m: m.param_id == "MIS_TAKEOFF_ALT").param_value == 10.0
    assert gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
    gcs.heartbeat(lambda m: m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    assert gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, *[NAN] * 7) == mavlink.MAV_RESULT_ACCEPTED
    gcs.heartbeat(lambda m: m.custom_mode == TAKEOFF)
    gcs.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_TAKEOFF)
    gcs.heartbeat(lambda m: m.custom_mode == LOITER, timeout=15.0)
    pos = gcs.wait("LOCAL_POSITION_NED")
    assert pos.z == pytest.approx(-10.0, abs=0.6)
    interval = mavlink.MAV_CMD_SET_MESSAGE_INTERVAL
    assert (
        gcs.command(interval, mavlink.MAVLINK_MSG_ID_ODOMETRY, 1e5) == mavlink.MAV_RESULT_ACCEPTED
    )
    odometry = gcs.wait("ODOMETRY")  # the same position as LOCAL_POSITION_NED, hovering
    assert (odometry.x, odometry.y, odometry.z) == pytest.approx((pos.x, pos.y, pos.z), abs=0.5)
    assert (odometry.frame_id, odometry.child_frame_id) == (
        mavlink.MAV_FRAME_LOCAL_NED,
        mavlink.MAV_FRAME_BODY_FRD,
    )
    assert gcs.command(interval, mavlink.MAVLINK_MSG_ID_ODOMETRY, -1) == mavlink.MAV_RESULT_ACCEPTED
    # In the air a disarm is refused as PX4 refuses it: TEMPORARILY_REJECTED (Commander.cpp).
    assert (
        gcs.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0)
        == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    )

    gcs.setpoint = (30.0, -20.0, -15.0)
    gcs.wait("HEARTBEAT", timeout=1.0)  # let a few setpoints flow first
    assert gcs.command(mavlink.MAV_CMD_DO_SET_MODE, 1, 6, 0) == mavlink.MAV_RESULT_ACCEPTED
    gcs.heartbeat(lambda m: m.custom_mode == OFFBOARD)
    reached = gcs.wait(
        "LOCAL_POSITION_NED", lambda m: math.dist((m.x, m.y, m.z), gcs.setpoint) < 1.0, timeout=20.0
    )
    assert abs(reached.x) <= 200 and abs(reached.y) <= 200

    gcs.setpoint = None  # stop streaming: COM_OF_LOSS_T later the vehicle holds
    t0 = time.monotonic()
    gcs.wait("STATUSTEXT", lambda m: "offboard lost" in m.text, timeout=5.0)
    gcs.heartbeat(lambda m: m.custom_mode == LOITER, timeout=5.0)
    assert time.monotonic() - t0 < 3.0
    held = gcs.wait("LOCAL_POSITION_NED")
    assert math.dist((held.x, held.y, held.z), (30.0, -20.0, -15.0)) < 1.5

    assert gcs.command(mavlink.MAV_CMD_NAV_LAND, *[NAN] * 7) == mavlink.MAV_RESULT_ACCEPTED
    gcs.heartbeat(lambda m: m.custom_mode == LAND)
    gcs.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_LANDING)
    gcs.wait(
        "EXTENDED_SYS_STATE",
        lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND,
        timeout=20.0,
    )
    gcs.heartbeat(lambda m: not m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED, timeout=5.0)


def test_heartbeat_keeps_a_wall_clock_floor_at_low_speed():
    port = free_udp_port()
    with vehicle_process(f"udpin://127.0.0.1:{port}", 0.2, ["--no-payload"]):
        g = Gcs(port)
        try:
            g.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            deadline = time.monotonic() + 15.0
            while g.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5) is None:
                assert time.monotonic() < deadline
                g.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            t0 = time.monotonic()
            g.heartbeat(timeout=2.0)
            g.heartbeat(timeout=2.0)  # at 0.2x, 1 simulated s would be 5 wall s
            assert time.monotonic() - t0 < 3.0
        finally:
            g.close()


def test_cli_bad_arguments_exit_2_with_one_line():
    for args in (
        ["--speed", "0"],
        ["--connect", "udp:nowhere"],
        ["--scenario", "nope"],
        ["--param", "NOPE=1"],
        ["--home-lat", "123"],
        ["--no-payload", "--lockstep"],
    ):
        r = subprocess.run(
            [sys.executable, "-m", "sitl_stub", *args], capture_output=True, text=True, timeout=30
        )
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.count("\n") == 1 and "error" in r.stderr, r.stderr


def test_cli_exits_cleanly_on_sigterm_sigint_and_duration():
    port = free_udp_port()
    for sig in (signal.SIGTERM, signal.SIGINT):
        with vehicle_process(f"udpout:127.0.0.1:{port}", 1.0, ["--no-payload"]) as v:
            deadline = time.monotonic() + 15.0
            while "vehicle 1 on" not in v.output():
                assert time.monotonic() < deadline and v.proc.poll() is None, v.output()
                time.sleep(0.05)
            v.proc.send_signal(sig)
            assert v.proc.wait(10) == 0
            assert "Traceback" not in v.output()
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "sitl_stub",
            "--no-payload",
            "--speed",
            "10",
            "--duration-s",
            "2",
            "--connect",
            f"udpout:127.0.0.1:{port}",
        ],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert r.returncode == 0, r.stderr


def test_the_vehicles_hard_limit_is_the_radio_worlds_area():
    """`--set area.half_width_m=50` shrank the radio world and left the vehicle's 200 m limit: a
    client other than `uavlink fly` (which uploads its own fence) could fly where the world ends."""
    import json

    def fence_m(*settings: str) -> float:
        r = subprocess.run(
            [sys.executable, "-m", "sitl_stub", *settings, "--duration-s", "0.5", "--connect",
             f"udpout:127.0.0.1:{free_udp_port()}"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        stats = r.stderr.strip().splitlines()[-1].removeprefix("sitl-stub: stats ")
        return json.loads(stats)["vehicle"]["fence_m"]

    assert fence_m() == 200.0
    assert fence_m("--set", "area.half_width_m=50") == 50.0
