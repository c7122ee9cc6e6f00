"""The genie's planning core: a grid of UAV positions, the mean-channel reward of every grid cell in
every frame, and dynamic programming over frames for the best path under the motion limits.

Pure numpy, one episode at a time. Grid cells are indexed ``[ix, iy]`` (the point (x[ix], x[iy]),
metres east and north); a move is one of the grid offsets within r_max (hover first, so ties hover).
The DP runs backward over frames: the value of a cell is its reward plus the best value reachable
from it next frame, a max-filter with the disc's footprint (shifted maxima over its offsets).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uavlink.config import RadioConfig
from uavlink.radio.noise import noise_power_dbm
from uavlink.radio.pathloss import mean_rx_power_dbm
from uavlink.radio.spatial_shadowing import SpatialShadowField

REACH_SLACK_M = 1e-9  # a grid move of exactly r_max counts as reachable


@dataclass(frozen=True)
class Grid:
    """Square grid over the area, spacing at most ``spacing_m``; ``offsets`` (K, 2) are the cell
    moves within r_max, hover first."""

    x_m: np.ndarray  # (n,) coordinates of both axes, from -half to +half
    offsets: np.ndarray  # (K, 2) int
    r_max_m: float

    @classmethod
    def over_area(cls, half_width_m: float, spacing_m: float, r_max_m: float) -> Grid:
        n = int(np.ceil(2.0 * half_width_m / spacing_m - 1e-9)) + 1
        x = np.linspace(-half_width_m, half_width_m, n)
        step = x[1] - x[0]
        reach = int(r_max_m // step) + 1
        ij = [
            (i, j)
            for i in range(-reach, reach + 1)
            for j in range(-reach, reach + 1)
            if step * np.hypot(i, j) <= r_max_m + REACH_SLACK_M
        ]
        ij.sort(key=lambda o: (np.hypot(*o), o))  # hover first
        return cls(x, np.array(ij, dtype=int).reshape(-1, 2), float(r_max_m))

    @property
    def n(self) -> int:
        return len(self.x_m)

    @property
    def spacing_m(self) -> float:
        return float(self.x_m[1] - self.x_m[0])

    def points_m(self, cells: np.ndarray) -> np.ndarray:
        """Positions (..., 2) of cells (..., 2) given as [ix, iy]."""
        return self.x_m[np.asarray(cells)]

    def cells_within(self, xy_m: np.ndarray, radius_m: float) -> np.ndarray:
        """(n, n) bool: cells no farther than ``radius_m`` (+ slack) from ``xy_m``."""
        dx, dy = self.x_m - xy_m[0], self.x_m - xy_m[1]
        return dx[:, None] ** 2 + dy[None, :] ** 2 <= (radius_m + REACH_SLACK_M) ** 2


def grid_rx_dbm(
    grid: Grid,
    ue_xy_m: np.ndarray,
    field: SpatialShadowField | None,
    radio: RadioConfig,
    altitude_m: float,
    block: int = 16,
) -> np.ndarray:
    """Mean received power (T, U, n, n) float32, dBm, of each UE (positions (T, U, 2)) from a UAV at
    every grid cell: path loss plus the field's shadowing (none: the mean channel, as on AR(1)).

    The field (one env's, SPEC's sum of K cosines) at every cell for every UE position is one
    matrix product: cos(a + b) = cos a cos b - sin a sin b with a the UE's phase and b the cell's,
    (T U, 2K) @ (2K, n n), instead of n n T U K cosines."""
    n, x = grid.n, grid.x_m.astype(np.float32)
    at_1_m_dbm = (
        float(mean_rx_power_dbm(1e3, radio)) + 3.0 * radio.path_loss_slope_db
    )  # (1 m, unfloored)
    out = np.empty((*ue_xy_m.shape[:2], n, n), dtype=np.float32)
    if field is not None:
        ue_wave, uav_wave = (
            field.ue_wave_per_m[0].astype(float),
            field.uav_wave_per_m[0].astype(float),
        )
        cell_phase = (
            grid.x_m[:, None, None] * uav_wave[0] + grid.x_m[None, :, None] * uav_wave[1]
        ).reshape(n * n, -1)
        right = np.concatenate([np.cos(cell_phase), np.sin(cell_phase)], axis=1).T.astype(
            np.float32
        )
    for t0 in range(0, len(ue_xy_m), block):
        ue = ue_xy_m[t0 : t0 + block]  # (Tb, U, 2)
        dx2 = (x - ue[..., 0:1].astype(np.float32)) ** 2  # (Tb, U, n)
        dy2 = (x - ue[..., 1:2].astype(np.float32)) ** 2 + np.float32(altitude_m**2)
        # mean_rx_power_dbm (TR 25.814) on the squared distance, in place and in float32: the
        # planner's hot path (about 3x faster than float64, far finer than it needs; the plan's
        # value is re-scored by the env's own code in float64). tests/test_genie.py checks it.
        rx = out[t0 : t0 + len(ue)]
        np.add(dx2[..., :, None], dy2[..., None, :], out=rx)
        np.maximum(rx, np.float32(radio.min_distance_m**2), out=rx)
        np.log10(rx, out=rx)
        rx *= np.float32(-radio.path_loss_slope_db / 2.0)
        rx += np.float32(at_1_m_dbm)
        if field is not None:
            ue_phase = ue @ ue_wave + field.phase_rad[0].astype(float)  # (Tb, U, K)
            left = np.concatenate([np.cos(ue_phase), -np.sin(ue_phase)], axis=-1).astype(np.float32)
            rx += np.float32(field.amplitude_db) * (
                left.reshape(-1, left.shape[-1]) @ right
            ).reshape(rx.shape)
    return out


def one_uav_rate_mbps(rx_dbm: np.ndarray, radio: RadioConfig) -> np.ndarray:
    """Mean UE rate (..., n, n), Mbps, of one UAV at every grid cell from its received powers
    (..., U, n, n) dBm (``grid_rx_dbm``): round robin's (B / U) log2(1 + SNR), averaged over UEs. In
    float32, 10^(x/10) as exp: the hot path of one UAV's plan."""
    snr = np.exp(
        (rx_dbm - np.float32(noise_power_dbm(radio.bandwidth_hz, radio)))
        * np.float32(np.log(10.0) / 10.0)
    )
    snr += np.float32(1.0)
    return (radio.bandwidth_hz / rx_dbm.shape[-3] * 1e-6) * np.log2(snr, out=snr).mean(
        axis=-3, dtype=float
    )


