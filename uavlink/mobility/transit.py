"""Separation in transit: the guard on where two vehicles fly between setpoints.

The separation filter (:func:`uavlink.mobility.fleet.separate`) keeps the *setpoints* 20 m apart,
as trained. A vehicle does not jump to its setpoint: PX4's position loop (and sitl_stub's, and the
env's ``uav_motion="px4"``: :class:`~uavlink.mobility.uav_motion.PositionLoop`) flies it there
under speed and acceleration limits, so a 12 m move takes more than a 1 s frame, and a vehicle
already moving carries on along its velocity while it turns. Two vehicles moving at once can pass
closer between setpoints than at either end (a crossing, a slide past each other, a turn at speed).

:func:`guard_transit` predicts: it flies every vehicle's position loop ahead from where it is and
how fast it moves (:data:`HORIZON_S`, in the loop's own 20 ms substeps) and shortens moves, vehicle
after vehicle as the separation filter does, so that each pair's predicted paths keep
``min_separation_m`` (plus an optional margin) apart at every substep. Vehicle d tries the points
E(t) = S + t (S' - S) of its filtered move (t on a grid of :data:`GRID` steps) against the decided
vehicles' (j < d) paths to their new setpoints and the others' paths to their current ones, and
keeps the largest t that passes (each later vehicle is then checked against d's chosen path, so
every pair's final paths are). Keeping S (t = 0) continues the previous frame's checked
prediction, so it passes unless the previous frame's horizon ran out or the vehicles did not fly
as predicted (a free-running flight predicts from telemetry flown on for its estimated age); then
a pair may not come closer than keeping S would bring it. New setpoints also keep the minimum from
the others' setpoints.

Before this guard predicted, it kept the regions the vehicles sweep (the triangle of P, S and S')
apart; a turning vehicle's path leaves that triangle by metres, and a free-running fleet of three
flew to 17.2 m with its setpoints 20 m apart (``tests/test_fleet_transit.py`` drives 24 fleets at
one point: 10.7-18.7 m at some 20 ms substep with the triangles, 20.0 m predicted).

Batched numpy over envs, (N, D, 2) (a flight is one env, (D, 2)): the flight loop and the env's
``uav_motion="px4"`` fleet call the same code, and every operation is element-wise or an exact
minimum, so an env's row is what a flight of that env computes, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from uavlink.mobility.uav_motion import PX4_MOTION, PositionLoop

HORIZON_S = 6.0  # how far ahead paths are predicted (4 s left pairs 0.1 m short at D = 4)
GRID = 32  # a move is cut to a multiple of 1/GRID of itself (12 m: 0.375 m steps)
# up to this many envs with a cut move search their grid one move at a time, longest first, in the
# position loop's float kernel (a flight: a few ms where the move is cut little); more fly the
# whole grid at once in numpy
SCAN_MAX_ENVS = 4


def guard_transit(
    actual_m: np.ndarray,
    current_m: np.ndarray,
    new_m: np.ndarray,
    min_separation_m: float,
    velocity_mps: np.ndarray | None = None,
    fence_m: float = math.inf,
    margin_m: float = 0.0,
    loop: PositionLoop = PX4_MOTION,
) -> np.ndarray:
    """New setpoints (N, D, 2) or (D, 2), each on its vehicle's move ``current_m`` -> ``new_m``,
    cut where the vehicles flown by ``loop`` from ``actual_m`` at ``velocity_mps`` (None: at rest)
    inside the fence ``fence_m`` would come within ``min_separation_m`` (+ ``margin_m``: what the
    prediction may miss) of each other (see the module)."""
    one = np.ndim(new_m) == 2
    actual, current, out = (
        np.array(x, dtype=float, ndmin=3) for x in (actual_m, current_m, new_m)
    )  # (N, D, 2)
    velocity = (
        np.zeros_like(actual)
        if velocity_mps is None
        else np.array(velocity_mps, dtype=float, ndmin=3).reshape(actual.shape)
    )
    n = out.shape[1]
    if n < 2:
        return out[0] if one else out
    steps = round(HORIZON_S / loop.substep_s)
    # every vehicle's path to its current setpoint (kept until it is decided) and to its new one
    paths, whole = loop.path(actual, velocity, np.stack([current, out]), steps, fence_m).swapaxes(
        0, 1
    )
    for d in range(n):
        others = [j for j in range(n) if j != d]
        setpoints = np.stack([out[:, j] if j < d else current[:, j] for j in others], axis=1)
        held = _Try(paths[:, :, d], current[:, d], paths[:, :, others], setpoints)
        need = (
            np.minimum(min_separation_m + margin_m, held.closest),
            np.minimum(min_separation_m, held.spacing),
        )
        cut = np.flatnonzero(
            ~_Try(whole[:, :, d], out[:, d], paths[:, :, others], setpoints).meets(*need)
        )
        if 0 < len(cut) <= SCAN_MAX_ENVS:  # a flight: the grid's longest moves first, one by one
            for e in cut:
                out[e, d], whole[:, e, d] = _longest_passing_move(
                    loop,
                    (actual[e, d], velocity[e, d], current[e, d], out[e, d]),
                    (paths[:, e, others], setpoints[e]),
                    (need[0][e], need[1][e]),
                    steps,
                    fence_m,
                )
        elif len(cut):  # the grid of shorter moves, on the envs whose whole move does not pass
            t = (np.arange(GRID + 1) / GRID)[:, None, None]
            tries = current[None, cut, d] + t * (out[None, cut, d] - current[None, cut, d])
            tried = loop.path(actual[None, cut, d], velocity[None, cut, d], tries, steps, fence_m)
            grid = _Try(
                tried, tries, paths[:, None][:, :, cut][:, :, :, others], setpoints[None, cut]
            )
            ok = grid.meets(need[0][cut], need[1][cut])  # (G, cut): t = 0 always passes
            best = np.where(ok, np.arange(GRID + 1)[:, None], 0).max(axis=0)
            out[cut, d] = tries[best, np.arange(len(cut))]
            whole[:, cut, d] = tried[:, best, np.arange(len(cut))]
        paths[:, :, d] = whole[:, :, d]
    return out[0] if one else out


def _longest_passing_move(
    loop: PositionLoop,
    vehicle: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    others: tuple[np.ndarray, np.ndarray],
    need: tuple[np.ndarray, np.ndarray],
    steps: int,
    fence_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One env's vehicle: the longest move of the grid that passes, and its path, found from the
    longest down (the grid's answer and bits, without flying the 33 moves when one of the first
    passes). ``vehicle``: its position, velocity, current and new setpoint (2,); ``others``: the
    others' paths (T, J, 2) and setpoints (J, 2); ``need``: the closest approach and spacing (J,)."""
    actual, velocity, current, new = vehicle
    t = np.arange(GRID + 1) / GRID
    for g in range(GRID, -1, -1):
        point = current + t[g] * (new - current)
        path = loop.path(actual, velocity, point, steps, fence_m)
        if g == 0 or _Try(path, point, *others).meets(*need):  # t = 0 always passes
            break
    return point, path


class _Try:
    """One vehicle's predicted path (T, ..., 2) to its setpoint (..., 2) against the others' paths
    (T, ..., J, 2) and setpoints (..., J, 2): the pairs' closest approach and spacing (..., J)."""

    def __init__(
        self, path: np.ndarray, setpoint: np.ndarray, others: np.ndarray, setpoints: np.ndarray
    ) -> None:
        gap = path[..., None, :] - others
        self.closest = np.hypot(gap[..., 0], gap[..., 1]).min(axis=0)
        apart = setpoint[..., None, :] - setpoints
        self.spacing = np.hypot(apart[..., 0], apart[..., 1])

    def meets(self, closest: np.ndarray, spacing: np.ndarray) -> np.ndarray:
        """Whether every pair keeps at least ``closest`` and ``spacing`` (..., J) -> (...)."""
        return ((self.closest >= closest - 1e-9) & (self.spacing >= spacing - 1e-9)).all(axis=-1)
