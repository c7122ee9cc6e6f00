"""The fleet genie's separation checks on its grid: whether a straight move keeps clear of a point,
and the boxes of allowed moves the DP reads (``uavlink.policies.genie.grid.MoveBox``).

The env's separation filter (``uavlink.mobility.fleet.separate``) cuts a move that passes within
the separation of another UAV; the planner keeps every planned move clear of it, so the realised
path is the planned one."""

from __future__ import annotations

import itertools

import numpy as np

from uavlink.policies.genie.grid import MoveBox


def segment_clear(a: np.ndarray, b: np.ndarray, c: np.ndarray, distance_m: float) -> np.ndarray:
    """Whether points ``c`` lie at least ``distance_m`` from segments [a, b] (all (..., 2), broadcasting)."""
    abx, aby = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    acx, acy = c[..., 0] - a[..., 0], c[..., 1] - a[..., 1]
    length2 = abx * abx + aby * aby
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(length2 > 0.0, (acx * abx + acy * aby) / length2, 0.0), 0.0, 1.0)
    dx, dy = acx - t * abx, acy - t * aby
    return dx * dx + dy * dy >= distance_m * distance_m


def merged_boxes(rows: list[int], cols: list[int], allowed: np.ndarray) -> list[MoveBox]:
    """Disjoint boxes from square windows of allowed moves (origins ``rows``, ``cols``; ``allowed``
    (D - 1, K, w, w)): windows that overlap merge into one box spanning them, a move allowed there
    where every window allows it."""
    w = allowed.shape[-1]
    groups = [[i] for i in range(len(rows))]
    merged = True
    while merged:  # at most D - 1 windows: merge pairs until no two groups overlap
        merged = False
        for a, b in itertools.combinations(range(len(groups)), 2):
            ra, rb = [min(rows[i] for i in groups[g]) for g in (a, b)]
            ca, cb = [min(cols[i] for i in groups[g]) for g in (a, b)]
            ha, hb = [max(rows[i] for i in groups[g]) + w for g in (a, b)]
            wa, wb = [max(cols[i] for i in groups[g]) + w for g in (a, b)]
            if ra < hb and rb < ha and ca < wb and cb < wa:
                groups[a] += groups.pop(b)
                merged = True
                break
    boxes = []
    for group in groups:
        if len(group) == 1:
            (i,) = group
            boxes.append(MoveBox(rows[i], cols[i], allowed[i]))
            continue
        row, col = min(rows[i] for i in group), min(cols[i] for i in group)
        h, v = max(rows[i] for i in group) + w - row, max(cols[i] for i in group) + w - col
        box = np.ones((allowed.shape[1], h, v), dtype=bool)
        for i in group:
            r, c = rows[i] - row, cols[i] - col
            box[:, r : r + w, c : c + w] &= allowed[i]
        boxes.append(MoveBox(row, col, box))
    return boxes
