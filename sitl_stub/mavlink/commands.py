"""COMMAND_LONG / COMMAND_INT handling, as PX4 commander and mavlink_receiver answer them.

Every command gets exactly one result (the server turns it into a COMMAND_ACK to the sender);
messages a command asks for are sent after the ACK. State-changing commands retried with
``confirmation > 0`` within :data:`RETRY_WINDOW_S` are answered from a cache without acting
again, so retries are idempotent even when the first ACK was lost.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from sitl_stub.core.modes import MANUAL_MAIN_MODES, FlightMode
from sitl_stub.core.vehicle_state import Outcome, Result
from sitl_stub.flight.vehicle import Vehicle
from sitl_stub.mavlink import guided_commands as guided
from sitl_stub.mavlink.streams import StreamScheduler
from sitl_stub.mavlink.telemetry import TelemetrySender
from uavlink.mavlink.dialect import mavlink

RETRY_WINDOW_S = 3.0  # wall seconds
FORCE_MAGIC = 21196  # COMPONENT_ARM_DISARM param2 that forces (PX4, ArduPilot)
MIN_TAKEOFF_ALT_M = 0.5

_STATE_CHANGING = frozenset(
    {
        mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
        mavlink.MAV_CMD_NAV_TAKEOFF,
        mavlink.MAV_CMD_NAV_LAND,
        mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
        mavlink.MAV_CMD_DO_SET_MODE,
        mavlink.MAV_CMD_MISSION_START,
        mavlink.MAV_CMD_DO_REPOSITION,
        mavlink.MAV_CMD_DO_ORBIT,
        mavlink.MAV_CMD_DO_CHANGE_SPEED,
        mavlink.MAV_CMD_INJECT_FAILURE,
    }
)


@dataclass(frozen=True)
class CommandRequest:
    """A command from COMMAND_LONG (frame None) or COMMAND_INT (params 5/6 as the ints x/y)."""

    command: int
    params: tuple[float, float, float, float, float, float, float]
    confirmation: int = 0
    frame: int | None = None
    src_system: int = 255
    src_component: int = 0


@dataclass
class CommandReply:
    """The MAV_RESULT, a reason when refused, and what to send after the ACK."""

    result: int
    reason: str = ""
    then: list[Callable[[], None]] = field(default_factory=list)


class CommandHandler:
    """Maps MAV_CMDs onto the vehicle and the telemetry streams."""

    def __init__(
        self, vehicle: Vehicle, streams: StreamScheduler, telemetry: TelemetrySender
    ) -> None:
        self.vehicle = vehicle
        self.streams = streams
        self.telemetry = telemetry
        self._recent: dict[tuple, tuple[float, CommandReply]] = {}

    def handle(self, req: CommandRequest, wall_s: float) -> CommandReply:
        key = (req.src_system, req.src_component, req.command, _param_key(req.params))
        if req.command in _STATE_CHANGING:
            cached = self._recent.get(key)
            if req.confirmation > 0 and cached and wall_s - cached[0] <= RETRY_WINDOW_S:
                return CommandReply(cached[1].result, cached[1].reason)
        reply = self._dispatch(req)
        if req.command in _STATE_CHANGING:
            self._recent = {
                k: v for k, v in self._recent.items() if wall_s - v[0] <= RETRY_WINDOW_S
            }
            self._recent[key] = (wall_s, reply)
        return reply

    def _dispatch(self, req: CommandRequest) -> CommandReply:
        c = req.command
        p = req.params
        v = self.vehicle
        if c == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1.0:
                return _reply(v.arm())
            if p[0] == 0.0:
                return _reply(v.disarm(force=p[1] == FORCE_MAGIC))
            return CommandReply(Result.DENIED, "Arming: param1 must be 0 or 1")
        if c == mavlink.MAV_CMD_NAV_TAKEOFF:
            return _reply(v.takeoff(self._takeoff_altitude(req)))
        if c == mavlink.MAV_CMD_NAV_LAND:
            return _reply(v.land())
        if c == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return _reply(v.return_to_launch())
        if c == mavlink.MAV_CMD_DO_SET_MODE:
            return self._set_mode(p)
        if c == mavlink.MAV_CMD_MISSION_START:  # AUTO.MISSION; param1 >= 0: from that item
            first = int(p[0]) if math.isfinite(p[0]) and p[0] >= 0 else None
            return _reply(v.start_mission(first))
        if c == mavlink.MAV_CMD_DO_REPOSITION:
            return _reply(guided.reposition(v, v.origin, p, req.frame))
        if c == mavlink.MAV_CMD_DO_CHANGE_SPEED:
            return _reply(guided.change_speed(v, p))
        if c == mavlink.MAV_CMD_DO_ORBIT:
            return _reply(guided.orbit(v, v.origin, p, req.frame))
        if c == mavlink.MAV_CMD_INJECT_FAILURE:
            return _reply(guided.inject_failure(v, p))
        if c == mavlink.MAV_CMD_REQUEST_MESSAGE:
            name = _message_name(p[0])
            if name is None or not self.telemetry.can_send(name):
                return CommandReply(Result.DENIED)
            return CommandReply(Result.ACCEPTED, then=[self._sender(name)])
        if c == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            return CommandReply(Result.ACCEPTED, then=[self._sender("AUTOPILOT_VERSION")])
        if c == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            name = _message_name(p[0])
            if name is None or not self.streams.set_interval(name, p[1]):
                return CommandReply(Result.DENIED)
            return CommandReply(Result.ACCEPTED)
        if c == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            name = _message_name(p[0])
            if name is None or name not in self.streams:
                return CommandReply(Result.DENIED)
            msg_id, interval = int(p[0]), self.streams.interval_us(name)
            return CommandReply(
                Result.ACCEPTED,
                then=[lambda: self.telemetry.mav.message_interval_send(msg_id, interval)],
            )
        return CommandReply(Result.UNSUPPORTED)

    def _sender(self, name: str) -> Callable[[], None]:
        return lambda: self.telemetry.send(name, self.vehicle.state())

    def _set_mode(self, p: tuple[float, ...]) -> CommandReply:
        if not all(math.isfinite(x) for x in p[:3]):
            return CommandReply(Result.DENIED, "Mode change denied: invalid mode")
        if not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return CommandReply(Result.DENIED, "Mode change denied: only PX4 custom modes")
        main, sub = int(p[1]), int(p[2])
        if main in MANUAL_MAIN_MODES:
            return CommandReply(
                Result.TEMPORARILY_REJECTED, "Mode change denied: no manual control (RC)"
            )
        mode = FlightMode.from_main_sub(main, sub)
        if mode is None:
            return CommandReply(Result.DENIED, f"Mode change denied: mode {main}.{sub} unsupported")
        return _reply(self.vehicle.set_mode(mode))

    def _takeoff_altitude(self, req: CommandRequest) -> float | None:
        """Height above home from NAV_TAKEOFF param7, or None for MIS_TAKEOFF_ALT.

        PX4 reads param7 as AMSL (COMMAND_LONG, global frames); relative-altitude frames give a
        height, MAV_FRAME_LOCAL_NED a down coordinate. NaN, or a height under 0.5 m, means
        MIS_TAKEOFF_ALT (PX4: "using minimum takeoff altitude").
        """
        alt = guided.height_m(req.params[6], req.frame, self.vehicle.origin)
        return alt if alt is not None and alt >= MIN_TAKEOFF_ALT_M else None


def _reply(outcome: Outcome) -> CommandReply:
    return CommandReply(int(outcome.result), outcome.reason)


def _message_name(msg_id: float) -> str | None:
    if not math.isfinite(msg_id) or msg_id != int(msg_id) or msg_id < 0:
        return None
    cls = mavlink.mavlink_map.get(int(msg_id))
    return None if cls is None else cls.msgname


def _param_key(params: tuple[float, ...]) -> tuple:
    return tuple("nan" if math.isnan(x) else x for x in params)
