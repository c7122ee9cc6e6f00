"""Geofence geometry in local metres: inclusion/exclusion polygons and circles (no MAVLink I/O).

PX4's rule (``src/modules/navigator/geofence.cpp``, ``checkPolygons``): a point is allowed when it
lies inside at least one inclusion zone (if there are any) and outside every exclusion zone. A
point on a boundary counts as inside. Zones are built from the FENCE list the mission microservice
stores (MAV_CMD_NAV_FENCE_POLYGON_VERTEX_* 5001/5002 with param1 = vertex count and the vertices
consecutive; MAV_CMD_NAV_FENCE_CIRCLE_* 5003/5004 with param1 = radius), projected to LOCAL_NED
(north, east) through the vehicle's :class:`~sitl_stub.core.geo.GeoOrigin`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import FENCE, MissionItem, MissionStore

POLYGON_INCLUSION = 5001  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
POLYGON_EXCLUSION = 5002
CIRCLE_INCLUSION = 5003
CIRCLE_EXCLUSION = 5004

Point = tuple[float, float]  # (north_m, east_m)


@dataclass(frozen=True)
class Polygon:
    """A simple polygon, vertices (north_m, east_m) in order (either winding)."""

    vertices: tuple[Point, ...]
    inclusion: bool = True

    def contains(self, p: Point) -> bool:
        """Inside or on the boundary (even-odd ray casting along +east)."""
        if self.boundary_distance(p) <= 1e-9:
            return True
        n, e = p
        inside = False
        vs = self.vertices
        for (n1, e1), (n2, e2) in zip(vs, vs[1:] + vs[:1], strict=False):
            if (n1 > n) != (n2 > n):
                e_cross = e1 + (n - n1) * (e2 - e1) / (n2 - n1)
                if e < e_cross:
                    inside = not inside
        return inside

    def boundary_distance(self, p: Point) -> float:
        """Shortest distance from ``p`` to an edge, metres."""
        vs = self.vertices
        return min(_segment_distance(p, a, b) for a, b in zip(vs, vs[1:] + vs[:1], strict=False))


@dataclass(frozen=True)
class Circle:
    """A circle around ``center`` (north_m, east_m)."""

    center: Point
    radius_m: float
    inclusion: bool = True

    def contains(self, p: Point) -> bool:
        return math.dist(p, self.center) <= self.radius_m

    def boundary_distance(self, p: Point) -> float:
        return abs(math.dist(p, self.center) - self.radius_m)


Zone = Polygon | Circle


@dataclass(frozen=True)
class Geofence:
    """The zones of one FENCE list; empty means no fence (everything allowed)."""

    zones: tuple[Zone, ...] = ()

    def allows(self, p: Point) -> bool:
        """PX4's rule: inside some inclusion zone (when any exist), outside every exclusion zone."""
        inclusions = [z for z in self.zones if z.inclusion]
        if inclusions and not any(z.contains(p) for z in inclusions):
            return False
        return not any(
            z.contains(p) and z.boundary_distance(p) > 1e-9 for z in self.zones if not z.inclusion
        )

    def boundary_distance(self, p: Point) -> float:
        """Distance to the nearest zone boundary, metres (inf without zones)."""
        return min((z.boundary_distance(p) for z in self.zones), default=math.inf)

    def last_allowed(self, start: Point, end: Point, iterations: int = 30) -> Point:
        """The point nearest ``end`` on the segment start -> end up to which every sampled point
        is allowed, found by bisection from an allowed ``start`` (``start`` when it is not)."""
        if not self.allows(start):
            return start
        if self.allows(end) and self._segment_allowed(start, end):
            return end
        lo, hi = 0.0, 1.0
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            if self._segment_allowed(start, _lerp(start, end, mid)):
                lo = mid
            else:
                hi = mid
        return _lerp(start, end, lo)

    def _segment_allowed(self, a: Point, b: Point, step_m: float = 1.0) -> bool:
        """Every point sampled every ``step_m`` along a -> b (ends included) is allowed."""
        n = max(1, math.ceil(math.dist(a, b) / step_m))
        return all(self.allows(_lerp(a, b, i / n)) for i in range(n + 1))


def fence_from_items(items: Sequence[MissionItem], origin: GeoOrigin) -> Geofence:
    """The geofence a stored FENCE list describes. Items of other commands, and polygons whose
    vertex run is shorter than its declared count (or under 3), are skipped."""
    zones: list[Zone] = []
    i = 0
    while i < len(items):
        item = items[i]
        if item.command in (CIRCLE_INCLUSION, CIRCLE_EXCLUSION):
            if item.param1 > 0:
                zones.append(
                    Circle(
                        _local(item, origin), float(item.param1), item.command == CIRCLE_INCLUSION
                    )
                )
            i += 1
        elif item.command in (POLYGON_INCLUSION, POLYGON_EXCLUSION):
            count = int(item.param1)
            run = items[i : i + max(count, 1)]
            if count >= 3 and len(run) == count and all(v.command == item.command for v in run):
                zones.append(
                    Polygon(
                        tuple(_local(v, origin) for v in run), item.command == POLYGON_INCLUSION
                    )
                )
                i += count
            else:
                i += 1
        else:
            i += 1
    return Geofence(tuple(zones))


def _local(item: MissionItem, origin: GeoOrigin) -> Point:
    return origin.to_local(*item.lat_lon_deg())


def _lerp(a: Point, b: Point, f: float) -> Point:
    return (a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f)


def _segment_distance(p: Point, a: Point, b: Point) -> float:
    (pn, pe), (an, ae), (bn, be) = p, a, b
    dn, de = bn - an, be - ae
    length2 = dn * dn + de * de
    f = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((pn - an) * dn + (pe - ae) * de) / length2))
    return math.hypot(pn - (an + f * dn), pe - (ae + f * de))


BREACH_TOLERANCE_M = 0.05  # a predicted stop this close outside a boundary is numerical noise


class FenceGuard:
    """The vehicle's live geofence: rebuilt from the store's FENCE list on every upload, checked
    every substep.

    PX4 (navigator_main.cpp, geofence_breach_avoidance.cpp, GF_PREDICT) checks where the vehicle
    would stop when braking now, so it reacts before crossing, and for a multicopter holds at a
    point inside the fence. :attr:`breached` is True while that stopping point is outside.
    """

    def __init__(self, store: MissionStore, origin: GeoOrigin) -> None:
        self.fence = fence_from_items(store.items(FENCE), origin)
        self.breached = False

        def rebuild(mission_type: int) -> None:
            if mission_type == FENCE:
                self.fence = fence_from_items(store.items(FENCE), origin)
                self.breached = False

        store.on_change(rebuild)

    def check(self, pos_ne: Point, stop_ne: Point) -> Point | None:
        """On a new breach (the stopping point just left the fence): the last allowed point on
        the way there, where a multicopter holds. None otherwise."""
        f = self.fence
        bad = (
            bool(f.zones)
            and not f.allows(stop_ne)
            and f.boundary_distance(stop_ne) > BREACH_TOLERANCE_M
        )
        if not bad:
            self.breached = False
            return None
        if self.breached:
            return None
        self.breached = True
        return f.last_allowed(pos_ne, stop_ne)
