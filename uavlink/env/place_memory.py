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

# A spot sensed 100 frames ago must have been 1 bit/s/Hz better than now.
STALE_BITS_PER_FRAME = 0.01
HYSTERESIS_BITS = 0.1  # the best cell stays best until it reads this much less than when it won
NEIGHBOURS = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])  # east, north, west, south, in cells


def sensed_value_bits(sinr_db: np.ndarray) -> np.ndarray:
    """The value a spot is remembered by: mean over UEs of log2(1 + SINR), rows (N, U) dB -> (N,)."""
    x = np.asarray(sinr_db, dtype=float) * (np.log(10.0) / 10.0)
    np.exp(x, out=x)  # exp: far cheaper than 10.0 ** x
    np.log1p(x, out=x)
    bits = x.sum(axis=1)  # then / U: what .mean(axis=1) computes, bit for bit, without its wrapper
    bits /= x.shape[1]
    bits /= np.log(2.0)
    return bits


class PlaceMemory:
    """Per-row grid maps (rows = agent rows, one UAV each), batched in numpy.

    The per-frame update is on the env's hot path and is some thirty small numpy calls, so cells are
    addressed flat (row offset + cell), cell centres and neighbours come from tables built once, and
    a neighbour beyond the grid's edge is a cell that is never sensed. A cell keeps its value (-inf:
    never sensed) and the frame it was sensed in; its score, value + stale x frame, is computed when
    needed (the same float64 as when it was written). So a cell is 12 bytes, not 24 (256 rows: 3.6 MB
    rather than 7.1 MB), and the gathers each frame makes across every row's grid stay in cache
    better: they are what the memory's update waits on."""

    def __init__(self, cell_m: float, half_width_m: float, n_rows: int) -> None:
        self.cell_m = float(cell_m)
        self.half_width_m = float(half_width_m)
        self.n_side = max(1, math.ceil(2 * half_width_m / cell_m))
        n_cells = self.n_side * self.n_side
        self._row_offset = np.arange(n_rows) * (n_cells + 1)  # flat index of a row's cell 0
        # One more cell per row than the grid has: the neighbour beyond the edge, never sensed.
        self._value = np.full((n_rows, n_cells + 1), -np.inf)
        self._seen = np.zeros(
            (n_rows, n_cells + 1), dtype=np.int32
        )  # the frame a cell was sensed in
        self.best = np.zeros(n_rows, dtype=np.int64)
        self.best_score = np.full(
            n_rows, -np.inf
        )  # the best cell's score when it won (or last rose)
        self.frames = 0
        ij = np.stack(np.divmod(np.arange(n_cells), self.n_side), axis=-1)  # (cells, 2)
        self._centres_m = (ij + 0.5) * self.cell_m - self.half_width_m
        nbr = ij[:, None, :] + NEIGHBOURS[None]  # (cells, 4, 2)
        inside = ((nbr >= 0) & (nbr < self.n_side)).all(axis=2)
        self._nbr_cell = np.where(inside, nbr[..., 0] * self.n_side + nbr[..., 1], n_cells)

    @property
    def value(self) -> np.ndarray:
        """(rows, cells) the value last sensed in each cell, bits/s/Hz; -inf where never sensed."""
        return self._value[:, :-1]

    @property
    def score(self) -> np.ndarray:
        """(rows, cells) each cell's rank, value + stale x frame seen; -inf where never sensed."""
        return self._scores(slice(None))[:, :-1]

    def _scores(self, rows) -> np.ndarray:
        return self._value[rows] + STALE_BITS_PER_FRAME * self._seen[rows]

    def reset(self) -> None:
        self._value[:] = -np.inf
        self.best_score[:] = -np.inf
        self.frames = 0

    def _cell(self, uav_xy_m: np.ndarray) -> np.ndarray:
        """Flat grid cells (rows,) of positions (rows, 2), clipped to the grid."""
        # truncation, then the clip, is floor's cell for every position (np.clip is slow on ints)
        ij = ((uav_xy_m + self.half_width_m) / self.cell_m).astype(np.int64)
        np.maximum(ij, 0, out=ij)
        np.minimum(ij, self.n_side - 1, out=ij)
        return ij[:, 0] * self.n_side + ij[:, 1]

    def centre_m(self, cell: np.ndarray) -> np.ndarray:
        """Centres (rows, 2) of flat cell indices (rows,)."""
        return self._centres_m.take(cell, axis=0)

    def update(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray) -> dict[str, np.ndarray]:
        """Write this frame's sensed value at each row's cell; the memory's quantities for the
        observation (see the module docstring), rows first."""
        uav_xy_m = np.asarray(uav_xy_m, dtype=float)
        t = self.frames
        now = sensed_value_bits(sinr_db)
        cell = self._cell(uav_xy_m)
        flat = self._row_offset + cell
        values, seen = self._value.reshape(-1), self._seen.reshape(-1)
        values[flat] = now
        seen[flat] = t
        new_score = now + STALE_BITS_PER_FRAME * t
        won = new_score >= self.best_score
        lost = (cell == self.best) & (
            new_score < self.best_score - HYSTERESIS_BITS
        )  # the best read less
        np.copyto(self.best, cell, where=won)
        np.copyto(self.best_score, new_score, where=won)
        if lost.any():
            rows = np.flatnonzero(lost)
            scores = self._scores(rows)
            best = scores.argmax(axis=1)  # never the edge cell: it stays -inf
            self.best[rows] = best
            self.best_score[rows] = scores[np.arange(len(rows)), best]
        self.frames = t + 1
        # take() rather than fancy indexing: the same gather at a fifth of the cost on these sizes
        best_flat = self._row_offset + self.best
        nbr = values.take(
            self._row_offset[:, None] + self._nbr_cell.take(cell, axis=0)
        )  # (rows, 4)
        known = nbr > -np.inf
        return {
            "place_best_offset_m": self._centres_m.take(self.best, axis=0) - uav_xy_m,
            "place_best_gain_bits": values.take(best_flat) - now,
            "place_best_age_frames": float(t) - seen.take(best_flat),
            "place_frames": np.full(len(cell), float(self.frames)),
            "place_neighbour_gain_bits": np.where(known, nbr - now[:, None], 0.0),
            "place_neighbour_known": known.astype(float),
        }
