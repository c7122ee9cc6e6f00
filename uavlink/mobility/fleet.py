"""Where a fleet's UAVs start and how they are kept apart (SPEC "A fleet").

Pure numpy over batches: positions (N, D, 2) in metres, x east, y north. The separation filter is
the one piece of code that keeps two UAVs at least ``min_separation_m`` apart horizontally; the env,
the genie's replays and the flight loop move UAVs through ``apply_moves``, so what was trained is
what flies. Vehicles that lag their setpoints (the env's ``uav_motion="px4"``, a flight) move
their setpoints through :func:`next_setpoints`, which adds the transit guard
(:mod:`uavlink.mobility.transit`); the env and ``uavlink fly`` call the same function.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from uavlink.mobility.transit import guard_transit

if TYPE_CHECKING:
    from uavlink.config import EnvConfig

# A move is cut this much short of the point where it would touch another UAV's disk, so that
# rounding can never leave two UAVs a hair closer than the minimum.
_MARGIN = 1e-9


def start_positions_m(n_uavs: int, radius_m: float) -> np.ndarray:
    """(D, 2) start (and ``static``) positions: UAV d at ``radius_m``, 360 d / D degrees from east;
    one UAV starts at the centre."""
    if n_uavs == 1:
        return np.zeros((1, 2))
    angle = 2.0 * np.pi * np.arange(n_uavs) / n_uavs
    return radius_m * np.stack([np.cos(angle), np.sin(angle)], axis=1)


def separate(current_m: np.ndarray, target_m: np.ndarray, min_separation_m: float) -> np.ndarray:
    """Targets (N, D, 2) with each move shortened so that no two UAVs end closer than
    ``min_separation_m``, given current positions (N, D, 2) that respect it.

    Deterministic and sequential, UAV 0 first: UAV d's straight move stops where it would first
    enter the disk of radius ``min_separation_m`` around any other UAV, taking UAVs before d at their
    new positions and UAVs after d at their current ones (each of those then checks against d's new
    position), so the result respects the minimum whatever the targets. A move that starts inside a
    disk (only possible if ``current_m`` already breaks the minimum) is not made."""
    current_m = np.asarray(current_m, dtype=float)
    out = np.array(target_m, dtype=float)
    n_uavs = current_m.shape[1]
    if n_uavs == 1 or min_separation_m <= 0.0:
        return out
    s2 = float(min_separation_m) ** 2
    for d in range(n_uavs):
        start = current_m[:, d]
        move = out[:, d] - start
        others = np.concatenate([out[:, :d], current_m[:, d + 1 :]], axis=1)  # (N, D-1, 2)
        # |start - q + t move|^2 = s^2: a t^2 + b t + c = 0, entering at the smaller root.
        rel = start[:, None, :] - others
        a = np.einsum("nk,nk->n", move, move)[:, None]
        b = 2.0 * np.einsum("njk,nk->nj", rel, move)
        c = np.einsum("njk,njk->nj", rel, rel) - s2
        disc = b * b - 4.0 * a * c
        with np.errstate(divide="ignore", invalid="ignore"):
            root = (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a)
        approaching = (a > 0.0) & (disc > 0.0) & (b < 0.0)
        inside = c < 0.0
        t_enter = np.where(inside & (b < 0.0), 0.0, np.where(approaching & (root < 1.0), root, 1.0))
        t = np.clip(t_enter.min(axis=1), 0.0, 1.0)
        t = np.where(t < 1.0, np.maximum(t - _MARGIN * (1.0 + t), 0.0), 1.0)
        new = start + t[:, None] * move
        # Rounding in a grazing approach can leave the cut point a hair inside: then stay put
        # (the current position respects the minimum by the invariant above).
        short = (
            np.einsum("njk,njk->nj", new[:, None, :] - others, new[:, None, :] - others) < s2
        ).any(axis=1)
        out[:, d] = np.where(short[:, None] & ~inside.any(axis=1)[:, None], start, new)
    return out


def apply_moves(
    current_m: np.ndarray, moves_m: np.ndarray, half_width_m: float, min_separation_m: float
) -> np.ndarray:
    """Where UAVs (N, D, 2) at ``current_m`` go for ``moves_m`` (N, D, 2): clipped into the area
    (``|x|, |y| <= half_width_m``), then kept apart by :func:`separate`."""
    target = np.clip(current_m + moves_m, -half_width_m, half_width_m)
    return separate(current_m, target, min_separation_m)


def next_setpoints(
    setpoint_m: np.ndarray,
    moves_m: np.ndarray,
    half_width_m: float,
    min_separation_m: float,
    actual_m: np.ndarray | None = None,
    velocity_mps: np.ndarray | None = None,
    margin_m: float = 0.0,
) -> np.ndarray:
    """Next setpoints (N, D, 2) from the current ones and the moves (N, D, 2), as the env moves its
    UAVs (:func:`apply_moves`: clipped to the area, then the separation filter); with the vehicles'
    ``actual_m`` positions (N, D, 2) and ``velocity_mps``, moves are also cut where what they sweep
    until the next setpoint would bring two within ``min_separation_m``
    (:func:`~uavlink.mobility.transit.guard_transit`)."""
    target = apply_moves(setpoint_m, moves_m, half_width_m, min_separation_m)
    if actual_m is None:
        return target
    return guard_transit(
        actual_m, setpoint_m, target, min_separation_m, velocity_mps, half_width_m, margin_m
    )


def fleet_setpoints(
    current_xy_m: np.ndarray,
    moves_m: np.ndarray,
    cfg: EnvConfig,
    movable: np.ndarray | None = None,
    actual_xy_m: np.ndarray | None = None,
    velocity_mps: np.ndarray | None = None,
    margin_m: float = 0.0,
) -> np.ndarray:
    """One fleet's next setpoints (D, 2) east/north (the flight loop's): :func:`next_setpoints`
    with ``cfg``'s area and separation. ``movable`` (D,) bool: a vehicle that cannot be told this
    frame keeps its setpoint (its move is not made)."""
    moves = np.where(movable[:, None], moves_m, 0.0) if movable is not None else moves_m
    actual = None if actual_xy_m is None else np.asarray(actual_xy_m)[None]
    velocity = None if velocity_mps is None else np.asarray(velocity_mps)[None]
    return next_setpoints(
        np.asarray(current_xy_m)[None],
        np.asarray(moves)[None],
        cfg.area.half_width_m,
        cfg.uav_separation_m,
        actual,
        velocity,
        margin_m,
    )[0]


def min_separation_m(xy_m: np.ndarray) -> np.ndarray:
    """Smallest horizontal distance between two UAVs of each env: (N, D, 2) -> (N,); inf for D = 1."""
    xy_m = np.asarray(xy_m, dtype=float)
    if xy_m.shape[1] < 2:
        return np.full(xy_m.shape[0], np.inf)
    gaps = np.linalg.norm(xy_m[:, :, None, :] - xy_m[:, None, :, :], axis=-1)
    gaps[:, np.arange(xy_m.shape[1]), np.arange(xy_m.shape[1])] = np.inf
    return gaps.min(axis=(1, 2))
