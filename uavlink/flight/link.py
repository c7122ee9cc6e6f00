"""The MAVLink side of ``uavlink fly``: a ground-station/companion link to a PX4-style vehicle.

Follows what PX4 expects from an offboard companion (and what MAVSDK's examples do): wait for the
autopilot's heartbeat, arm, take off, stream position setpoints before and while in OFFBOARD, land.
Every message in either direction is written to a .tlog (8-byte big-endian microsecond timestamp +
raw packet, as MAVProxy writes; readable by ``mavlogdump.py``).
"""

from __future__ import annotations

import math
import os
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from uavlink.flight.connection import normalize_connection
from uavlink.flight.radio_codec import RADIO_COMPONENT_ID, decode_score, message_kind

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

MAV = mavutil.mavlink
PX4_MAIN_AUTO, PX4_MAIN_OFFBOARD = 4, 6
PX4_SUB_LOITER, PX4_SUB_LAND = 3, 6
MULTIROTOR_TYPES = {MAV.MAV_TYPE_QUADROTOR, MAV.MAV_TYPE_HEXAROTOR, MAV.MAV_TYPE_OCTOROTOR,
                    MAV.MAV_TYPE_TRICOPTER, MAV.MAV_TYPE_COAXIAL}
POSITION_ONLY_MASK = 0x0DF8  # ignore velocity, acceleration, yaw, yaw rate: position bits clear


class LinkError(RuntimeError):
    """The vehicle did not answer or refused; the message says what and why."""


@dataclass
class VehicleStatus:
    armed: bool = False
    main_mode: int = 0
    sub_mode: int = 0
    landed_state: int = 0
    north_m: float = 0.0
    east_m: float = 0.0
    down_m: float = 0.0
    time_boot_ms: int = 0
    heartbeats: int = 0

    @property
    def in_air(self) -> bool:
        return self.landed_state in (MAV.MAV_LANDED_STATE_IN_AIR, MAV.MAV_LANDED_STATE_TAKEOFF)

    @property
    def offboard(self) -> bool:
        return self.main_mode == PX4_MAIN_OFFBOARD


