"""The SITL vehicle's MAVLink 2 endpoint: system 1, autopilot component 1, plus payload components.

It talks on one or more links (:mod:`sitl_stub.mavlink.links`): by default PX4 SITL instance
``ServerConfig.instance``'s API link (from 14580+N to 127.0.0.1:14540+N) and GCS link (from
18570+N to 127.0.0.1:14550), or the connections in ``ServerConfig.connect``. Every link gets all
telemetry; replies go back on the link the request came on; signing covers every link.

One thread does everything: it advances simulated time (:class:`~sitl_stub.sim.clock.SimClock`),
steps the :class:`~sitl_stub.flight.vehicle.Vehicle` (stopping at payload frame boundaries to tick the
payloads, and staying there while a lockstep payload holds time: :mod:`sitl_stub.sim.lockstep`),
handles incoming messages and sends the telemetry that is due. Use it blocking
(:meth:`SitlServer.run`, as ``python -m sitl_stub`` does) or in the background
(:meth:`SitlServer.start` / :meth:`SitlServer.stop`, or ``with SitlServer(...)``), e.g. listening
on ``udpin:127.0.0.1:0`` and reading the chosen port from :attr:`SitlServer.address` (the first
link's).

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

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.params import ParamStore
from sitl_stub.core.vehicle_state import VehicleState
from sitl_stub.flight.vehicle import SUBSTEP_S, Vehicle
from sitl_stub.mavlink.commands import CommandHandler
from sitl_stub.mavlink.links import (
    Fanout,
    Link,
    LinkSpec,
    Route,
    connect_links,
    open_links,
    px4_links,
)
from sitl_stub.mavlink.message_handler import AUTOPILOT_COMPONENT, MessageHandler
from sitl_stub.mavlink.param_protocol import ParamProtocol
from sitl_stub.mavlink.streams import StreamScheduler
from sitl_stub.mavlink.telemetry import TelemetrySender
from sitl_stub.sim.background import BackgroundLoop
from sitl_stub.sim.battery import Battery
from sitl_stub.sim.clock import SimClock
from sitl_stub.sim.payload import Payload, PayloadSlot, check_payload
from uavlink.config import AreaConfig
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.rejects import RejectLog
from uavlink.mavlink.signing import SigningGuard

log = logging.getLogger("sitl_stub")

LOOP_WAIT_S = 0.005  # longest wait for input between loop iterations (wall)


@dataclass(frozen=True)
class ServerConfig:
    """How to run the vehicle. ``connect``: one connection string or several (one link each);
    None means PX4 SITL instance ``instance``'s API and GCS links. ``system_id`` defaults to
    ``instance + 1`` (PX4's MAV_SYS_ID in SITL: ROMFS/px4fmu_common/init.d-posix/rcS,
    ``param set MAV_SYS_ID $((px4_instance+1))``). ``speed`` is simulated seconds per wall second;
    ``duration_s`` (simulated) ends :meth:`SitlServer.run`; ``params`` overrides parameter
    defaults."""

    connect: str | Sequence[str] | None = None
    instance: int = 0
    speed: float = 1.0
    home: GeoOrigin = field(default_factory=GeoOrigin)
    area: AreaConfig = field(default_factory=AreaConfig)
    params: Mapping[str, float] = field(default_factory=dict)
    system_id: int | None = None
    duration_s: float | None = None
    max_stream_wall_hz: float = 50.0
    home_ne: tuple[float, float] = (0.0, 0.0)  # spawn point = home, LOCAL_NED (a fleet's vehicles)
    signing_key: bytes | None = field(default=None, repr=False)

    def link_specs(self) -> tuple[LinkSpec, ...]:
        """The links to open (ValueError for a bad connection string or instance)."""
        if self.connect is None:
            return px4_links(self.instance)
        urls = [self.connect] if isinstance(self.connect, str) else list(self.connect)
        if not urls:
            raise ValueError("connect: give at least one connection, or None for PX4's ports")
        return connect_links(urls)

    @property
    def vehicle_id(self) -> int:
        """The MAVLink system id: ``system_id``, else ``instance + 1``."""
        return self.instance + 1 if self.system_id is None else self.system_id

    def validate(self) -> ServerConfig:
        """``self``, or a ValueError saying what is wrong (the CLI prints it as one line)."""
        self.link_specs()
        self.home.validate()
        if not (
            isinstance(self.speed, (int, float)) and math.isfinite(self.speed) and self.speed > 0
        ):
            raise ValueError(f"speed must be a positive number, got {self.speed}")
        if not 1 <= self.vehicle_id <= 255:
            raise ValueError(f"system_id must be in 1..255, got {self.vehicle_id}")
        return self


class SitlServer(BackgroundLoop):
    """A PX4-style SITL multicopter speaking MAVLink 2 on one or more links."""

    def __init__(
        self, config: ServerConfig | None = None, payloads: Sequence[Payload] = ()
    ) -> None:
        super().__init__()
        self.config = c = (config or ServerConfig()).validate()
        self.link_specs = c.link_specs()
        self.connection = ", ".join(spec.describe() for spec in self.link_specs)
        self.system_id = c.vehicle_id
        self.params = ParamStore(c.params)
        self.battery = Battery(self.params)
        self.vehicle = Vehicle(self.params, c.area, origin=c.home, home_ne=c.home_ne)
        self.streams = StreamScheduler(max_wall_hz=c.max_stream_wall_hz)
        ids = {AUTOPILOT_COMPONENT}
        for p in payloads:
            check_payload(p, ids)
            ids.add(int(p.component_id))
        self._payloads = list(payloads)
        self._lockstep = any(getattr(p, "lockstep", False) for p in payloads)
        if self._lockstep and any(
            abs(p.frame_s / SUBSTEP_S - round(p.frame_s / SUBSTEP_S)) > 1e-9 for p in payloads
        ):
            raise ValueError(
                f"lockstep needs payload frames in whole {SUBSTEP_S * 1e3:g} ms substeps"
            )
        self._slots: list[PayloadSlot] = []
        self.stats: Counter[str] = Counter()
        self.rejects = RejectLog(log)
        self.signing: SigningGuard | None = None
        self._notices: list[str] = []
        self.links: list[Link] = []
        self.route = Route()
        self.clock: SimClock | None = None
        self._snapshot = self.vehicle.state()

    # --------------------------------------------------------------- lifecycle
    def open(self) -> None:
        """Open every link (raises OSError when one cannot be) and reset the clock.

        ``self.mav`` (and each payload slot's ``mav``) sends on the links :attr:`route` picks:
        every link, or the one whose input is being handled, so replies go back where the request
        came from. Each link's encoders sign with the link's index as MAVLink link id."""
        if self.links:
            return
        c = self.config
        self.links = open_links(self.link_specs, self.system_id, AUTOPILOT_COMPONENT)
        encoders = [
            [link.mav, *(link.encoder(int(p.component_id)) for p in self._payloads)]
            for link in self.links
        ]
        if c.signing_key is not None:
            self.signing = SigningGuard(c.signing_key, on_first_reject=self._on_signing_reject)
            for link, mavs in zip(self.links, encoders, strict=True):
                for mav in mavs:
                    self.signing.attach(mav).signing.link_id = link.index
        per_component = list(zip(*encoders, strict=True))  # [autopilot encoders, payload 1's, ...]
        self.mav = Fanout(per_component[0], self.route)
        # home is the vehicle's (PX4's commander owns it); telemetry encodes positions against it
        self.telemetry = TelemetrySender(
            self.mav, self.vehicle.origin, self.battery, self.mav.everyone(), c.home_ne
        )
        self.commands = CommandHandler(self.vehicle, self.streams, self.telemetry)
        self.param_protocol = ParamProtocol(self.params, self.mav)
        self._slots = [
            PayloadSlot(p, Fanout(mavs, self.route))
            for p, mavs in zip(self._payloads, per_component[1:], strict=True)
        ]
        self.inboxes = [
            MessageHandler(
                self.system_id,
                link.conn,
                self.vehicle,
                self.commands,
                self.telemetry,
                self.param_protocol,
                self._slots,
                self.stats,
                self.rejects,
                self.signing,
            )
            for link in self.links
        ]
        self.clock = SimClock(c.speed)
        log.debug("vehicle %d on %s at %gx real time", self.system_id, self.connection, c.speed)

    def close(self) -> None:
        for link in self.links:
            link.close()
        self.links = []

    @property
    def conn(self) -> Any:
        """The first link's pymavlink connection (the only one with a single ``connect``), or
        None when closed."""
        return self.links[0].conn if self.links else None

    @property
    def address(self) -> tuple[str, int]:
        """Local (host, port) of the first link's socket: where to send when it listens."""
        if not self.links:
            raise RuntimeError("server not open")
        return self.links[0].address()

    def state(self) -> VehicleState:
        """Latest vehicle snapshot (safe from any thread)."""
        return self._snapshot

    def report(self) -> dict[str, Any]:
        """Counters for logs and tests: the links, signing, rejected input by kind, ACK results,
        and the vehicle's safety monitors (geofence, offboard setpoint age, failsafes, battery)."""
        s = self._snapshot
        acks = {k[4:]: v for k, v in sorted(self.stats.items()) if k.startswith("ack_")}
        payloads = {  # summary() is optional (the payload hook's contract)
            str(p.component_id): summary()
            for p in self._payloads
            if callable(summary := getattr(p, "summary", None))
        }
        return {
            "links": [spec.describe() for spec in self.link_specs],
            "signing": self.signing.stats() if self.signing else None,
            "payloads": payloads,
            "rejected": self.rejects.as_dict(),
            "acks": acks,
            "vehicle": {
                "time_s": round(s.time_s, 3),
                "armed": s.armed,
                "mode": s.mode.px4_name,
                "offboard_failsafes": s.offboard_failsafes,
                "max_offboard_setpoint_age_s": round(s.max_offboard_setpoint_age_s, 3),
                "max_abs_xy_m": round(s.max_abs_xy_m, 3),
                "fence_m": self.vehicle.fence_m,
                "setpoints_accepted": s.setpoints_accepted,
                "setpoints_clamped": s.setpoints_clamped,
                "battery_pct": round(self.battery.reading().remaining_pct, 1),
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
            select.select([link.fd for link in self.links], [], [], LOOP_WAIT_S)

    # -------------------------------------------------------------- one tick
    def iterate(self) -> None:
        """Handle input, advance simulated time to the wall clock, send what is due."""
        assert self.clock is not None
        wall = self.clock.wall()
        self.receive(wall)
        if self._advance_to(self.clock.advance()):
            self.clock.sim_s = self.vehicle.t  # held: the wall time spent waiting is not made up
        self.after_step(wall)

    def receive(self, wall: float) -> None:
        """Handle the input of every link (the first phase of :meth:`iterate`)."""
        for link, inbox in zip(self.links, self.inboxes, strict=True):
            with self.route.answering_link(link.index):
                inbox.receive(wall)

    def after_step(self, wall: float) -> None:
        """Events, battery and the telemetry that is due, once simulated time has advanced (the
        last phase of :meth:`iterate`; a fleet steps its vehicles in lockstep in between)."""
        self.battery.update(self.vehicle.t, self.vehicle.armed)
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

    def _advance_to(self, target_s: float) -> bool:
        """Step the vehicle to ``target_s``, stopping at payload frames to tick them; True when a
        payload holds time at its frame (lockstep). In lockstep the vehicle moves in whole
        integration substeps, so its path does not depend on how wall time fell into steps."""
        v = self.vehicle
        while True:
            for slot in self._slots:
                while slot.next_frame * slot.payload.frame_s <= v.t + 1e-6:
                    self._tick(slot, slot.next_frame * slot.payload.frame_s)
                    slot.next_frame += 1
            if self._lockstep and _holds_clock(self._slots, v.state()):
                return True
            next_frame = min(
                (s.next_frame * s.payload.frame_s for s in self._slots), default=math.inf
            )
            if not step_vehicles([v], min(target_s, next_frame), self._lockstep):
                return False

    def tick_payloads(self, sim_time_s: float) -> None:
        """Every payload's frame at ``sim_time_s``, whatever their own clocks say: for a fleet, whose
        shared world clocks every vehicle's radio view (``sitl_stub.fleet``)."""
        for slot in self._slots:
            self._tick(slot, sim_time_s)

    def _tick(self, slot: PayloadSlot, sim_time_s: float) -> None:
        state = self.vehicle.state()
        if getattr(slot.payload, "lockstep", False):
            # the position at this very instant, before the frame's readings: what the flight
            # computer decides with, as the env's step does
            self.telemetry.send("LOCAL_POSITION_NED", state)
        try:
            slot.payload.on_frame(sim_time_s, state, slot.mav)
        except Exception:
            slot.failures += 1
            if slot.failures == 1 or slot.failures % 100 == 0:
                log.exception(
                    "payload %d failed in on_frame (%d failures)",
                    slot.payload.component_id,
                    slot.failures,
                )

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


def step_vehicles(vehicles: Sequence[Vehicle], end_s: float, whole_substeps: bool) -> bool:
    """Step every vehicle (all at the same time) to ``end_s``, or with ``whole_substeps`` to the
    last 20 ms substep boundary before it; False when there is nothing to step."""
    t = vehicles[0].t
    if not whole_substeps:
        if end_s <= t + 1e-9:
            return False
        for v in vehicles:
            v.step(end_s - v.t)
        return True
    substeps = math.floor(end_s / SUBSTEP_S + 1e-6) - round(t / SUBSTEP_S)
    for _ in range(substeps):
        for v in vehicles:
            v.step(SUBSTEP_S)
    return substeps > 0


def _holds_clock(slots: Sequence[PayloadSlot], state: VehicleState) -> bool:
    """Whether a lockstep payload holds time at its frame (its optional ``holds_clock``)."""
    for slot in slots:
        if not getattr(slot.payload, "lockstep", False):
            continue
        holds_clock = getattr(slot.payload, "holds_clock", None)  # optional: not in the Protocol
        if holds_clock and holds_clock(state):
            return True
    return False
