"""The SITL vehicle's MAVLink 2 endpoint: system 1, autopilot component 1, plus payload components.

One thread does everything: it advances simulated time (:class:`~sitl_stub.clock.SimClock`),
steps the :class:`~sitl_stub.vehicle.Vehicle` (stopping at payload frame boundaries to tick the
payloads), handles incoming messages and sends the telemetry that is due. Use it blocking
(:meth:`SitlServer.run`, as ``python -m sitl_stub`` does) or in the background
(:meth:`SitlServer.start` / :meth:`SitlServer.stop`, or ``with SitlServer(...)``), e.g. listening
on ``udpin:127.0.0.1:0`` and reading the chosen port from :attr:`SitlServer.address`.

Accepted targets: target_system 0 or the vehicle's id, target_component 0 (broadcast, what
pymavlink ground stations send) or 1; commands addressed to a payload's component id go to it.

With ``ServerConfig.signing_key`` every packet the vehicle sends (autopilot and payloads) is signed
and every packet it receives must be signed with that key, newer than the last one of its stream
(see :mod:`uavlink.mavlink.signing`); anything else is dropped before it is looked at: no ACK, no
effect. Rejected input of every kind (signing, bad bytes, unknown messages, unusable setpoints,
refused parameters and commands) is counted in :meth:`SitlServer.report` and logged once per kind.
"""

from __future__ import annotations

import logging
import math
import select
import threading
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from sitl_stub.clock import SimClock
from sitl_stub.commands import CommandHandler, CommandReply, CommandRequest
from sitl_stub.ftp import ftp_reply
from sitl_stub.geo import GeoOrigin
from sitl_stub.param_protocol import ParamProtocol
from sitl_stub.params import ParamStore
from sitl_stub.payload import Payload, check_payload
from sitl_stub.streams import StreamScheduler
from sitl_stub.telemetry import TelemetrySender
from sitl_stub.vehicle import Vehicle
from sitl_stub.vehicle_state import Result, VehicleState
from uavlink.config import AreaConfig
from uavlink.mavlink.connection import normalize_connection
from uavlink.mavlink.dialect import mavlink, mavutil
from uavlink.mavlink.px4_modes import decode_custom_mode
from uavlink.mavlink.rejects import RejectLog, rescan_bad_frame
from uavlink.mavlink.signing import SigningGuard

log = logging.getLogger("sitl_stub")

AUTOPILOT_COMPONENT = 1
POSITION_IGNORE_MASK = 0x7  # SET_POSITION_TARGET type_mask bits x, y, z
YAW_IGNORE_BIT = 0x400
LOOP_WAIT_S = 0.005  # longest wait for input between loop iterations (wall)
MAX_RX_PER_TICK = 2000  # messages/datagrams handled per loop iteration: a flood cannot stall time


@dataclass(frozen=True)
class ServerConfig:
    """How to run the vehicle. ``speed`` is simulated seconds per wall second; ``duration_s``
    (simulated) ends :meth:`SitlServer.run`; ``params`` overrides parameter defaults."""

    connect: str = "udpout:127.0.0.1:14550"
    speed: float = 1.0
    home: GeoOrigin = field(default_factory=GeoOrigin)
    area: AreaConfig = field(default_factory=AreaConfig)
    params: Mapping[str, float] = field(default_factory=dict)
    system_id: int = 1
    duration_s: float | None = None
    max_stream_wall_hz: float = 50.0
    signing_key: bytes | None = field(default=None, repr=False)


@dataclass
class _Slot:
    payload: Payload
    mav: Any
    next_frame: int = 0
    failures: int = 0