class VehicleLink:
    def __init__(self, url: str, tlog: Path | None = None, system_id: int = 255,
                 component_id: int = MAV.MAV_COMP_ID_ONBOARD_COMPUTER) -> None:
        self.url = normalize_connection(url)
        self.conn = mavutil.mavlink_connection(self.url, source_system=system_id,
                                               source_component=component_id, dialect="common")
        self.status = VehicleStatus()
        self.target_system = 1
        self.on_radio: Callable = lambda msg: None
        self.on_score: Callable = lambda score: None
        self._acks: dict[int, int] = {}
        # Offboard keep-alive: while set, poll() re-sends this NED setpoint every
        # ``stream_period_vehicle_s`` of vehicle time, so waits never starve PX4's offboard stream.
        self.stream_ned: tuple[float, float, float] | None = None
        self.stream_period_vehicle_s = 0.2
        self._last_stream = 0.0
        self._boot_samples: list[tuple[float, float]] = []
        self._tlog = open(tlog, "wb") if tlog else None  # noqa: SIM115 - closed in close()
        if self._tlog:
            self.conn.mav.set_send_callback(self._log_sent)

    # -- I/O ---------------------------------------------------------------------------------
    def _log(self, msg) -> None:
        self._tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + msg.get_msgbuf())

    def _log_sent(self, msg) -> None:
        self._log(msg)

    def poll(self, timeout_s: float) -> None:
        """Handle the messages that arrive within ``timeout_s`` of wall time; keep the stream alive."""
        if self.stream_ned is not None:
            period = self.stream_period_vehicle_s / self.speed_factor()
            due = self._last_stream + period - time.monotonic()
            if due <= 0:
                self.send_setpoint(*self.stream_ned)
                due = period
            timeout_s = min(timeout_s, due)
        msg = self.conn.recv_match(blocking=True, timeout=max(timeout_s, 0.0))
        while msg is not None:
            self._handle(msg)
            msg = self.conn.recv_match(blocking=False)

    def _handle(self, msg) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        if self._tlog:
            self._log(msg)
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if src_sys != self.target_system:
            return
        st = self.status
        if kind == "HEARTBEAT" and src_comp == 1:
            st.heartbeats += 1
            self.heartbeat = msg
            st.armed = bool(msg.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED)
            st.main_mode = (msg.custom_mode >> 16) & 0xFF
            st.sub_mode = (msg.custom_mode >> 24) & 0xFF
        elif kind == "LOCAL_POSITION_NED":
            st.north_m, st.east_m, st.down_m = msg.x, msg.y, msg.z
            st.time_boot_ms = msg.time_boot_ms
            self._boot_samples.append((time.monotonic(), msg.time_boot_ms * 1e-3))
            del self._boot_samples[:-50]
        elif kind == "EXTENDED_SYS_STATE":
            st.landed_state = msg.landed_state
        elif kind == "COMMAND_ACK":
            self._acks[msg.command] = msg.result
        elif src_comp == RADIO_COMPONENT_ID:
            which = message_kind(msg)
            if which == "readings":
                self.on_radio(msg)
            elif which == "score":
                self.on_score(decode_score(msg))

    def close(self) -> None:
        if self._tlog:
            self._tlog.close()
            self._tlog = None
        self.conn.close()

    # -- time ----------------------------------------------------------------------------------
    def speed_factor(self) -> float:
        """Vehicle seconds per wall second, from LOCAL_POSITION_NED timestamps (1.0 until known)."""
        if len(self._boot_samples) < 5:
            return 1.0
        (w0, b0), (w1, b1) = self._boot_samples[0], self._boot_samples[-1]
        return max((b1 - b0) / (w1 - w0), 0.1) if w1 - w0 > 0.05 and b1 > b0 else 1.0

    def wait_until(self, condition: Callable[[], bool], vehicle_s: float, what: str) -> None:
        """Poll until ``condition()``; LinkError after ``vehicle_s`` of vehicle time (at least 3 s wall)."""
        deadline = time.monotonic() + max(3.0, vehicle_s / self.speed_factor())
        while not condition():
            if time.monotonic() > deadline:
                raise LinkError(f"timed out waiting for {what}")
            self.poll(0.05)

    # -- vehicle -------------------------------------------------------------------------------
    def wait_vehicle(self, timeout_s: float = 30.0) -> None:
        """Wait for the autopilot's heartbeat; refuse anything but a PX4 multicopter."""
        deadline = time.monotonic() + timeout_s
        while self.status.heartbeats == 0:
            if time.monotonic() > deadline:
                raise LinkError(f"no heartbeat from a vehicle on {self.url} within {timeout_s:.0f} s")
            self.poll(0.2)
        hb = self.heartbeat
        if hb.autopilot != MAV.MAV_AUTOPILOT_PX4 or hb.type not in MULTIROTOR_TYPES:
            raise LinkError(f"vehicle is not a PX4 multicopter (autopilot {hb.autopilot}, type {hb.type})")
        # Wait for a position too: the mission starts from it.
        self.wait_until(lambda: len(self._boot_samples) >= 5, 10.0, "LOCAL_POSITION_NED")

    def command(self, command: int, *params: float, vehicle_s: float = 3.0, retries: int = 3) -> None:
        """COMMAND_LONG to the autopilot, retried (confirmation 0, 1, ...) until an ACK; LinkError on refusal."""
        params = tuple(params) + (math.nan,) * (7 - len(params))
        name = MAV.enums["MAV_CMD"][command].name if command in MAV.enums["MAV_CMD"] else str(command)
        for confirmation in range(retries):
            self._acks.pop(command, None)
            self.conn.mav.command_long_send(self.target_system, 1, command, confirmation, *params)
            try:
                self.wait_until(lambda: command in self._acks, vehicle_s, f"ACK of {name}")
            except LinkError:
                continue
            result = self._acks[command]
            if result not in (MAV.MAV_RESULT_ACCEPTED, MAV.MAV_RESULT_IN_PROGRESS):
                raise LinkError(f"vehicle refused {name} (MAV_RESULT {result})")
            return
        raise LinkError(f"no ACK for {name} after {retries} tries")

    def set_param(self, name: str, value: float) -> None:
        self.conn.mav.param_set_send(self.target_system, 1, name.encode(), float(value),
                                     MAV.MAV_PARAM_TYPE_REAL32)

    def arm(self) -> None:
        self.command(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        self.wait_until(lambda: self.status.armed, 3.0, "armed heartbeat")

    def takeoff(self, altitude_m: float) -> None:
        self.set_param("MIS_TAKEOFF_ALT", altitude_m)
        self.poll(0.05)
        self.command(MAV.MAV_CMD_NAV_TAKEOFF)
        self.wait_until(lambda: -self.status.down_m >= altitude_m - 1.0, 120.0, f"take-off to {altitude_m:g} m")

    def set_mode(self, main: int, sub: int = 0) -> None:
        base = MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (MAV.MAV_MODE_FLAG_SAFETY_ARMED if self.status.armed else 0)
        self.command(MAV.MAV_CMD_DO_SET_MODE, float(base), float(main), float(sub))

    def send_setpoint(self, north_m: float, east_m: float, down_m: float) -> None:
        self._last_stream = time.monotonic()
        self.conn.mav.set_position_target_local_ned_send(
            self.status.time_boot_ms, self.target_system, 1, MAV.MAV_FRAME_LOCAL_NED,
            POSITION_ONLY_MASK, north_m, east_m, down_m, 0, 0, 0, 0, 0, 0, 0, 0)

    def land(self) -> None:
        self.command(MAV.MAV_CMD_NAV_LAND)
