"""A memory of place: what each UAV sensed where, kept over the episode (SPEC "The limit, and a memory
of place"), and the small summary of it a policy sees.

GPS-free for the UEs: its inputs are the UAV's own position (the env's, in flight the autopilot's
LOCAL_POSITION_NED) and the SINRs it senses, the same two inputs as every observation frame, and it
lives in the observation builder, so env and ``fly`` build it with the same code.

The map: a grid of ``place_cell_m`` cells over the area; each cell keeps the sensed value there, the
mean over UEs of log2(1 + SINR) (bits/s/Hz, what the round-robin throughput follows), the last time
the UAV was in it, and that frame. The team moves, so an entry goes stale: cells are ranked by
value - ``STALE_BITS_PER_FRAME`` x age, so a spot sensed long ago must have been much better to win.
Ranking by value + stale x frame_seen is the same order at every frame, which keeps the best cell
incremental: one write per row and frame, and a full search only for the rows whose best reads
``HYSTERESIS_BITS`` less than when it became best (so the best is within that of the top-ranked cell;
the fast fading's frame-to-frame wobble neither moves it nor costs a search).

What a policy sees (``PLACE_FIELDS`` of ``uavlink.env.observation``): the best remembered cell's
offset from the UAV (m), its value minus what the UAV senses now, its age (frames), how many frames
the memory holds (the episode clock), and the four neighbouring cells (east, north, west, south)
as value minus now, with a flag for "never sensed". Fixed width whatever the grid.
"""

from __future__ import annotations

import math

import numpy as np

STALE_BITS_PER_FRAME = 0.01  # a spot sensed 100 frames ago must have been 1 bit/s/Hz better than now
HYSTERESIS_BITS = 0.1  # the best cell stays best until it reads this much less than when it won
NEIGHBOURS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])  # east, north, west, south, in cells


def sensed_value_bits(sinr_db: np.ndarray) -> np.ndarray:
    """The value a spot is remembered by: mean over UEs of log2(1 + SINR), rows (N, U) dB -> (N,)."""
    linear = np.exp(np.asarray(sinr_db, dtype=float) * (np.log(10.0) / 10.0))  # exp: far cheaper than 10.0 ** x
    return np.log1p(linear).mean(axis=1) / np.log(2.0)


class PlaceMemory:
    """Per-row grid maps (rows = agent rows, one UAV each), batched in numpy."""

    def __init__(self, cell_m: float, half_width_m: float, n_rows: int) -> None:
        self.cell_m = float(cell_m)
        self.half_width_m = float(half_width_m)
        self.n_side = max(1, math.ceil(2 * half_width_m / cell_m))
        n_cells = self.n_side * self.n_side
        self._rows = np.arange(n_rows)
        self.value = np.zeros((n_rows, n_cells))
        self.score = np.full((n_rows, n_cells), -np.inf)  # value + stale x frame seen; -inf: never
        self.seen = np.zeros((n_rows, n_cells), dtype=np.int64)
        self.best = np.zeros(n_rows, dtype=np.int64)
        self.best_score = np.full(n_rows, -np.inf)  # the best cell's score when it won (or last rose)
        self.frames = 0

    def reset(self) -> None:
        self.score[:] = -np.inf
        self.best_score[:] = -np.inf
        self.frames = 0

    def _cell_xy(self, uav_xy_m: np.ndarray) -> np.ndarray:
        """Grid indices (rows, 2) of positions (rows, 2)."""
        ij = np.floor((uav_xy_m + self.half_width_m) / self.cell_m).astype(np.int64)
        return np.clip(ij, 0, self.n_side - 1)

    def centre_m(self, cell: np.ndarray) -> np.ndarray:
        """Centres (rows, 2) of flat cell indices (rows,)."""
        ij = np.stack([cell // self.n_side, cell % self.n_side], axis=-1)
        return (ij + 0.5) * self.cell_m - self.half_width_m

    def update(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray) -> dict[str, np.ndarray]:
        """Write this frame's sensed value at each row's cell; the memory's quantities for the
        observation (see the module docstring), rows first."""
        uav_xy_m = np.asarray(uav_xy_m, dtype=float)
        rows, t = self._rows, self.frames
        now = sensed_value_bits(sinr_db)
        ij = self._cell_xy(uav_xy_m)
        cell = ij[:, 0] * self.n_side + ij[:, 1]
        new_score = now + STALE_BITS_PER_FRAME * t
        self.value[rows, cell] = now
        self.seen[rows, cell] = t
        self.score[rows, cell] = new_score
        won = new_score >= self.best_score
        lost = (cell == self.best) & (new_score < self.best_score - HYSTERESIS_BITS)  # the best read less
        self.best = np.where(won, cell, self.best)
        self.best_score = np.where(won, new_score, self.best_score)
        if lost.any():
            best = self.score[lost].argmax(axis=1)
            self.best[lost] = best
            self.best_score[lost] = self.score[np.flatnonzero(lost), best]
        self.frames = t + 1
        best = self.best
        nbr = ij[:, None, :] + NEIGHBOURS[None]  # (rows, 4, 2)
        inside = ((nbr >= 0) & (nbr < self.n_side)).all(axis=2)
        nbr_cell = np.clip(nbr[..., 0], 0, self.n_side - 1) * self.n_side + np.clip(nbr[..., 1], 0, self.n_side - 1)
        known = inside & np.isfinite(self.score[rows[:, None], nbr_cell])
        return {
            "place_best_offset_m": self.centre_m(best) - uav_xy_m,
            "place_best_gain_bits": self.value[rows, best] - now,
            "place_best_age_frames": (t - self.seen[rows, best]).astype(float),
            "place_frames": np.full(len(rows), float(self.frames)),
            "place_neighbour_gain_bits": np.where(known, self.value[rows[:, None], nbr_cell] - now[:, None], 0.0),
            "place_neighbour_known": known.astype(float),
        }