class SitlServer:
    """A PX4-style SITL multicopter speaking MAVLink 2 on one connection."""

    def __init__(self, config: ServerConfig | None = None, payloads: Sequence[Payload] = ()) -> None:
        self.config = config or ServerConfig()
        c = self.config
        self.connection = normalize_connection(c.connect)
        c.home.validate()
        if not (isinstance(c.speed, (int, float)) and math.isfinite(c.speed) and c.speed > 0):
            raise ValueError(f"speed must be a positive number, got {c.speed}")
        if not 1 <= c.system_id <= 255:
            raise ValueError(f"system_id must be in 1..255, got {c.system_id}")
        self.params = ParamStore(c.params)
        self.vehicle = Vehicle(self.params, c.area)
        self.streams = StreamScheduler(max_wall_hz=c.max_stream_wall_hz)
        ids = {AUTOPILOT_COMPONENT}
        for p in payloads:
            check_payload(p, ids)
            ids.add(int(p.component_id))
        self._payloads = list(payloads)
        self._slots: list[_Slot] = []
        self.stats: Counter[str] = Counter()
        self.rejects = RejectLog(log)
        self.signing: SigningGuard | None = None
        self._notices: list[str] = []
        self.conn: Any = None
        self.clock: SimClock | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._snapshot = self.vehicle.state()
        self.error: BaseException | None = None

    # --------------------------------------------------------------- lifecycle
    def open(self) -> None:
        """Open the connection (raises OSError when it cannot) and reset the clock."""
        if self.conn is not None:
            return
        c = self.config
        self.conn = mavutil.mavlink_connection(self.connection, source_system=c.system_id,
                                               source_component=AUTOPILOT_COMPONENT)
        self.mav = self.conn.mav
        self.telemetry = TelemetrySender(self.mav, c.home)
        self.commands = CommandHandler(self.vehicle, self.streams, self.telemetry)
        self.param_protocol = ParamProtocol(self.params, self.mav)
        self._slots = [_Slot(p, mavlink.MAVLink(self.conn, srcSystem=c.system_id,
                                                srcComponent=int(p.component_id)))
                       for p in self._payloads]
        if c.signing_key is not None:
            self.signing = SigningGuard(c.signing_key, on_first_reject=self._on_signing_reject)
            for mav in (self.mav, *(slot.mav for slot in self._slots)):
                self.signing.attach(mav)
        self.clock = SimClock(c.speed)
        log.debug("vehicle %d on %s at %gx real time", c.system_id, self.connection, c.speed)

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None

    def start(self) -> SitlServer:
        """Open and run in a daemon thread; returns self."""
        self.open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run_thread, name="sitl_stub", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the loop (thread or :meth:`run`) and close the connection."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
            self._thread = None
        self.close()

    def __enter__(self) -> SitlServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def address(self) -> tuple[str, int]:
        """Local (host, port) of the vehicle's socket: where to send when it listens."""
        if self.conn is None:
            raise RuntimeError("server not open")
        sock = getattr(self.conn, "listen", None) or self.conn.port  # tcpin listens separately
        host, port = sock.getsockname()[:2]
        return str(host), int(port)

    def state(self) -> VehicleState:
        """Latest vehicle snapshot (safe from any thread)."""
        return self._snapshot

    def report(self) -> dict[str, Any]:
        """Counters for logs and tests: signing, rejected input by kind, ACK results, and the
        vehicle's safety monitors (geofence, offboard setpoint age, failsafes)."""
        s = self._snapshot
        acks = {k[4:]: v for k, v in sorted(self.stats.items()) if k.startswith("ack_")}
        payloads = {str(p.component_id): p.summary() for p in self._payloads
                    if callable(getattr(p, "summary", None))}
        return {
            "signing": self.signing.stats() if self.signing else None,
            "payloads": payloads,
            "rejected": self.rejects.as_dict(),
            "acks": acks,
            "vehicle": {
                "time_s": round(s.time_s, 3), "armed": s.armed, "mode": s.mode.px4_name,
                "offboard_failsafes": s.offboard_failsafes,
                "max_offboard_setpoint_age_s": round(s.max_offboard_setpoint_age_s, 3),
                "max_abs_xy_m": round(s.max_abs_xy_m, 3), "fence_m": self.vehicle.fence_m,
                "setpoints_accepted": s.setpoints_accepted,
                "setpoints_clamped": s.setpoints_clamped,
            },
        }

    def run(self, stop: threading.Event | None = None) -> None:
        """Run until ``stop`` (or :meth:`stop`) is set or ``duration_s`` simulated seconds pass."""
        self.open()
        assert self.clock is not None
        stop = stop or self._stop
        duration = self.config.duration_s
        while not stop.is_set() and not self._stop.is_set():
            self.iterate()
            if duration is not None and self.vehicle.t >= duration:
                break
            select.select([self.conn.fd], [], [], LOOP_WAIT_S)  # fd changes on a TCP accept

    def _run_thread(self) -> None:
        try:
            self.run()
        except BaseException as exc:  # reported to the embedding code via .error
            self.error = exc
            log.exception("sitl_stub loop failed")

    # -------------------------------------------------------------- one tick
    def iterate(self) -> None:
        """Handle input, advance simulated time to the wall clock, send what is due."""
        assert self.clock is not None
        wall = self.clock.wall()
        self._receive(wall)
        self._advance_to(self.clock.advance())
        for severity, text in self.vehicle.drain_events():
            log.info("%s", text)
            self.telemetry.statustext(severity, text)
        for text in self._notices:
            self.telemetry.statustext(mavlink.MAV_SEVERITY_WARNING, text)
        self._notices.clear()
        self._send_due(wall)
        self._snapshot = self.vehicle.state()

    def _advance_to(self, target_s: float) -> None:
        v = self.vehicle
        while True:
            for slot in self._slots:
                while slot.next_frame * slot.payload.frame_s <= v.t + 1e-6:
                    self._tick(slot, slot.next_frame * slot.payload.frame_s)
                    slot.next_frame += 1
            next_frame = min((s.next_frame * s.payload.frame_s for s in self._slots),
                             default=math.inf)
            end = min(target_s, next_frame)
            if end <= v.t + 1e-9:
                return
            v.step(end - v.t)

    def _tick(self, slot: _Slot, sim_time_s: float) -> None:
        try:
            slot.payload.on_frame(sim_time_s, self.vehicle.state(), slot.mav)
        except Exception:
            slot.failures += 1
            if slot.failures == 1 or slot.failures % 100 == 0:
                log.exception("payload %d failed in on_frame (%d failures)",
                              slot.payload.component_id, slot.failures)

    def _send_due(self, wall: float) -> None:
        s = self.vehicle.state()
        if self.streams.heartbeat_due(s.time_s, wall):
            self.telemetry.heartbeat(s)
            for slot in self._slots:
                slot.mav.heartbeat_send(*slot.payload.heartbeat())
        for name in self.streams.due(s.time_s, wall):
            self.telemetry.send(name, s)

    # ------------------------------------------------------------------ input
    def _on_signing_reject(self, reason: str, text: str) -> None:
        self._notices.append(f"Signing: rejected {reason} packets")

    def _receive(self, wall: float) -> None:
        if self.signing is not None and not self.signing.is_attached(self.conn.mav):
            raise RuntimeError("pymavlink replaced the signed MAVLink parser; refusing to go on")
        for _ in range(MAX_RX_PER_TICK):
            try:
                msg = self.conn.recv_msg()
            except Exception as exc:  # a parser error robust parsing did not turn into BAD_DATA
                self.rejects.reject("parse_error", f"MAVLink parser error: {exc!r}")
                self.conn.mav.buf, self.conn.mav.buf_index = bytearray(), 0
                continue
            if msg is None:
                # a datagram without a whole message (garbage, a split packet): go on while more
                # are waiting, or garbage would starve the commands queued behind it
                if not select.select([self.conn.fd], [], [], 0)[0]:
                    return
                continue
            kind = msg.get_type()
            rescan_bad_frame(self.conn.mav, msg)
            if not self.rejects.screen(msg):
                if kind == "BAD_DATA":  # signing rejects are counted by reason in self.signing
                    bad_signature = "signature" in str(getattr(msg, "reason", ""))
                    self.stats["signing_rejected" if bad_signature else "bad_data"] += 1
                continue
            self.stats[f"rx_{kind}"] += 1
            try:
                self._dispatch(msg, kind, wall)
            except Exception:
                self._handler_error(f"handling {kind}")
                self.rejects.reject("handler_error", f"failed to handle {kind}", key=f"error_{kind}")

    def _dispatch(self, msg: Any, kind: str, wall: float) -> None:
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._on_command(msg, kind, wall)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            self._on_setpoint(msg)
        elif kind.startswith("PARAM_"):
            if self._for_autopilot(msg):
                refused = self.param_protocol.rejected_sets
                self.param_protocol.handle(msg)
                if self.param_protocol.rejected_sets > refused:
                    name = getattr(msg, "param_id", "?")
                    self.rejects.reject("param_set_refused",
                                        f"PARAM_SET {name}={msg.param_value!r} out of range",
                                        key=f"param_{name}")
        elif kind == "SET_MODE":  # deprecated message: acted on like DO_SET_MODE, no ACK
            if (msg.target_system == self.config.system_id
                    and msg.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED):
                main, sub = decode_custom_mode(msg.custom_mode)
                reply = self.commands.handle(self._request(
                    msg, mavlink.MAV_CMD_DO_SET_MODE, (1.0, main, sub, 0, 0, 0, 0)), wall)
                if reply.reason:
                    self.telemetry.statustext(mavlink.MAV_SEVERITY_WARNING, reply.reason)
        elif kind == "PING":
            if msg.target_system == 0 and msg.target_component == 0:
                self.mav.ping_send(msg.time_usec, msg.seq, msg.get_srcSystem(),
                                   msg.get_srcComponent())
        elif kind == "TIMESYNC":
            if msg.tc1 == 0:
                self.mav.timesync_send(int(self.vehicle.t * 1e9), msg.ts1)
        elif kind == "FILE_TRANSFER_PROTOCOL":
            reply = ftp_reply(msg.payload) if self._for_autopilot(msg) else None
            if reply is not None:
                self.mav.file_transfer_protocol_send(0, msg.get_srcSystem(),
                                                     msg.get_srcComponent(), reply)
        elif kind == "MISSION_REQUEST_LIST" and self._for_autopilot(msg):
            # no mission, fence or rally items (MAVProxy asks on connect)
            self.mav.mission_count_send(msg.get_srcSystem(), msg.get_srcComponent(), 0,
                                        msg.mission_type)

    def _handler_error(self, what: str) -> None:
        """A bug met by some input: counted; the first (and every 100th) traceback is logged."""
        self.stats["handler_errors"] += 1
        n = self.stats["handler_errors"]
        if n == 1 or n % 100 == 0:
            log.error("error while %s (%d so far); the vehicle flies on", what, n, exc_info=True)

    def _for_autopilot(self, msg: Any) -> bool:
        return (getattr(msg, "target_system", 0) in (0, self.config.system_id)
                and getattr(msg, "target_component", 0) in (0, AUTOPILOT_COMPONENT))

    def _on_setpoint(self, m: Any) -> None:
        if not self._for_autopilot(m):
            self.stats["setpoints_ignored"] += 1  # someone else's: not an error
            return
        if m.coordinate_frame != mavlink.MAV_FRAME_LOCAL_NED:
            self.stats["setpoints_ignored"] += 1
            self.rejects.reject("setpoint_frame",
                                f"setpoint in frame {m.coordinate_frame}: only MAV_FRAME_LOCAL_NED (1)",
                                key=f"setpoint_frame_{m.coordinate_frame}")
            return
        if m.type_mask & POSITION_IGNORE_MASK:
            self.stats["setpoints_ignored"] += 1
            self.rejects.reject("setpoint_type_mask",
                                f"setpoint type_mask 0x{m.type_mask:x} ignores position: "
                                "only position setpoints are flown")
            return
        yaw = None if m.type_mask & YAW_IGNORE_BIT else m.yaw
        if not self.vehicle.offer_setpoint(m.x, m.y, m.z, yaw):
            self.stats["setpoints_rejected"] += 1
            self.rejects.reject("setpoint_not_finite",
                                f"setpoint with a NaN/infinite position ({m.x}, {m.y}, {m.z})")

    def _on_command(self, msg: Any, kind: str, wall: float) -> None:
        if msg.target_system not in (0, self.config.system_id):
            return
        slot = next((s for s in self._slots if s.payload.component_id == msg.target_component),
                    None)
        if slot is not None:
            self._payload_command(slot, msg)
            return
        if msg.target_component not in (0, AUTOPILOT_COMPONENT):
            return
        if kind == "COMMAND_LONG":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6,
                      msg.param7)
            req = self._request(msg, msg.command, params, msg.confirmation)
        else:
            params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y),
                      msg.z)
            req = self._request(msg, msg.command, params, 0, msg.frame)
        try:
            reply: CommandReply = self.commands.handle(req, wall)
        except Exception as exc:  # a bug or an input nobody foresaw: answer FAILED, fly on
            self._handler_error(f"command {msg.command}")
            reply = CommandReply(Result.FAILED, f"Command {msg.command} failed: {type(exc).__name__}")
        self.mav.command_ack_send(msg.command, int(reply.result), 0, 0, msg.get_srcSystem(),
                                  msg.get_srcComponent())
        result = Result(reply.result)
        self.stats[f"ack_{result.name.lower()}"] += 1
        if result is Result.UNSUPPORTED:
            self.rejects.reject("command_unsupported", f"unsupported command {msg.command}",
                                key=f"command_unsupported_{msg.command}")
        elif result is not Result.ACCEPTED:
            self.rejects.reject(f"command_{result.name.lower()}",
                                f"command {msg.command}: {result.name} {reply.reason}".rstrip(),
                                key=f"{reply.reason or msg.command}")
        if reply.reason:
            self.telemetry.statustext(mavlink.MAV_SEVERITY_WARNING, reply.reason)
        for follow_up in reply.then:
            follow_up()

    def _payload_command(self, slot: _Slot, msg: Any) -> None:
        handler = getattr(slot.payload, "on_command", None)
        try:
            result = handler(msg, slot.mav) if handler else mavlink.MAV_RESULT_UNSUPPORTED
        except Exception:
            self._handler_error(f"payload {slot.payload.component_id} command {msg.command}")
            self.rejects.reject("command_failed", f"payload {slot.payload.component_id} failed "
                                f"command {msg.command}", key=f"payload_cmd_{msg.command}")
            result = mavlink.MAV_RESULT_FAILED
        if result is not None:
            slot.mav.command_ack_send(msg.command, int(result), 0, 0, msg.get_srcSystem(),
                                      msg.get_srcComponent())

    @staticmethod
    def _request(msg: Any, command: int, params: tuple, confirmation: int = 0,
                 frame: int | None = None) -> CommandRequest:
        return CommandRequest(int(command), tuple(float(p) for p in params), int(confirmation),
                              frame, msg.get_srcSystem(), msg.get_srcComponent())