@dataclass(frozen=True)
class MoveBox:
    """The moves allowed from one box of cells in one frame: ``allowed`` (K, h, w) bool, move k
    from cell [row + i, col + j] at ``allowed[k, i, j]``. Every move from a cell outside a frame's
    boxes (disjoint) is allowed: a fleet's separation forbids moves only near another UAV, so the
    DP's mask is a few boxes per frame, not a (K, n, n) array."""

    row: int
    col: int
    allowed: np.ndarray

    def at(self, cell: np.ndarray) -> np.ndarray | None:
        """(K,) the moves allowed from ``cell`` [ix, iy], or None when it lies outside the box."""
        i, j = int(cell[0]) - self.row, int(cell[1]) - self.col
        h, w = self.allowed.shape[1:]
        return self.allowed[:, i, j] if 0 <= i < h and 0 <= j < w else None


def best_grid_path(
    reward: np.ndarray,
    grid: Grid,
    first: np.ndarray,
    boxes: Sequence[Sequence[MoveBox]] | None = None,
) -> tuple[np.ndarray | None, float]:
    """The path of cells (T, 2) maximising the summed ``reward`` (T, n, n) (entry t: frame t + 1;
    -inf marks a forbidden cell), its first cell among ``first`` (n, n) bool, each later cell one
    grid offset from the one before; ``boxes`` (T - 1 entries of disjoint ``MoveBox``) may forbid
    moves from cells at frame t + 1. Returns (None, -inf) when no path is allowed. Exact: the DP's
    value is the best over all such paths (tests/test_genie.py checks by brute force).

    Backward, only maxima are kept (the value of every cell in every frame, contiguous shifted
    maxima, then recomputed inside the frame's boxes over their allowed moves); the path is read
    forward from the values, the first of equal moves (hover) winning."""
    n_frames, n = reward.shape[0], grid.n
    pad = int(np.abs(grid.offsets).max())
    values = np.empty((n_frames, n, n))
    values[-1] = reward[-1]
    padded = np.full((n + 2 * pad, n + 2 * pad), -np.inf)
    best = np.empty((n, n))
    for t in range(n_frames - 2, -1, -1):
        padded[pad : pad + n, pad : pad + n] = values[t + 1]
        best.fill(-np.inf)
        for di, dj in grid.offsets:
            np.maximum(best, padded[pad + di : pad + di + n, pad + dj : pad + dj + n], out=best)
        for box in () if boxes is None else boxes[t]:
            (h, w), r, c = box.allowed.shape[1:], pad + box.row, pad + box.col
            inside = np.full((h, w), -np.inf)
            for (di, dj), allowed in zip(grid.offsets, box.allowed, strict=True):
                # a forbidden move leaves ``inside`` as it is (ufunc ``where``: no masked copy)
                window = padded[r + di : r + di + h, c + dj : c + dj + w]
                np.maximum(inside, window, out=inside, where=allowed)
            best[box.row : box.row + h, box.col : box.col + w] = inside
        np.add(reward[t], best, out=values[t])
    total = np.where(first, values[0], -np.inf)
    cell = np.unravel_index(int(np.argmax(total)), total.shape)
    if not np.isfinite(total[cell]):
        return None, -np.inf
    path = np.empty((n_frames, 2), dtype=int)
    path[0] = cell
    for t in range(n_frames - 1):
        nxt = path[t] + grid.offsets  # (K, 2)
        inside = ((nxt >= 0) & (nxt < n)).all(axis=1)
        score = np.full(len(nxt), -np.inf)
        score[inside] = values[t + 1][nxt[inside, 0], nxt[inside, 1]]
        for box in () if boxes is None else boxes[t]:
            allowed = box.at(path[t])
            if allowed is not None:
                score[~allowed] = -np.inf
        path[t + 1] = nxt[int(np.argmax(score))]
    return path, float(total[cell])
