"""A fleet of SITL vehicles in one process around one shared radio world (``--fleet D``).

PX4's multi-vehicle SITL (Tools/simulation/sitl_multiple_run.sh: ``$build_path/bin/px4 -i $n``
for n = 0 .. N-1) starts one ``px4 -i N`` per vehicle: instance N is MAVLink system N+1
(ROMFS/px4fmu_common/init.d-posix/rcS: ``param set MAV_SYS_ID $((px4_instance+1))``) with the API
link from 14580+N to 14540+N and the GCS link from 18570+N to 14550 (init.d-posix/px4-rc.mavlink;
:mod:`sitl_stub.mavlink.links`), so a ground station on 14550 hears every system on one port (PX4 guide,
"Multi-Vehicle Simulation with JMAVSim": "all GCS traffic is sent to PX4's remote UDP port: 14550
from all instances"; APIs such as MAVSDK listen on 14540 + instance). Here each vehicle is one :class:`~sitl_stub.mavlink.server.SitlServer` with
exactly those links (instance ``first_instance + i``), and :class:`FleetServer` runs them in
lockstep on one simulated clock: every vehicle steps to each radio frame boundary, the world
advances once with every vehicle's actual position, then each vehicle's radio payload
(:class:`FleetRadioView`, its own component 158 on its own system) publishes its UAV's readings.

Frames and homes: every vehicle's LOCAL_NED origin is the area centre (the env's frame, one origin
for the fleet, so the flight loop and the separation filter compare positions directly); vehicle i
spawns at the fleet's start position i (SPEC: radius ``fleet_start_radius_m``, 360 i / D degrees
from east) and that spawn point is its home: HOME_POSITION carries its latitude/longitude and its
local x/y, and RTL returns there. (PX4 gives each vehicle its own EKF origin at its spawn point;
one shared origin is this simulator's choice, stated in HOME_POSITION's x/y.)

The world's episodes are :mod:`sitl_stub.sim.radio_episodes`' (as the single vehicle's): a new one for
each flight of the team (a vehicle arming while the others are disarmed), started at the first
frame tick that finds every vehicle in OFFBOARD, so no vehicle misses a frame while the others are
still taking off; until then frame 0's readings are repeated, flagged as waiting.
"""

from __future__ import annotations

import logging
import math
import select
import threading
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from sitl_stub.core.modes import FlightMode
from sitl_stub.core.vehicle_state import VehicleState
from sitl_stub.mavlink.server import LOOP_WAIT_S, ServerConfig, SitlServer, step_vehicles
from sitl_stub.sim.background import BackgroundLoop
from sitl_stub.sim.clock import SimClock
from sitl_stub.sim.lockstep import FrameHold
from sitl_stub.sim.radio_episodes import RadioEpisodes
from sitl_stub.sim.radio_payload import HEARTBEAT, publish_frame
from uavlink.config import EnvConfig
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID, encode_readings, encode_score
from uavlink.mobility.fleet import start_positions_m

log = logging.getLogger("sitl_stub.fleet")


def spawn_points_ne(cfg: EnvConfig) -> list[tuple[float, float]]:
    """Each vehicle's spawn point and home (LOCAL_NED north, east): the env's start positions,
    rounded to float32 as a PX4-motion env starts its UAVs (``BatchedUavEnv._as_carried``): a
    flight holds each vehicle at the float32 position it reports until the episode starts, so a
    vehicle spawned between two float32 values would creep by micrometres before frame 0, and a
    lockstep flight would part from its replay in the last bits."""
    xy = start_positions_m(cfg.n_uavs, cfg.fleet_start_radius_m).astype(np.float32)
    return [(float(y), float(x)) for x, y in xy]


class FleetWorld:
    """One radio world with ``cfg.n_uavs`` UAVs; one :class:`FleetRadioView` per vehicle.
    ``truth_origin``: the fleet's LOCAL_NED origin, where the first vehicle's payload places the
    UEs it sends as ADSB_VEHICLE (:mod:`sitl_stub.sim.ue_truth`; once for the fleet); None: not sent."""

    def __init__(
        self,
        cfg: EnvConfig,
        seed: int,
        truth_origin: GeoOrigin | None = None,
        lockstep: bool = False,
    ) -> None:
        self.cfg = cfg
        self.truth_origin = truth_origin
        # Each frame waits for the FRAME_DECIDED of every vehicle in OFFBOARD.
        self.lockstep = lockstep
        self.hold = FrameHold()
        self.frame_s = self.cfg.frame_s
        self.episodes = RadioEpisodes(cfg, seed)
        self.next_frame = 0
        self.score: list[float] | None = None  # this frame's encoded score (None before the start)
        self.views = [FleetRadioView(self, d) for d in range(cfg.n_uavs)]

    def tick(self, states: Sequence[VehicleState]) -> None:
        """One frame with every vehicle's state (:meth:`RadioEpisodes.tick`)."""
        result = self.episodes.tick(states)
        self.score = None if result is None else encode_score(result.rate_bps, result.fair_rate)
        self.next_frame += 1
        if self.lockstep and self.episodes.awaits_decision(
            states
        ):  # each vehicle flying it decides
            self.hold.hold(
                self.episodes.world.frame,
                {i for i, s in enumerate(states) if s.mode is FlightMode.OFFBOARD},
            )

    def summary(self) -> dict[str, Any]:
        lockstep = {"lockstep_timeouts": self.hold.timeouts} if self.lockstep else {}
        return {**self.episodes.summary(), **lockstep}


