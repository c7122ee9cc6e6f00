"""Separation in transit: the guard on what two vehicles sweep between setpoints.

The separation filter (:func:`uavlink.mobility.fleet.separate`) keeps the *setpoints* 20 m apart,
as trained. A vehicle does not jump to its setpoint: it lags it (sitl_stub's and PX4's position
controller closes a P loop at ~1 /s under velocity and acceleration limits, so a 12 m move takes
more than a 1 s frame; the env's ``uav_motion="px4"`` flies it the same way) and two vehicles moving
at once can pass closer between setpoints than at either end (a crossing or a sideways slide past
each other). What a vehicle occupies until its next setpoint is the path from where it is now (P)
to that setpoint; with the inertia of still heading for its previous setpoint (S) when the new one
(S') comes, it sweeps the triangle P, S, S' (the union of the segments from P to every point of the
move S -> S').

:func:`guard_transit` shortens moves, vehicle after vehicle as the separation filter does, so that
those regions keep ``min_separation_m`` apart: vehicle d's triangle against the triangles of the
vehicles already decided and the current paths [P, S] of those after it (each of which then checks
against d's triangle). A new setpoint only shortens the filter's move (it stays on S -> S'); a pair
whose regions are already closer than the minimum (the lag of a previous frame: a PX4 vehicle's
path curves out of its triangle when it turns at speed) may only move apart, and the setpoints
themselves are kept the minimum apart all the same (each new one against the others' setpoints).

Batched numpy over envs, (N, D, 2) (a flight is one env, (D, 2)): the flight loop and the env's
``uav_motion="px4"`` fleet call the same code, and every operation is element-wise (products and
sums written out, no reductions whose order could depend on the batch), so an env's row is what a
flight of that env computes, bit for bit.
"""

from __future__ import annotations

import numpy as np

BISECT_STEPS = 21  # a 12 m move to 12 m / 2^21 < 0.01 mm


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


