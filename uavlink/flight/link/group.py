"""A fleet's links: several :class:`~uavlink.flight.link.vehicle_link.VehicleLink` polled as one.

Each vehicle of a fleet is its own MAVLink system with its own link state (status, ACKs, offboard
keep-alive). While the loop waits on one vehicle (an ACK, a take-off), every other vehicle's
offboard stream must keep going, or PX4's offboard-loss failsafe (COM_OF_LOSS_T) would put it in
hold: a :class:`LinkGroup` makes any member's ``poll`` serve every member.

Connections: one URL per vehicle (``--connect URL1,URL2``; the embedded fleet; as MAVSDK's
examples/multiple_drones/multiple_drones.cpp adds one connection per instance, ``udp://:14540
udp://:14541``, and takes every system it discovers), or one URL carrying several systems (a GCS
port such as 14550, where PX4 multi-vehicle SITL sends every instance, as MAVProxy listens there
and picks the target with ``vehicle N``, MAVProxy docs "Multiple Vehicles with MAVProxy"; or a
MAVLink router): then the links share one connection, each message read once and handed to every
link (each keeps the state of every system and acts on its own target's). The systems on a shared
URL are taken in ascending system id order (PX4 SITL instance i is MAV_SYS_ID i+1, rcS). A
pymavlink listening socket (``udpin``) sends to every peer it has heard (``mavutil.mavudp.write``),
and each vehicle ignores what is addressed to another system, so commands reach the right vehicle.
"""

from __future__ import annotations

import select
import time
from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

from uavlink.errors import UserError
from uavlink.flight.link.vehicle_link import LinkError, VehicleLink

DISCOVERY_S = 30.0  # wall seconds to hear every system on a shared URL


class LinkGroup:
    """Polls its links together: keep-alives of all, every connection read once."""

    def __init__(self, links: Sequence[VehicleLink]) -> None:
        self.links = list(links)
        for link in self.links:
            link.group = self

    def poll(self, timeout_s: float) -> None:
        now = time.monotonic()
        for link in self.links:
            timeout_s = min(timeout_s, link.keep_alive(now))
        shared: dict[int, list[VehicleLink]] = {}
        for link in self.links:
            shared.setdefault(id(link.conn), []).append(link)
        members = list(shared.values())
        if timeout_s > 0:
            try:
                select.select([m[0].conn.fd for m in members], [], [], timeout_s)
            except (OSError, ValueError):
                time.sleep(timeout_s)
        for owner, *sharing in members:
            owner.drain(sharing)

    def close(self) -> None:
        for link in reversed(self.links):  # the owners of shared connections last
            link.close()


def open_fleet_links(
    urls: Sequence[str], n_vehicles: int, tlog: Path | None, signing_key: bytes | None = None
) -> tuple[LinkGroup, BinaryIO | None]:
    """Links to ``n_vehicles`` vehicles, in UAV order: one per URL, or all on one URL (its systems
    in ascending id order, discovered from their autopilot heartbeats). Returns the group and the
    shared tlog file (the caller closes it after the group)."""
    if len(urls) not in (1, n_vehicles):
        raise UserError(
            f"a fleet of {n_vehicles} takes --connect with {n_vehicles} URLs (one per "
            f"vehicle, comma-separated) or one URL carrying every system; got {len(urls)}"
        )
    tlog_file = open(tlog, "wb") if tlog else None  # noqa: SIM115 - the caller closes it
    if len(urls) == n_vehicles:
        links = [VehicleLink(url, signing_key=signing_key, tlog_file=tlog_file) for url in urls]
        return LinkGroup(links), tlog_file
    owner = VehicleLink(urls[0], signing_key=signing_key, tlog_file=tlog_file)
    deadline = time.monotonic() + DISCOVERY_S
    while (
        len(systems := sorted(s for s, st in owner.systems.items() if st.heartbeats)) < n_vehicles
    ):
        if time.monotonic() > deadline:
            owner.close()
            raise LinkError(
                f"heard {len(systems)} vehicle(s) on {urls[0]} within {DISCOVERY_S:g} s, "
                f"the fleet needs {n_vehicles}"
            )
        owner.poll(0.2)
    owner.target_system = systems[0]
    links = [owner] + [
        VehicleLink(urls[0], target_system=sid, connection=owner.conn, tlog_file=tlog_file)
        for sid in systems[1:n_vehicles]
    ]
    for link in links[1:]:
        link.systems = owner.systems  # what was heard so far is every link's to know
    return LinkGroup(links), tlog_file
