"""Geofence geometry (sitl_stub.flight.geofence): polygons, circles, PX4's inclusion/exclusion rule,
the FENCE list parser and the breach predictor, with property tests."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import FENCE, MissionItem, MissionStore
from sitl_stub.flight.geofence import (
    CIRCLE_EXCLUSION,
    CIRCLE_INCLUSION,
    POLYGON_EXCLUSION,
    POLYGON_INCLUSION,
    Circle,
    FenceGuard,
    Geofence,
    Polygon,
    fence_from_items,
)

pytestmark = pytest.mark.timeout(60)

coord = st.floats(-500.0, 500.0, allow_nan=False)
point = st.tuples(coord, coord)


def rectangle(
    n0: float, e0: float, n1: float, e1: float, inclusion: bool = True, clockwise: bool = False
) -> Polygon:
    vs = ((n0, e0), (n0, e1), (n1, e1), (n1, e0))
    return Polygon(vs[::-1] if clockwise else vs, inclusion)


def regular(center: tuple[float, float], radius: float, sides: int) -> Polygon:
    return Polygon(
        tuple(
            (
                center[0] + radius * math.cos(2 * math.pi * k / sides),
                center[1] + radius * math.sin(2 * math.pi * k / sides),
            )
            for k in range(sides)
        )
    )


@given(p=point, a=point, b=point, clockwise=st.booleans())
def test_rectangle_contains_agrees_with_its_bounds(p, a, b, clockwise):
    n0, n1 = sorted((a[0], b[0]))
    e0, e1 = sorted((a[1], b[1]))
    if n1 - n0 < 1e-3 or e1 - e0 < 1e-3:
        return
    rect = rectangle(n0, e0, n1, e1, clockwise=clockwise)
    inside = n0 <= p[0] <= n1 and e0 <= p[1] <= e1
    assert rect.contains(p) == (inside or rect.boundary_distance(p) <= 1e-9)  # boundary: inside


@given(center=point, radius=st.floats(1.0, 300.0), sides=st.integers(3, 12), p=point)
def test_regular_polygon_lies_between_its_inscribed_and_circumscribed_circles(
    center, radius, sides, p
):
    poly = regular(center, radius, sides)
    d = math.dist(p, center)
    if d <= radius * math.cos(math.pi / sides) - 1e-6:
        assert poly.contains(p)
    if d > radius + 1e-6:
        assert not poly.contains(p)


@given(center=point, radius=st.floats(0.5, 300.0), p=point)
def test_circle_contains_and_boundary_distance(center, radius, p):
    c = Circle(center, radius)
    d = math.dist(p, center)
    assert c.contains(p) == (d <= radius)
    assert c.boundary_distance(p) == pytest.approx(abs(d - radius), abs=1e-9)


@given(p=point)
def test_polygon_boundary_distance_of_a_square(p):
    sq = rectangle(-100, -100, 100, 100)
    n, e = p
    if sq.contains(p):
        expected = min(100 - abs(n), 100 - abs(e))
    else:
        expected = math.hypot(max(abs(n) - 100, 0.0), max(abs(e) - 100, 0.0))
    assert sq.boundary_distance(p) == pytest.approx(expected, abs=1e-6)


@given(p=point)
def test_px4_rule_inside_some_inclusion_and_outside_every_exclusion(p):
    inc_a = rectangle(-200, -200, 0, 0)
    inc_b = Circle((100.0, 100.0), 80.0)
    exc = Circle((-100.0, -100.0), 30.0, inclusion=False)
    fence = Geofence((inc_a, inc_b, exc))
    expected = (inc_a.contains(p) or inc_b.contains(p)) and not (
        exc.contains(p) and exc.boundary_distance(p) > 1e-9
    )
    assert fence.allows(p) == expected
    assert Geofence().allows(p)  # no fence: everything allowed
    assert Geofence((exc,)).allows(p) == (not exc.contains(p) or exc.boundary_distance(p) <= 1e-9)


@pytest.mark.slow  # 60 cases: 2.1 s on an idle 2-core machine
@settings(
    max_examples=60, deadline=None
)  # a property, not a speed: it ran 0.2-0.5 s per case on a loaded 2-core machine
@given(end=point)
def test_last_allowed_stops_on_the_boundary_when_the_end_is_outside(end):
    fence = Geofence((rectangle(-100, -100, 100, 100), Circle((50.0, 0.0), 10.0, inclusion=False)))
    start = (0.0, 0.0)
    stop = fence.last_allowed(start, end)
    assert fence.allows(stop)
    # on the segment start -> end
    cross = (end[0] - start[0]) * (stop[1] - start[1]) - (end[1] - start[1]) * (stop[0] - start[0])
    assert abs(cross) <= 1e-6 * max(1.0, math.dist(start, end)) ** 2
    if not fence.allows(end):
        assert fence.boundary_distance(stop) < 1e-3 * max(1.0, math.dist(start, end))


def test_fence_from_items_reads_polygons_and_circles_and_skips_broken_runs():
    origin = GeoOrigin()

    def item(seq: int, cmd: int, n: float, e: float, p1: float) -> MissionItem:
        lat, lon = origin.to_global(n, e)
        return MissionItem(
            seq, 0, cmd, param1=p1, x=round(lat * 1e7), y=round(lon * 1e7), mission_type=FENCE
        )

    items = (
        item(0, POLYGON_INCLUSION, -100, -100, 4),
        item(1, POLYGON_INCLUSION, -100, 100, 4),
        item(2, POLYGON_INCLUSION, 100, 100, 4),
        item(3, POLYGON_INCLUSION, 100, -100, 4),
        item(4, CIRCLE_EXCLUSION, 0, 0, 20),
        item(5, POLYGON_EXCLUSION, 50, 50, 3),
        item(6, POLYGON_EXCLUSION, 60, 50, 3),  # 2 of 3
        item(7, CIRCLE_INCLUSION, 500, 500, 0),  # radius 0: no zone
    )
    fence = fence_from_items(items, origin)
    assert len(fence.zones) == 2
    poly, circle = fence.zones
    assert isinstance(poly, Polygon) and poly.inclusion and len(poly.vertices) == 4
    assert poly.vertices[2] == pytest.approx((100.0, 100.0), abs=0.02)
    assert isinstance(circle, Circle) and not circle.inclusion and circle.radius_m == 20.0
    assert fence.allows((50.0, 0.0)) and not fence.allows((10.0, 0.0))
    assert not fence.allows((150.0, 0.0))


def test_fence_guard_rebuilds_on_upload_and_reports_a_breach_once():
    store = MissionStore()
    guard = FenceGuard(store, GeoOrigin())
    assert guard.check((0.0, 0.0), (500.0, 0.0)) is None  # no fence yet
    home = GeoOrigin()
    store.replace(
        FENCE,
        (
            MissionItem(
                0,
                0,
                CIRCLE_INCLUSION,
                param1=100.0,
                x=round(home.lat_deg * 1e7),
                y=round(home.lon_deg * 1e7),
                mission_type=FENCE,
            ),
        ),
    )
    safe = guard.check((0.0, 0.0), (150.0, 0.0))
    assert safe is not None and guard.breached
    assert safe[0] == pytest.approx(100.0, abs=0.01) and safe[1] == pytest.approx(0.0, abs=1e-6)
    assert guard.check((1.0, 0.0), (151.0, 0.0)) is None and guard.breached  # same breach
    assert guard.check((0.0, 0.0), (100.03, 0.0)) is None and not guard.breached  # within tolerance
    assert guard.check((0.0, 0.0), (150.0, 0.0)) is not None  # a new breach
    store.replace(FENCE, ())
    assert not guard.breached and guard.check((0.0, 0.0), (500.0, 0.0)) is None
