"""The MAVLink side of ``uavlink fly``: a ground-station/companion link to a PX4-style vehicle.

Follows what PX4 expects from an offboard companion (and what MAVSDK's examples do): wait for the
autopilot's heartbeat, arm, take off, stream position setpoints before and while in OFFBOARD, land.
Every message in either direction is written to a .tlog (8-byte big-endian microsecond timestamp +
raw packet, as MAVProxy writes; readable by ``mavlogdump.py``).

Robustness: the link sends its own HEARTBEAT at 1 Hz (so a listening vehicle learns where to
answer, and as every MAVLink component should); commands are retried every half second of wall
time (``ACK_WAIT_S``) until acknowledged (the vehicle answers retries idempotently); parameter sets are
retried until the vehicle echoes the value. With a signing key everything sent is signed and
everything received must be signed by the same key (:mod:`uavlink.mavlink.signing`). Telemetry
that cannot be used (NaN positions, unusable radio scores, garbage bytes) is counted in
:attr:`VehicleLink.rejects` and logged once per kind.

Systems: the link keeps a :class:`VehicleStatus` per MAVLink system id it hears (as pymavlink's
``mavfile.sysid_state``), and commands one of them, its target: the one given, or else the system
(and component) of the first autopilot heartbeat (any HEARTBEAT whose autopilot is not
MAV_AUTOPILOT_INVALID: payloads, cameras and ground stations send INVALID). PX4's MAV_SYS_ID is 1
by default, but nothing here assumes it.
"""

from __future__ import annotations

import logging
import math
import select
import struct
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, BinaryIO, Protocol

from uavlink.errors import LinkError, UserError
from uavlink.flight.link.vehicle_status import VehicleStatus
from uavlink.mavlink import radio_codec as radio
from uavlink.mavlink.connection import is_listening, normalize_connection, open_mavlink
from uavlink.mavlink.dialect import enum_name, mavlink
from uavlink.mavlink.mission import MISSION_REPLIES
from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD
from uavlink.mavlink.rejects import RejectLog, rescan_bad_frame
from uavlink.mavlink.signing import SigningGuard
from uavlink.mavlink.typemask import POSITION_ONLY

MAV = mavlink
MULTIROTOR_TYPES = {
    MAV.MAV_TYPE_QUADROTOR,
    MAV.MAV_TYPE_HEXAROTOR,
    MAV.MAV_TYPE_OCTOROTOR,
    MAV.MAV_TYPE_TRICOPTER,
    MAV.MAV_TYPE_COAXIAL,
}
HEARTBEAT_PERIOD_S = 1.0  # our own HEARTBEAT, wall time
# Offboard keep-alive: 10 setpoints per COM_OF_LOSS_T survive a lossy link.
STREAM_PERIOD_VEHICLE_S = 0.1
ACK_WAIT_S = 0.5  # wall time to wait for a COMMAND_ACK before sending the command again
COMMAND_TRIES = 10
PARAM_TRIES = 10
MAX_RX_PER_POLL = 2000  # messages/datagrams handled per poll: a flood cannot stall the loop
# Packets signed with another key, none accepted: the heartbeat wait gives up.
WRONG_KEY_PACKETS = 20

log = logging.getLogger(__name__)


class _Group(Protocol):
    """What a link asks of its group (``group.LinkGroup``, which imports this module)."""

    def poll(self, timeout_s: float) -> None: ...