def _point_segment_m(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    denom = _dot(ab, ab)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(denom == 0.0, 0.0, np.clip(_dot(p - a, ab) / denom, 0.0, 1.0))
    gap = a + u[..., None] * ab - p
    return np.hypot(gap[..., 0], gap[..., 1])


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (a[..., 1] - o[..., 1]) * (
        b[..., 0] - o[..., 0]
    )


def segment_distance_m(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Distance between the segments [a, b] and [c, d] (points (..., 2), m, broadcast); 0 where
    they cross."""
    a, b, c, d = (np.asarray(x, dtype=float) for x in (a, b, c, d))
    d1, d2, d3, d4 = _cross(c, d, a), _cross(c, d, b), _cross(a, b, c), _cross(a, b, d)
    crossing = (
        ((d1 > 0) != (d2 > 0))
        & ((d3 > 0) != (d4 > 0))
        & (d1 != 0.0)
        & (d2 != 0.0)
        & (d3 != 0.0)
        & (d4 != 0.0)
    )
    gap = np.minimum(
        np.minimum(_point_segment_m(a, c, d), _point_segment_m(b, c, d)),
        np.minimum(_point_segment_m(c, a, b), _point_segment_m(d, a, b)),
    )
    return np.where(crossing, 0.0, gap)[()]


def guard_transit(
    actual_m: np.ndarray, current_m: np.ndarray, new_m: np.ndarray, min_separation_m: float
) -> np.ndarray:
    """New setpoints (N, D, 2) or (D, 2), each on its vehicle's move ``current_m`` -> ``new_m`` and
    cut where the region it sweeps from ``actual_m`` (see the module) would come within
    ``min_separation_m`` of another vehicle's; where a pair is already closer, that pair may not
    come closer still."""
    one = np.ndim(new_m) == 2
    actual, current, out = (
        np.array(x, dtype=float, ndmin=3) for x in (actual_m, current_m, new_m)
    )  # (N, D, 2)
    n_envs, n = out.shape[:2]
    for d in range(n if n > 1 else 0):  # one vehicle: nothing to keep apart
        # the segments of each other vehicle j: its triangle if decided (j < d), else its path
        regions = [
            [(actual[:, j], current[:, j]), (current[:, j], out[:, j]), (actual[:, j], out[:, j])]
            if j < d
            else [(actual[:, j], current[:, j])]
            for j in range(n)
            if j != d
        ]
        # and each other vehicle's setpoint: its new one if decided, else its current one
        setpoints = np.stack([out[:, j] if j < d else current[:, j] for j in range(n) if j != d])
        sweep = _Sweep(actual[:, d], current[:, d], out[:, d] - current[:, d], regions, setpoints)
        # a pair already closer than the minimum keeps at least its present gap (moves apart only);
        # setpoints the minimum apart (the filter's) stay so
        sweep.need = np.minimum(min_separation_m, sweep.gaps(np.zeros(n_envs)))
        cut = np.flatnonzero(~sweep.clear(np.ones(n_envs)))
        if not len(cut):
            continue
        sweep = sweep.take(cut)  # the bisection, on the envs whose move is cut
        lo, hi = np.zeros(len(cut)), np.ones(len(cut))
        for _ in range(BISECT_STEPS):
            mid = 0.5 * (lo + hi)
            ok = sweep.clear(mid)
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        out[cut, d] = sweep.s + lo[:, None] * sweep.move
    return out[0] if one else out


class _Sweep:
    """Vehicle d's sweep against the others' regions, per env: d sweeps the triangle P, S, E(t)
    (E(t) = S + t (S' - S)); its edge P -> S is the same for every t, and the triangle only grows
    with t, so each gap only shrinks and a bisection on t finds the cut. The others' segments are
    stacked (K, N, 2), ``owner`` (K,) naming the other vehicle (0 .. J-1) each belongs to."""

    def __init__(
        self, p: np.ndarray, s: np.ndarray, move: np.ndarray, regions: list, setpoints: np.ndarray
    ) -> None:
        self.p, self.s, self.move, self.setpoints = p, s, move, setpoints
        self.a = np.stack([a for region in regions for a, _ in region])
        self.b = np.stack([b for region in regions for _, b in region])
        self.owner = np.array([j for j, region in enumerate(regions) for _ in region])
        self.fixed = self._per_other(segment_distance_m(p, s, self.a, self.b))  # (J, N)
        self.need = self.fixed  # set by guard_transit before clear()

    def _per_other(self, gap: np.ndarray) -> np.ndarray:
        """Per other vehicle, the smallest of its segments' gaps (..., K, N) -> (J, N)."""
        return np.stack(
            [gap[..., self.owner == j, :].min(axis=-2) for j in range(self.owner[-1] + 1)]
        )

    def take(self, rows: np.ndarray) -> _Sweep:
        out = object.__new__(_Sweep)
        out.p, out.s, out.move = self.p[rows], self.s[rows], self.move[rows]
        out.setpoints = self.setpoints[:, rows]
        out.a, out.b, out.owner = self.a[:, rows], self.b[:, rows], self.owner
        out.fixed, out.need = self.fixed[:, rows], self.need[:, rows]
        return out

    def gaps(self, t: np.ndarray) -> np.ndarray:
        """(2 J, N): per other vehicle, the gap (m) between its region and d's triangle up to E(t);
        then the distance from E(t) to its setpoint. Where every region keeps the minimum the second
        follows from the first (a setpoint lies in its region, E(t) in d's); where lag has already
        brought two regions closer, it keeps the setpoints the minimum apart all the same (each pair
        is checked at the later one's turn, against the earlier one's final setpoint)."""
        end = self.s + t[:, None] * self.move
        q = np.stack([self.p, self.s])[:, None]  # (2, 1, N, 2): the triangle's other two edges
        swept = segment_distance_m(q, end, self.a, self.b).min(axis=0)  # (K, N)
        apart = end - self.setpoints
        return np.concatenate(
            [np.minimum(self.fixed, self._per_other(swept)), np.hypot(apart[..., 0], apart[..., 1])]
        )

    def clear(self, t: np.ndarray) -> np.ndarray:
        return np.asarray((self.gaps(t) >= self.need - 1e-9).all(axis=0))
