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
from sitl_stub.commands import CommandHandler
from sitl_stub.geo import GeoOrigin
from sitl_stub.message_handler import AUTOPILOT_COMPONENT, MessageHandler
from sitl_stub.param_protocol import ParamProtocol
from sitl_stub.params import ParamStore
from sitl_stub.payload import Payload, PayloadSlot, check_payload
from sitl_stub.streams import StreamScheduler
from sitl_stub.telemetry import TelemetrySender
from sitl_stub.vehicle import Vehicle
from sitl_stub.vehicle_state import VehicleState
from uavlink.config import AreaConfig
from uavlink.mavlink.connection import normalize_connection
from uavlink.mavlink.dialect import mavlink, mavutil
from uavlink.mavlink.rejects import RejectLog
from uavlink.mavlink.signing import SigningGuard

log = logging.getLogger("sitl_stub")

LOOP_WAIT_S = 0.005  # longest wait for input between loop iterations (wall)


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
        self.vehicle = Vehicle(self.params, c.area, origin=c.home)
        self.streams = StreamScheduler(max_wall_hz=c.max_stream_wall_hz)
        ids = {AUTOPILOT_COMPONENT}
        for p in payloads:
            check_payload(p, ids)
            ids.add(int(p.component_id))
        self._payloads = list(payloads)
        self._slots: list[PayloadSlot] = []
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
        self._slots = [PayloadSlot(p, mavlink.MAVLink(self.conn, srcSystem=c.system_id,
                                                srcComponent=int(p.component_id)))
                       for p in self._payloads]
        if c.signing_key is not None:
            self.signing = SigningGuard(c.signing_key, on_first_reject=self._on_signing_reject)
            for mav in (self.mav, *(slot.mav for slot in self._slots)):
                self.signing.attach(mav)
        self.inbox = MessageHandler(c.system_id, self.conn, self.vehicle, self.commands,
                                    self.telemetry, self.param_protocol, self._slots, self.stats,
                                    self.rejects, self.signing)
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
        self.inbox.receive(wall)
        self._advance_to(self.clock.advance())
        for severity, text in self.vehicle.drain_events():
            log.info("%s", text)
            self.telemetry.statustext(severity, text)
        for seq in self.vehicle.mission.drain_reached():
            self.telemetry.mission_item_reached(seq)
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

    def _tick(self, slot: PayloadSlot, sim_time_s: float) -> None:
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
        due = self.streams.due(s.time_s, wall)
        if s.mission_current != self._snapshot.mission_current and "MISSION_CURRENT" not in due:
            due.append("MISSION_CURRENT")  # on change too, as PX4 does
        for name in due:
            self.telemetry.send(name, s)

    # ------------------------------------------------------------------ input
    def _on_signing_reject(self, reason: str, text: str) -> None:
        self._notices.append(f"Signing: rejected {reason} packets")
