"""AUTO.RTL: where the vehicle returns and its climb / return / land phases (no MAVLink I/O).

PX4 v1.15 ``src/modules/navigator/rtl.cpp`` / ``rtl_params.c``: with RTL_TYPE 0 (the default) the
vehicle returns to the closest safe point, home or a rally point (MAV_CMD_NAV_RALLY_POINT 5100 in
the RALLY list), whichever is nearest to where it is: it climbs to max(current, RTL_RETURN_ALT),
flies there and lands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import MissionItem

NAV_RALLY_POINT = 5100
HOME_NE = (0.0, 0.0)
ALT_ACCEPT_M = 0.5  # climb done within this of the return altitude
XY_ACCEPT_M = 0.5  # return done within this of the destination

Ned = tuple[float, float, float]


def rally_points(items: Sequence[MissionItem], origin: GeoOrigin) -> list[tuple[float, float]]:
    """(north_m, east_m) of every NAV_RALLY_POINT of a stored RALLY list."""
    return [origin.to_local(*i.lat_lon_deg()) for i in items if i.command == NAV_RALLY_POINT]


def return_destination(
    north_m: float,
    east_m: float,
    rally: Sequence[tuple[float, float]],
    home_ne: tuple[float, float] = HOME_NE,
) -> tuple[float, float]:
    """The safe point nearest (north_m, east_m): home or a rally point (home wins a tie)."""
    return min((home_ne, *rally), key=lambda p: math.hypot(p[0] - north_m, p[1] - east_m))


class ReturnPhases:
    """RTL's phase machine: "climb" -> "return" -> "land"; targets are LOCAL_NED."""

    def __init__(self) -> None:
        self.phase = "climb"
        self.alt_m = 0.0
        self.dest_ne = HOME_NE

    def start(
        self, stop_ned: Ned, landed: bool, return_alt_m: float, dest_ne: tuple[float, float]
    ) -> Ned:
        """Begin at the braking point ``stop_ned``; returns the first target. On the ground RTL
        just stays landed (PX4)."""
        self.alt_m = max(-stop_ned[2], return_alt_m)
        self.dest_ne = dest_ne
        n, e, _ = stop_ned
        self.phase = "land" if landed else "climb"
        return (n, e, 1.0) if landed else (n, e, -self.alt_m)  # 1 m below ground: touch down

    def advance(self, pos: Sequence[float]) -> Ned | None:
        """The next target when a phase ends at ``pos``, else None."""
        n, e = self.dest_ne
        if self.phase == "climb" and -pos[2] >= self.alt_m - ALT_ACCEPT_M:
            self.phase = "return"
            return (n, e, -self.alt_m)
        if self.phase == "return" and math.hypot(pos[0] - n, pos[1] - e) < XY_ACCEPT_M:
            self.phase = "land"
            return (n, e, 1.0)
        return None

    @property
    def landing(self) -> bool:
        return self.phase == "land"
