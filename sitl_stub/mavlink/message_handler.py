"""What the SITL vehicle does with each MAVLink message it receives.

Commands (COMMAND_LONG/INT, and the deprecated SET_MODE) go to the autopilot's
:class:`~sitl_stub.mavlink.commands.CommandHandler`, or to a payload's ``on_command`` when addressed to its
component, and get exactly one COMMAND_ACK; position setpoints go to the vehicle; the parameter
protocol, PING, TIMESYNC, FTP and mission-list requests are answered. Accepted targets:
target_system 0 or the vehicle's id, target_component 0 (broadcast, what pymavlink ground stations
send) or 1. Whatever is refused (bad bytes, unknown messages, unusable setpoints, refused
parameters, commands and mission-protocol messages) is counted in the server's ``rejects`` and
logged once per kind; a bug met by some input is counted in ``stats["handler_errors"]`` and the
vehicle flies on.
"""

from __future__ import annotations

import logging
import select
from collections import Counter
from collections.abc import Sequence
from typing import Any

from sitl_stub.core.vehicle_state import Result
from sitl_stub.flight.vehicle import Vehicle
from sitl_stub.mavlink.commands import CommandHandler, CommandReply, CommandRequest
from sitl_stub.mavlink.ftp import ftp_reply
from sitl_stub.mavlink.mission_protocol import MissionProtocol
from sitl_stub.mavlink.param_protocol import ParamProtocol
from sitl_stub.mavlink.setpoints import Refusal, read_setpoint
from sitl_stub.mavlink.telemetry import TelemetrySender
from sitl_stub.sim.payload import PayloadSlot
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.frames import GLOBAL_FRAMES, e7_to_deg, height_above_home_m
from uavlink.mavlink.px4_modes import decode_custom_mode
from uavlink.mavlink.rejects import RejectLog, rescan_bad_frame
from uavlink.mavlink.signing import SigningGuard

log = logging.getLogger("sitl_stub")

AUTOPILOT_COMPONENT = 1
_BODY_FRAMES = frozenset({mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_FRD})
MAX_RX_PER_TICK = 2000  # messages/datagrams handled per loop iteration: a flood cannot stall time


