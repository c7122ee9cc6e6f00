"""Separation in transit: the flight loop's guard on what two vehicles sweep between setpoints.

The env's filter (:func:`uavlink.mobility.fleet.separate`) keeps the *setpoints* 20 m apart, as
trained. A vehicle does not jump to its setpoint: it lags it (sitl_stub's and PX4's position
controller closes a P loop at ~1 /s under velocity and acceleration limits, so a 12 m move takes
more than a 1 s frame) and two vehicles moving at once can pass closer between setpoints than at
either end (a crossing or a sideways slide past each other). What a vehicle occupies until its next
setpoint is the path from where it is now (P) to that setpoint; with the inertia of still heading
for its previous setpoint (S) when the new one (S') comes, it sweeps the triangle P, S, S' (the
union of the segments from P to every point of the move S -> S').

:func:`guard_transit` shortens moves, vehicle after vehicle as the env's filter does, so that those
regions keep ``min_separation_m`` apart: vehicle d's triangle against the triangles of the vehicles
already decided and the current paths [P, S] of those after it (each of which then checks against
d's triangle). A new setpoint only shortens the env's move (it stays on S -> S'), so the setpoints
still respect the env's 20 m; a pair already closer than the minimum (the lag of a previous frame)
may only move apart. Vehicles number a handful, so plain Python on the segments suffices.
"""

from __future__ import annotations

import numpy as np

BISECT_STEPS = 21  # a 12 m move to 12 m / 2^21 < 0.01 mm


def _point_segment_m(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    denom = float(ab @ ab)
    u = 0.0 if denom == 0.0 else min(1.0, max(0.0, float((p - a) @ ab) / denom))
    return float(np.hypot(*(a + u * ab - p)))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def segment_distance_m(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> float:
    """Distance between the segments [a, b] and [c, d] (2-vectors, m); 0 where they cross."""
    d1, d2, d3, d4 = _cross(c, d, a), _cross(c, d, b), _cross(a, b, c), _cross(a, b, d)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0.0 not in (d1, d2, d3, d4):
        return 0.0
    return min(
        _point_segment_m(a, c, d),
        _point_segment_m(b, c, d),
        _point_segment_m(c, a, b),
        _point_segment_m(d, a, b),
    )


def guard_transit(
    actual_m: np.ndarray, current_m: np.ndarray, new_m: np.ndarray, min_separation_m: float
) -> np.ndarray:
    """New setpoints (D, 2), each on its vehicle's move ``current_m`` -> ``new_m`` and cut where the
    region it sweeps from ``actual_m`` (see the module) would come within ``min_separation_m`` of
    another vehicle's; where a pair is already closer, that pair may not come closer still."""
    actual = np.asarray(actual_m, dtype=float)
    current = np.asarray(current_m, dtype=float)
    out = np.array(new_m, dtype=float)
    n = len(out)
    for d in range(n):
        regions = [
            [(actual[j], current[j]), (current[j], out[j]), (actual[j], out[j])]
            if j < d
            else [(actual[j], current[j])]
            for j in range(n)
            if j != d
        ]

        # d sweeps the triangle P, S, E(t) (E(t) on S -> S'): its edge P -> S is the same for every t,
        # and the triangle only grows with t, so each gap only shrinks and a bisection finds the cut
        fixed = [
            min(segment_distance_m(actual[d], current[d], a, b) for a, b in region)
            for region in regions
        ]

        def gaps(t: float, regions: list = regions, fixed: list = fixed, d: int = d) -> list[float]:
            end = current[d] + t * (out[d] - current[d])
            return [
                min(
                    f,
                    *(
                        segment_distance_m(p, end, a, b)
                        for p in (actual[d], current[d])
                        for a, b in region
                    ),
                )
                for f, region in zip(fixed, regions, strict=True)
            ]

        # a pair already closer than the minimum keeps at least its present gap (moves apart only)
        need = [min(min_separation_m, g) for g in gaps(0.0)]

        def clear(t: float, need: list = need, gaps=gaps) -> bool:
            return all(g >= n_ - 1e-9 for g, n_ in zip(gaps(t), need, strict=True))

        if not regions or clear(1.0):
            continue
        lo, hi = 0.0, 1.0
        for _ in range(BISECT_STEPS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if clear(mid) else (lo, mid)
        out[d] = current[d] + lo * (out[d] - current[d])
    return out
