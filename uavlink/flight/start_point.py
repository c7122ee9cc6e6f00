"""A flight that took off away from its UAV's start position flies there before the episode starts.

An episode of the env starts with each UAV at its start position (``start_positions_m``: the centre
for one UAV, a fleet's ring), which is the vehicle's spawn point and home; a first flight takes off
there. A later flight takes off where the one before landed (``fly`` lands where the episode
ended), so before entering OFFBOARD (where the episode starts) each vehicle flies to its start at
the flight altitude in Hold, with DO_REPOSITION (PX4's "go to", MAVSDK's ``goto_location``), and
the episode starts where evaluation's does: ``uavlink evaluate`` of the episode replays it.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Iterable, Sequence

from uavlink.flight.fence import local_origin
from uavlink.flight.link import LinkError, VehicleLink, VehicleStatus
from uavlink.mavlink.dialect import mavlink

log = logging.getLogger(__name__)

# Horizontal distance that counts as at the start (DO_REPOSITION's float32 degrees: ~0.5 m)
AT_START_M = 2.0
TRANSIT_VEHICLE_S = 300.0  # vehicle seconds allowed for the transit


def _at_start(st: VehicleStatus, east: float, north: float) -> bool:
    """Whether the vehicle ``st`` reports is within :data:`AT_START_M` of (east, north)."""
    return math.hypot(st.east_m - east, st.north_m - north) <= AT_START_M


def fly_to_starts(links: Sequence[VehicleLink], starts_en_m: Iterable[Sequence[float]]) -> None:
    """Send every vehicle in the air that is further than :data:`AT_START_M` from its start (east,
    north in the local frame) there, then wait until all are within it (LinkError after
    :data:`TRANSIT_VEHICLE_S` of vehicle time)."""
    away = [
        (link, start)
        for link, start in zip(links, starts_en_m, strict=True)
        if link.status.in_air
        and math.hypot(link.status.east_m - start[0], link.status.north_m - start[1]) > AT_START_M
    ]
    for link, (east, north) in away:
        origin = local_origin(link)
        if origin is None:
            raise LinkError("no HOME_POSITION from the vehicle: cannot fly to the episode's start")
        lat, lon = origin.to_global(north, east)
        log.warning(
            "vehicle %s took off %.0f m from its start position: flying there first",
            link.target_system,
            math.hypot(link.status.east_m - east, link.status.north_m - north),
        )
        link.command(
            mavlink.MAV_CMD_DO_REPOSITION,
            -1.0,
            mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
            0.0,
            math.nan,
            lat,
            lon,
            math.nan,
        )
    for link, (east, north) in away:
        link.wait_until(
            functools.partial(_at_start, link.status, east, north),
            TRANSIT_VEHICLE_S,
            "the flight to the episode's start position",
        )