class VehicleLink:
    """The link to one vehicle: ``target_system``/``target_component`` when given, else learnt from
    the first autopilot heartbeat. ``system_id``/``component_id`` are the link's own ids."""

    def __init__(
        self,
        url: str,
        tlog: Path | None = None,
        system_id: int = 255,
        component_id: int = MAV.MAV_COMP_ID_ONBOARD_COMPUTER,
        signing_key: bytes | None = None,
        target_system: int | None = None,
        target_component: int | None = None,
        connection: Any = None,
        tlog_file: BinaryIO | None = None,
    ) -> None:
        for name, value in (
            ("target_system", target_system),
            ("target_component", target_component),
        ):
            if value is not None and not 1 <= value <= 255:
                raise ValueError(f"{name} must be in 1..255, got {value}")
        self.url = normalize_connection(url)
        # ``connection``: another link's (one URL carrying several systems; see ``group``)
        try:
            self.conn = connection or open_mavlink(
                self.url, source_system=system_id, source_component=component_id, dialect="common"
            )
        except OSError as exc:
            if not is_listening(self.url):  # nothing listens there: the vehicle, not the input
                raise LinkError(
                    f"cannot connect to {self.url}: {exc.strerror or exc} (is the vehicle running "
                    "and listening there?)"
                ) from None
            raise UserError(  # e.g. a ground station (QGroundControl: 14550) holds the port
                f"cannot open {self.url}: {exc.strerror or exc} "
                "(another ground station on this port? pick another with --connect)"
            ) from None
        self._owns_conn = connection is None
        self.group: _Group | None = None
        self.signing: SigningGuard | None = None
        if signing_key is not None and connection is None:
            self.signing = SigningGuard(signing_key)
            self.signing.attach(self.conn.mav)
        self.rejects = RejectLog(log)
        self.params: dict[str, float] = {}
        self.last_rx_wall = time.monotonic()
        self._last_heartbeat_sent = -math.inf
        self.systems: dict[int, VehicleStatus] = {}
        self.target_system = target_system
        self._target_component = target_component
        self.on_radio: Callable = lambda msg: None
        self.on_score: Callable = lambda score: None
        self.radio_episode: dict[
            str, int
        ] = {}  # the payload's UL_EP_SEED / UL_EPISODE: seed, count
        self._acks: dict[int, int] = {}
        self._mission_inbox: deque[Any] = deque(maxlen=64)  # for recv_mission
        # Offboard keep-alive: while set, poll() re-sends this NED setpoint every
        # ``stream_period_vehicle_s`` of vehicle time, so waits never starve PX4's offboard stream.
        self.stream_ned: tuple[float, float, float] | None = None
        self.stream_period_vehicle_s = STREAM_PERIOD_VEHICLE_S
        self._last_stream = 0.0
        self._speed = 1.0
        self._owns_tlog = tlog_file is None
        self._tlog = tlog_file or (open(tlog, "wb") if tlog else None)  # noqa: SIM115 - closed in close()
        if self._tlog:
            self.conn.mav.set_send_callback(self._log)

    # -- systems -------------------------------------------------------------------------------
    @property
    def status(self) -> VehicleStatus:
        """The target system's state (an empty one until the target is known)."""
        if self.target_system is None:
            return VehicleStatus()
        return self.systems.setdefault(self.target_system, VehicleStatus())

    @property
    def target_component(self) -> int:
        """The component commands go to: the one given, else the target's autopilot component
        (MAV_COMP_ID_AUTOPILOT1 until its heartbeat is heard)."""
        if self._target_component is not None:
            return self._target_component
        return self.status.component_id or MAV.MAV_COMP_ID_AUTOPILOT1

    # -- I/O ---------------------------------------------------------------------------------
    def _log(self, msg) -> None:
        assert self._tlog is not None  # the send callback is set only with a tlog
        self._tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + msg.get_msgbuf())

    def poll(self, timeout_s: float) -> None:
        """Handle what arrives within ``timeout_s`` (wall); keep the stream(s) of its group alive."""
        if self.group is not None:
            return self.group.poll(timeout_s)
        timeout_s = min(timeout_s, self.keep_alive(time.monotonic()))
        msg = self._recv(blocking=True, timeout=timeout_s) if timeout_s > 0 else None
        if msg is not None:
            self._handle(msg)
        self.drain()

    def drain(self, sharing: Sequence[VehicleLink] = ()) -> None:
        """Handle what waits on this link's connection (at most ``MAX_RX_PER_POLL`` messages), each
        message also by the links in ``sharing``: others on the same connection (``LinkGroup``)."""
        for _ in range(MAX_RX_PER_POLL):
            msg = self._recv(blocking=False)
            if msg is None:
                if not self._readable():  # nothing waiting (a None can also be a garbage datagram)
                    return
                continue
            self._handle(msg)
            for link in sharing:
                link._handle(msg, first=False)

    def keep_alive(self, now: float) -> float:
        """Send our HEARTBEAT and the offboard keep-alive setpoint when due; wall seconds until
        the next is due."""
        if now - self._last_heartbeat_sent >= HEARTBEAT_PERIOD_S:
            self._last_heartbeat_sent = now
            self.conn.mav.heartbeat_send(
                MAV.MAV_TYPE_ONBOARD_CONTROLLER,
                MAV.MAV_AUTOPILOT_INVALID,
                0,
                0,
                MAV.MAV_STATE_ACTIVE,
            )
        if self.stream_ned is None:
            return HEARTBEAT_PERIOD_S
        period = self.stream_period_vehicle_s / self.speed_factor()
        due = self._last_stream + period - now
        if due <= 0:
            self.send_setpoint(*self.stream_ned)
            due = period
        return min(due, HEARTBEAT_PERIOD_S)

    def _readable(self) -> bool:
        try:
            return bool(select.select([self.conn.fd], [], [], 0)[0])
        except (OSError, ValueError):
            return False

    def _recv(self, **kwargs):
        if self.signing is not None and not self.signing.is_attached(self.conn.mav):
            raise LinkError("pymavlink replaced the signed MAVLink parser; refusing to go on")
        try:
            return self.conn.recv_match(**kwargs)
        except Exception as exc:  # a parser error robust parsing did not turn into BAD_DATA
            self.rejects.reject("parse_error", f"MAVLink parser error: {exc!r}")
            self.conn.mav.buf, self.conn.mav.buf_index = bytearray(), 0
            return None

    def _handle(self, msg, first: bool = True) -> None:
        """One received message; ``first``: this link is the first of those sharing the
        connection to see it (it rescans bad frames and writes the tlog record)."""
        kind = msg.get_type()
        if first:
            rescan_bad_frame(self.conn.mav, msg)
        if not self.rejects.screen(msg):
            return
        if self._tlog and first:
            self._log(msg)
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if (
            self.target_system is None
            and kind == "HEARTBEAT"
            and msg.autopilot != MAV.MAV_AUTOPILOT_INVALID
        ):
            self.target_system = src_sys
            log.info(
                "target: system %d component %d (first autopilot heartbeat)", src_sys, src_comp
            )
        st = self.systems.setdefault(src_sys, VehicleStatus())
        st.track(msg, kind, src_comp, self.rejects)
        if src_sys != self.target_system:
            return
        self.last_rx_wall = time.monotonic()
        if kind == "COMMAND_ACK":
            self._acks[msg.command] = msg.result
        elif kind in MISSION_REPLIES:
            self._mission_inbox.append(msg)
        elif kind == "PARAM_VALUE":
            name = (
                msg.param_id
                if isinstance(msg.param_id, str)
                else msg.param_id.decode("ascii", "replace")
            )
            self.params[name.split("\x00", 1)[0]] = msg.param_value
        elif src_comp == radio.RADIO_COMPONENT_ID:
            which = radio.message_kind(msg)
            if which == "readings":
                self.on_radio(msg)
            elif kind == "NAMED_VALUE_INT" and (episode := radio.decode_episode(msg)) is not None:
                self.radio_episode[episode[0]] = episode[1]
            elif which == "score":
                try:
                    score = radio.decode_score(msg)
                except radio.RadioReportError as exc:
                    self.rejects.reject("radio_score", f"radio score: {exc}")
                    return
                self.on_score(score)

    @property
    def unsigned_to_a_signing_vehicle(self) -> bool:
        """We send unsigned packets while the vehicle's arrive signed: pymavlink counts every packet
        that carries a signature (MAVLINK_IFLAG_SIGNED) in ``signing.sig_count`` even without a key to
        check it, so the vehicle is heard, and it drops what we send."""
        signing = self.conn.mav.signing
        return signing.secret_key is None and bool(signing.sig_count)

    def close(self) -> None:
        if self._tlog and self._owns_tlog:
            self._tlog.close()
        self._tlog = None
        if self._owns_conn:
            self.conn.close()

    # -- time ----------------------------------------------------------------------------------
    def speed_factor(self) -> float:
        """Vehicle seconds per wall second, from LOCAL_POSITION_NED timestamps (1.0 until known;
        the last estimate while too few samples are at hand)."""
        samples = self.status.boot_samples
        if len(samples) >= 5:
            (w0, b0), (w1, b1) = samples[0], samples[-1]
            if w1 - w0 > 0.05 and b1 > b0:
                self._speed = max((b1 - b0) / (w1 - w0), 0.1)
        return self._speed

    def wait_until(self, condition: Callable[[], bool], vehicle_s: float, what: str) -> None:
        """Poll until ``condition()``; LinkError after ``vehicle_s`` of vehicle time (at least 3 s wall)."""
        deadline = time.monotonic() + max(3.0, vehicle_s / self.speed_factor())
        while not condition():
            if time.monotonic() > deadline:
                raise LinkError(f"timed out waiting for {what}")
            self.poll(0.05)

    # -- vehicle -------------------------------------------------------------------------------
    def wait_vehicle(self, timeout_s: float = 30.0) -> None:
        """Wait for the target autopilot's heartbeat (the first autopilot's, when no target was
        given); refuse anything but a PX4 multicopter. Then wait for its position and landed state:
        whether it is already flying decides take-off or resume."""
        deadline = time.monotonic() + timeout_s
        while self.status.heartbeats == 0:
            if time.monotonic() > deadline:
                raise LinkError(
                    f"no heartbeat from a vehicle on {self.url} within {timeout_s:.0f} s"
                )
            guard = self.signing
            if (
                guard is not None
                and not guard.accepted
                and guard.rejected["bad_signature"] >= WRONG_KEY_PACKETS
            ):
                # a vehicle signing with another key: none of its packets will ever pass, so say so now
                raise LinkError(
                    f"no heartbeat accepted from {self.url}: its packets "
                    f"({guard.rejected['bad_signature']} so far) are all signed with another key"
                )
            self.poll(0.2)
        hb = self.status.heartbeat
        if hb.autopilot != MAV.MAV_AUTOPILOT_PX4 or hb.type not in MULTIROTOR_TYPES:
            raise LinkError(
                f"vehicle is not a PX4 multicopter (autopilot {hb.autopilot}, type {hb.type})"
            )
        # Wait for a position too: the mission starts from it; and for the landed state.
        self.wait_until(lambda: len(self.status.boot_samples) >= 5, 10.0, "LOCAL_POSITION_NED")
        self.wait_until(lambda: self.status.landed_known, 10.0, "EXTENDED_SYS_STATE")

    def wait_wall(self, condition: Callable[[], bool], wall_s: float) -> bool:
        """Poll until ``condition()`` (True) or ``wall_s`` of wall time pass (False)."""
        deadline = time.monotonic() + wall_s
        while not condition():
            if time.monotonic() > deadline:
                return False
            self.poll(0.02)
        return True

    def recv_mission(self, timeout_s: float) -> Any:
        """The target's next mission-protocol message within ``timeout_s`` of wall time, or None
        (a :data:`~uavlink.mavlink.mission.MissionRecv`: everything else is handled meanwhile)."""
        self.wait_wall(lambda: bool(self._mission_inbox), timeout_s)
        return self._mission_inbox.popleft() if self._mission_inbox else None

    def command(
        self,
        command: int,
        *params: float,
        ack_wait_s: float = ACK_WAIT_S,
        tries: int = COMMAND_TRIES,
        done: Callable[[], bool] | None = None,
    ) -> None:
        """COMMAND_LONG to the autopilot, sent again (confirmation 0, 1, ...) every ``ack_wait_s``
        of wall time until an ACK comes (or ``done()``: the telemetry already shows the effect, so
        a lost ACK costs no retry), and after a TEMPORARILY_REJECTED (PX4's answer when the state
        refuses it for now, as an arming before the estimator is ready); LinkError on any other
        refusal or after ``tries`` sends."""
        name, rejected = enum_name("MAV_CMD", command), False
        self._acks.pop(command, None)
        for confirmation in range(tries):
            self.send_command(command, *params, confirmation=confirmation)
            if not self.wait_wall(
                lambda: command in self._acks or (done is not None and done()), ack_wait_s
            ):
                continue
            if command not in self._acks:
                return  # done() although the ACK was lost
            result = self._acks.pop(command)
            rejected = result == MAV.MAV_RESULT_TEMPORARILY_REJECTED
            if rejected:
                self.wait_wall(lambda: False, ack_wait_s)
                continue
            if result not in (MAV.MAV_RESULT_ACCEPTED, MAV.MAV_RESULT_IN_PROGRESS):
                raise LinkError(f"vehicle refused {name} (MAV_RESULT {result})")
            return
        if rejected:
            raise LinkError(f"vehicle refused {name} for now, {tries} times (TEMPORARILY_REJECTED)")
        raise LinkError(f"no ACK for {name} after {tries} tries")

    def send_command(self, command: int, *params: float, confirmation: int = 0) -> None:
        """One COMMAND_LONG to the autopilot, unused params NaN; no wait for its ACK (``command``
        waits)."""
        params = tuple(params) + (math.nan,) * (7 - len(params))
        self.conn.mav.command_long_send(
            self.target_system, self.target_component, command, min(confirmation, 255), *params
        )

    def set_param(self, name: str, value: float, tries: int = PARAM_TRIES) -> None:
        """PARAM_SET, sent again until the vehicle's PARAM_VALUE shows the value (REAL32 only)."""
        self.params.pop(name, None)
        for _ in range(tries):
            self.conn.mav.param_set_send(
                self.target_system,
                self.target_component,
                name.encode(),
                float(value),
                MAV.MAV_PARAM_TYPE_REAL32,
            )
            if self.wait_wall(lambda: name in self.params, ACK_WAIT_S):
                if abs(self.params[name] - value) <= 1e-3 * max(1.0, abs(value)):
                    return
                raise LinkError(f"vehicle refused {name}={value:g} (keeps {self.params[name]:g})")
        raise LinkError(f"no PARAM_VALUE for {name} after {tries} tries")

    def arm(self, armed: bool = True) -> None:
        """Arm (or, with ``armed=False``, disarm) and wait for a heartbeat that shows it."""
        beats = self.status.heartbeats
        self.command(
            MAV.MAV_CMD_COMPONENT_ARM_DISARM,
            float(armed),
            done=lambda: self.status.armed == armed and self.status.heartbeats > beats,
        )
        self.wait_until(
            lambda: self.status.armed == armed, 3.0, f"{'' if armed else 'dis'}armed heartbeat"
        )

    def takeoff(self, altitude_m: float, wait: bool = True) -> None:
        """Take off to ``altitude_m`` (PX4: MIS_TAKEOFF_ALT, then NAV_TAKEOFF); with ``wait``, until
        there (:meth:`wait_altitude`)."""
        self.set_param("MIS_TAKEOFF_ALT", altitude_m)
        self.command(MAV.MAV_CMD_NAV_TAKEOFF)
        if wait:
            self.wait_altitude(altitude_m)

    def wait_altitude(self, altitude_m: float) -> None:
        """Poll until the vehicle is within 1 m of ``altitude_m``; LinkError after 120 s of its time."""
        self.wait_until(
            lambda: -self.status.down_m >= altitude_m - 1.0, 120.0, f"take-off to {altitude_m:g} m"
        )

    def _mode_params(self, main: int, sub: int) -> tuple[float, float, float]:
        """DO_SET_MODE's params for PX4's custom mode ``main``/``sub`` (base mode: custom, armed as now)."""
        base = MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            MAV.MAV_MODE_FLAG_SAFETY_ARMED if self.status.armed else 0
        )
        return float(base), float(main), float(sub)

    def request_mode(self, main: int, sub: int = 0) -> None:
        """DO_SET_MODE sent once, no wait: a loop that flies other vehicles meanwhile asks again."""
        self.send_command(MAV.MAV_CMD_DO_SET_MODE, *self._mode_params(main, sub))

    def set_mode(self, main: int, sub: int = 0, tries: int = COMMAND_TRIES) -> None:
        """DO_SET_MODE; done when ACKed or when a heartbeat received after sending shows the mode."""
        st = self.status
        beats = st.heartbeats

        def shows_mode() -> bool:
            in_mode = st.main_mode == main and (main == PX4_MAIN_OFFBOARD or st.sub_mode == sub)
            return st.heartbeats > beats and in_mode

        self.command(
            MAV.MAV_CMD_DO_SET_MODE, *self._mode_params(main, sub), tries=tries, done=shows_mode
        )

    def send_setpoint(self, north_m: float, east_m: float, down_m: float) -> None:
        self._last_stream = time.monotonic()
        self.conn.mav.set_position_target_local_ned_send(
            self.status.time_boot_ms,
            self.target_system,
            self.target_component,
            MAV.MAV_FRAME_LOCAL_NED,
            POSITION_ONLY,
            north_m,
            east_m,
            down_m,
            *(0,) * 8,  # velocity, acceleration, yaw, yaw rate: ignored (POSITION_ONLY)
        )

    def land(self) -> None:
        self.command(MAV.MAV_CMD_NAV_LAND)