class MessageHandler:
    """Reads the vehicle's connection and acts on each message (one per :meth:`receive` loop)."""

    def __init__(
        self,
        system_id: int,
        conn: Any,
        vehicle: Vehicle,
        commands: CommandHandler,
        telemetry: TelemetrySender,
        param_protocol: ParamProtocol,
        slots: Sequence[PayloadSlot],
        stats: Counter[str],
        rejects: RejectLog,
        signing: SigningGuard | None,
    ) -> None:
        self.system_id = system_id
        self.conn = conn
        self.mav = conn.mav
        self.vehicle = vehicle
        self.commands = commands
        self.telemetry = telemetry
        self.param_protocol = param_protocol
        self._slots = slots
        self.stats = stats
        self.rejects = rejects
        self.signing = signing
        self.missions = MissionProtocol(
            vehicle.plans, self.mav, system_id, telemetry.statustext, reject=rejects.reject
        )

    def receive(self, wall: float) -> None:
        """Handle what arrived (at most MAX_RX_PER_TICK messages or datagrams)."""
        if self.signing is not None and not self.signing.is_attached(self.conn.mav):
            raise RuntimeError("pymavlink replaced the signed MAVLink parser; refusing to go on")
        self.missions.tick(wall)
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
                self.rejects.reject(
                    "handler_error", f"failed to handle {kind}", key=f"error_{kind}"
                )

    def _dispatch(self, msg: Any, kind: str, wall: float) -> None:
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            self._on_command(msg, kind, wall)
        elif kind in ("SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT"):
            self._on_setpoint(msg)
        elif kind == "SET_ATTITUDE_TARGET" and self._for_autopilot(msg):
            self.stats["setpoints_ignored"] += 1  # not a stream: OFFBOARD stays refused
            self.rejects.reject(
                "setpoint_attitude",
                "SET_ATTITUDE_TARGET refused: attitude and "
                "rate setpoints are not flown; use SET_POSITION_TARGET_*",
            )
        elif kind.startswith("PARAM_"):
            if self._for_autopilot(msg):
                refused = self.param_protocol.rejected_sets
                self.param_protocol.handle(msg)
                if self.param_protocol.rejected_sets > refused:
                    name = getattr(msg, "param_id", "?")
                    self.rejects.reject(
                        "param_set_refused",
                        f"PARAM_SET {name}={msg.param_value!r} out of range",
                        key=f"param_{name}",
                    )
        elif kind == "SET_MODE":  # deprecated message: acted on like DO_SET_MODE, no ACK
            if (
                msg.target_system == self.system_id
                and msg.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            ):
                main, sub = decode_custom_mode(msg.custom_mode)
                reply = self.commands.handle(
                    self._request(msg, mavlink.MAV_CMD_DO_SET_MODE, (1.0, main, sub, 0, 0, 0, 0)),
                    wall,
                )
                if reply.reason:
                    self.telemetry.statustext(mavlink.MAV_SEVERITY_WARNING, reply.reason)
        elif kind == "PING":
            if msg.target_system == 0 and msg.target_component == 0:
                self.mav.ping_send(
                    msg.time_usec, msg.seq, msg.get_srcSystem(), msg.get_srcComponent()
                )
        elif kind == "TIMESYNC":
            if msg.tc1 == 0:
                self.mav.timesync_send(int(self.vehicle.t * 1e9), msg.ts1)
        elif kind == "FILE_TRANSFER_PROTOCOL":
            ftp = ftp_reply(msg.payload) if self._for_autopilot(msg) else None
            if ftp is not None:
                self.mav.file_transfer_protocol_send(
                    0, msg.get_srcSystem(), msg.get_srcComponent(), ftp
                )
        elif kind.startswith("MISSION_"):
            self.missions.handle(msg, wall)

    def _handler_error(self, what: str) -> None:
        """A bug met by some input: counted; the first (and every 100th) traceback is logged."""
        self.stats["handler_errors"] += 1
        n = self.stats["handler_errors"]
        if n == 1 or n % 100 == 0:
            log.error("error while %s (%d so far); the vehicle flies on", what, n, exc_info=True)

    def _for_autopilot(self, msg: Any) -> bool:
        return getattr(msg, "target_system", 0) in (0, self.system_id) and getattr(
            msg, "target_component", 0
        ) in (0, AUTOPILOT_COMPONENT)

    def _on_setpoint(self, m: Any) -> None:
        """SET_POSITION_TARGET_LOCAL_NED (LOCAL_NED; BODY_NED/BODY_FRD velocities) or
        SET_POSITION_TARGET_GLOBAL_INT (lat/lon; altitude AMSL or above home by frame)."""
        if not self._for_autopilot(m):
            self.stats["setpoints_ignored"] += 1  # someone else's: not an error
            return
        frame = m.coordinate_frame
        body_yaw = None
        if m.get_type() == "SET_POSITION_TARGET_GLOBAL_INT":
            if frame not in GLOBAL_FRAMES:
                return self._refuse_setpoint(
                    Refusal(
                        "setpoint_frame",
                        f"global setpoint in frame {frame}: only MAV_FRAME_GLOBAL"
                        "(_INT), GLOBAL_RELATIVE_ALT(_INT) and GLOBAL_TERRAIN_ALT(_INT)",
                    ),
                    frame,
                )
            position = self._global_to_local(m.lat_int, m.lon_int, m.alt, frame)
        else:
            if frame in _BODY_FRAMES:
                body_yaw = self.vehicle.yaw
            elif frame != mavlink.MAV_FRAME_LOCAL_NED:
                return self._refuse_setpoint(
                    Refusal(
                        "setpoint_frame",
                        f"setpoint in frame {frame}: only MAV_FRAME_LOCAL_NED (1), "
                        "BODY_NED (8) and BODY_FRD (12)",
                    ),
                    frame,
                )
            position = (m.x, m.y, m.z)
        sp = read_setpoint(m.type_mask, position, (m.vx, m.vy, m.vz), m.yaw, m.yaw_rate, body_yaw)
        if isinstance(sp, Refusal):
            return self._refuse_setpoint(sp, frame)
        if not self.vehicle.offer_setpoint(*sp.position_ned, sp.yaw_rad, sp.motion):
            self.stats["setpoints_rejected"] += 1
            self.rejects.reject(
                "setpoint_not_finite", f"setpoint with a NaN/infinite position {position}"
            )

    def _refuse_setpoint(self, refusal: Refusal, frame: int) -> None:
        self.stats["setpoints_ignored"] += 1
        key = f"setpoint_frame_{frame}" if refusal.kind == "setpoint_frame" else None
        self.rejects.reject(refusal.kind, refusal.text, key=key)

    def _global_to_local(
        self, lat_int: int, lon_int: int, alt_m: float, frame: int
    ) -> tuple[float, float, float]:
        """LOCAL_NED of a global setpoint; the world is flat at home, so terrain = home."""
        origin = self.vehicle.origin
        north, east = origin.to_local(e7_to_deg(lat_int), e7_to_deg(lon_int))
        return north, east, -height_above_home_m(alt_m, frame, origin.alt_amsl_m)

    def _on_command(self, msg: Any, kind: str, wall: float) -> None:
        if msg.target_system not in (0, self.system_id):
            return
        slot = next(
            (s for s in self._slots if s.payload.component_id == msg.target_component), None
        )
        if slot is not None:
            self._payload_command(slot, msg)
            return
        if msg.target_component not in (0, AUTOPILOT_COMPONENT):
            return
        if kind == "COMMAND_LONG":
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                msg.param5,
                msg.param6,
                msg.param7,
            )
            req = self._request(msg, msg.command, params, msg.confirmation)
        else:
            params = (
                msg.param1,
                msg.param2,
                msg.param3,
                msg.param4,
                float(msg.x),
                float(msg.y),
                msg.z,
            )
            req = self._request(msg, msg.command, params, 0, msg.frame)
        try:
            reply: CommandReply = self.commands.handle(req, wall)
        except Exception as exc:  # a bug or an input nobody foresaw: answer FAILED, fly on
            self._handler_error(f"command {msg.command}")
            reply = CommandReply(
                Result.FAILED, f"Command {msg.command} failed: {type(exc).__name__}"
            )
        self.mav.command_ack_send(
            msg.command, int(reply.result), 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        result = Result(reply.result)
        self.stats[f"ack_{result.name.lower()}"] += 1
        if result is Result.UNSUPPORTED:
            self.rejects.reject(
                "command_unsupported",
                f"unsupported command {msg.command}",
                key=f"command_unsupported_{msg.command}",
            )
        elif result is not Result.ACCEPTED:
            self.rejects.reject(
                f"command_{result.name.lower()}",
                f"command {msg.command}: {result.name} {reply.reason}".rstrip(),
                key=f"{reply.reason or msg.command}",
            )
        if reply.reason:
            self.telemetry.statustext(mavlink.MAV_SEVERITY_WARNING, reply.reason)
        for follow_up in reply.then:
            follow_up()

    def _payload_command(self, slot: PayloadSlot, msg: Any) -> None:
        handler = getattr(slot.payload, "on_command", None)
        try:
            result = handler(msg, slot.mav) if handler else mavlink.MAV_RESULT_UNSUPPORTED
        except Exception:
            self._handler_error(f"payload {slot.payload.component_id} command {msg.command}")
            self.rejects.reject(
                "command_failed",
                f"payload {slot.payload.component_id} failed command {msg.command}",
                key=f"payload_cmd_{msg.command}",
            )
            result = mavlink.MAV_RESULT_FAILED
        if result is not None:
            slot.mav.command_ack_send(
                msg.command, int(result), 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
            )

    @staticmethod
    def _request(
        msg: Any, command: int, params: tuple, confirmation: int = 0, frame: int | None = None
    ) -> CommandRequest:
        p1, p2, p3, p4, p5, p6, p7 = (float(p) for p in params)  # a command has seven params
        return CommandRequest(
            int(command),
            (p1, p2, p3, p4, p5, p6, p7),
            int(confirmation),
            frame,
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        )