class FleetRadioView:
    """Vehicle ``uav``'s radio payload: publishes what its UAV's base station senses in the shared
    world (SINR, AoA and its cell's UEs), and the team's score."""

    component_id = RADIO_COMPONENT_ID

    def __init__(self, fleet: FleetWorld, uav: int) -> None:
        self.fleet, self.uav = fleet, uav
        self.frame_s = fleet.frame_s
        self.lockstep = fleet.lockstep

    def on_command(self, msg: Any, mav: Any) -> int | None:
        return self.fleet.hold.on_command(msg, self.uav)

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        return HEARTBEAT

    def on_frame(self, sim_time_s: float, state: VehicleState, mav: Any) -> None:
        episodes = self.fleet.episodes
        r = episodes.world.readings(self.uav)
        publish_frame(
            mav,
            sim_time_s,
            episodes,
            self.fleet.score,
            encode_readings(r.sinr_db, r.aoa_deg, episodes.started, r.serves, self.fleet.lockstep),
            self.fleet.truth_origin if self.uav == 0 else None,
        )  # the UEs once for the fleet

    def summary(self) -> dict[str, Any]:
        return {"uav": self.uav, **self.fleet.summary()}


def fleet_configs(
    base: ServerConfig, n_vehicles: int, homes_ne: Sequence[tuple[float, float]]
) -> list[ServerConfig]:
    """Vehicle i: PX4 instance ``base.instance + i`` (system id + 1), or ``base.connect[i]`` when
    connections are given (exactly one per vehicle), spawning at ``homes_ne[i]``."""
    urls = (
        None
        if base.connect is None
        else ([base.connect] if isinstance(base.connect, str) else list(base.connect))
    )
    if urls is not None and len(urls) != n_vehicles:
        raise ValueError(
            f"--fleet {n_vehicles} with --connect needs {n_vehicles} --connect URLs, "
            f"one per vehicle in order (got {len(urls)}); or drop --connect for PX4's "
            "ports"
        )
    if base.system_id is not None:
        raise ValueError(
            "--system-id does not go with --fleet: vehicle i is system instance + i + 1"
        )
    return [
        replace(
            base,
            instance=base.instance + i,
            connect=None if urls is None else urls[i],
            home_ne=homes_ne[i],
        )
        for i in range(n_vehicles)
    ]


class FleetServer(BackgroundLoop):
    """D :class:`SitlServer` vehicles on one simulated clock, around one :class:`FleetWorld`."""

    thread_name = "sitl_stub_fleet"

    def __init__(self, configs: Sequence[ServerConfig], world: FleetWorld | None) -> None:
        if world is not None and len(world.views) != len(configs):
            raise ValueError("one radio view per vehicle")
        super().__init__()
        self.world = world
        self.servers = [
            SitlServer(c, [world.views[i]] if world else []) for i, c in enumerate(configs)
        ]
        self.speed = configs[0].speed
        self.duration_s = configs[0].duration_s
        self.clock: SimClock | None = None

    @property
    def connection(self) -> str:
        return "; ".join(f"system {s.system_id}: {s.connection}" for s in self.servers)

    def open(self) -> None:
        """Open every vehicle's links (OSError when one cannot be; those opened are closed)."""
        if self.clock is not None:
            return
        try:
            for server in self.servers:
                server.open()
        except OSError:
            self.close()
            raise
        self.clock = SimClock(self.speed)

    def close(self) -> None:
        for server in self.servers:
            server.close()

    def iterate(self) -> None:
        """Every vehicle's input, then simulated time in lockstep, then every vehicle's output."""
        assert self.clock is not None
        wall = self.clock.wall()
        for server in self.servers:
            server.receive(wall)
        if self._advance_to(self.clock.advance()):
            self.clock.sim_s = self.servers[0].vehicle.t  # held: the wait is not made up
        for server in self.servers:
            server.after_step(wall)

    def _advance_to(self, target_s: float) -> bool:
        """Step every vehicle to ``target_s``, ticking the world at its frames; True when the
        world holds time at a frame (lockstep: :mod:`sitl_stub.sim.lockstep`)."""
        vehicles = [s.vehicle for s in self.servers]
        world = self.world
        while True:
            t = vehicles[0].t
            boundary = world.next_frame * world.frame_s if world else math.inf
            if world is not None and boundary <= t + 1e-6:  # no world: boundary is inf
                world.tick([v.state() for v in vehicles])
                for server in self.servers:
                    server.tick_payloads(boundary)
                continue
            if world is not None and world.hold.holding(
                flying=any(v.mode is FlightMode.OFFBOARD for v in vehicles)
            ):
                return True
            if not step_vehicles(
                vehicles, min(target_s, boundary), world is not None and world.lockstep
            ):
                return False

    def run(self, stop: threading.Event | None = None) -> None:
        """Run until ``stop`` is set or ``duration_s`` simulated seconds pass."""
        self.open()
        stop = stop or self._stop
        fds = [link.fd for s in self.servers for link in s.links]
        while not stop.is_set() and not self._stop.is_set():
            self.iterate()
            if self.duration_s is not None and self.servers[0].vehicle.t >= self.duration_s:
                break
            select.select(fds, [], [], LOOP_WAIT_S)

    def report(self) -> dict[str, Any]:
        """Each vehicle's :meth:`SitlServer.report`, and the shared world's episode."""
        return {
            "vehicles": {str(s.system_id): s.report() for s in self.servers},
            "world": self.world.summary() if self.world else None,
        }
