"""A model of the sensed field: kriging of what a UAV sensed where, and the spot it makes worth flying to
(observation layout v5; ``EnvConfig.place_model = "kriging"``).

GPS-free for the UEs, like the memory of place (``uavlink.env.place_memory``): its inputs are the
UAV's own position and the value it senses each frame (mean over UEs of log2(1 + SINR), bits/s/Hz).
On the spatial channel that value is a field over the UAV's position: path loss plus the shadowing,
which decorrelates over ``DECORRELATION_M`` (Gudmundson's exponential covariance, SPEC "A spatially
consistent channel"; TR 38.901 7.6.3 models spatial consistency the same way). So the value is
modelled as a Gaussian process with that covariance, an unknown constant mean (a broad prior on a
constant term: ordinary kriging) and a nugget for the fast fading, and its posterior is kept at spots on a grid
(``SPACING_M``) over a disc of ``RADIUS_M`` around the area's centre, where a UAV starts over its team.

Each frame the model picks the spot worth most over the frames left, optimistically:
(frames left - frames to get there) x (posterior mean + ``BETA`` x posterior std), GP-UCB with the
horizon in it (Srinivas et al. 2010), so a look far away pays early in an episode and not late. A
picked spot stays picked until another scores ``SWITCH_GAIN`` times more: a vehicle that changes its
mind each frame flies reversals. The values were chosen on the validation episodes (seed 1) of
no_move: research/log/memory-of-place.md, "A model of the field".

The posterior is updated in O(n K) a frame (n spots sensed so far, K grid spots) by appending each
observation to the inverse Cholesky factor of the observations' covariance, batched over rows; a
fleet's pooled model appends a frame's D observations as one block (the block Cholesky update), so
that its (n, K) factor is read once a frame.
"""

from __future__ import annotations

import math

import numpy as np

DECORRELATION_M = 50.0  # the SPEC's UAV-end shadowing decorrelation distance
SIGMA_BITS = 1.5  # the field's standard deviation in sensed value (8 dB shadowing; fit on seed 1)
MEAN_SIGMA_BITS = 10.0  # the prior on the unknown constant mean: broad, so the data set it
NUGGET_BITS = 0.3  # the fast fading's frame-to-frame wobble of a sensed value
BETA = 2.5  # optimism: posterior std's weight in a spot's score
RADIUS_M = 120.0  # the disc of candidate spots around the area's centre
SPACING_M = 6.0  # the grid of candidate spots
SWITCH_GAIN = 1.02  # a new pick must score this much more than the current one


def candidate_spots_m(
    radius_m: float = RADIUS_M, spacing_m: float = SPACING_M, half_width_m: float = math.inf
) -> np.ndarray:
    """The grid spots (K, 2) within ``radius_m`` of the centre and inside the area, m."""
    axis = np.arange(-radius_m, radius_m + 1e-9, spacing_m)
    grid = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1).reshape(-1, 2)
    keep = (np.hypot(grid[:, 0], grid[:, 1]) <= radius_m) & (np.abs(grid) <= half_width_m).all(
        axis=1
    )
    return grid[keep]


class FieldModel:
    """Per-row Gaussian-process posteriors of the sensed value over candidate spots, batched in numpy.

    A row's model is one UAV's (layouts v5, v8), or with ``shared_by = D`` one fleet's (v9): the D
    UAVs of an env (consecutive rows of ``update``) each add what they sense and each pick from
    the one posterior, where they are."""

    def __init__(
        self,
        n_rows: int,
        horizon_frames: int,
        r_max_m: float,
        half_width_m: float = math.inf,
        sensors: int = 1,
        shared_by: int = 1,
    ) -> None:
        self.horizon_frames, self.r_max_m = int(horizon_frames), float(r_max_m)
        self.spots_m = candidate_spots_m(half_width_m=half_width_m)
        self.prior_var = SIGMA_BITS**2 + MEAN_SIGMA_BITS**2
        self.shared_by = int(shared_by)
        # room for the episode's first observation and a frame's each, from ``sensors`` places
        self.capacity = (self.horizon_frames + 1) * max(int(sensors), self.shared_by)
        n, k = self.capacity, len(self.spots_m)
        self._x = np.zeros((n_rows, n, 2))
        self._linv = np.zeros(
            (n_rows, n, n)
        )  # inverse Cholesky factor of the observations' covariance
        self._v = np.zeros((n_rows, n, k))  # linv @ cov(observations, spots)
        self._w = np.zeros((n_rows, n))  # linv @ values
        self.mean = np.zeros((n_rows, k))
        self.var = np.zeros((n_rows, k))
        self.pick = np.zeros(n_rows * self.shared_by, dtype=np.int64)
        self.frames = 0  # decisions made (updates)
        self.observed = 0  # observations added, the updates' and any other place's

    def reset(self) -> None:
        # the factors need no clearing: an update reads only the rows the episode has written
        self.mean[:] = 0.0
        self.var[:] = self.prior_var
        self.frames = self.observed = 0

    @staticmethod
    def _distance_m(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances (rows, m) between positions a (rows, 2) and b (rows, m, 2) or (m, 2); the two
        squares added by hand: numpy's sum over a last axis of 2 is several times slower."""
        dx, dy = b[..., 0] - a[:, 0, None], b[..., 1] - a[:, 1, None]
        return np.sqrt(dx * dx + dy * dy)

    @staticmethod
    def _cov(d_m: np.ndarray) -> np.ndarray:
        """Prior covariance at distances ``d_m``, computed in one buffer (the same bits as the
        textbook expression: IEEE negation, products and sums are exact to reorder this way)."""
        c = np.divide(d_m, -DECORRELATION_M)
        np.exp(c, out=c)
        c *= SIGMA_BITS**2
        c += MEAN_SIGMA_BITS**2
        return c

    def update(self, uav_xy_m: np.ndarray, value_bits: np.ndarray) -> dict[str, np.ndarray]:
        """Add this frame's sensed value at each UAV's position (rows x ``shared_by``, 2); the
        pick's quantities per UAV (offset from it, m; posterior mean minus the value now and
        posterior std, bits/s/Hz)."""
        x, y = np.asarray(uav_xy_m, dtype=float), np.asarray(value_bits, dtype=float)
        to_spots_m = self._distance_m(
            x, self.spots_m
        )  # (UAVs, K): the covariances' and the travel's
        if self.shared_by == 1:
            self._add(x, y, to_spots_m)
        else:  # the fleet's D readings in every row's one posterior, in fleet order
            d = self.shared_by
            self._add_frame(
                x.reshape(-1, d, 2),
                y.reshape(-1, d),
                to_spots_m.reshape(-1, d, to_spots_m.shape[1]),
            )
        self.frames += 1
        return self._pick(x, y, to_spots_m)

    def observe(self, xy_m: np.ndarray, value_bits: np.ndarray) -> None:
        """Add a value sensed at ``xy_m`` (rows, 2) by another place than the deciding UAV (a
        listening UAV of its fleet), without a decision; room for ``sensors - 1`` a frame."""
        x = np.asarray(xy_m, dtype=float)
        self._add(x, np.asarray(value_bits, dtype=float), self._distance_m(x, self.spots_m))

    def _add(self, x: np.ndarray, y: np.ndarray, to_spots_m: np.ndarray) -> None:
        """Append one observation per row: the posterior's update in O(n K)."""
        t = self.observed
        if t >= self.capacity:  # stepped past the episode without a reset: the model is full
            return
        linv, v, w = self._linv[:, :t, :t], self._v[:, :t], self._w[:, :t]
        k_old = self._cov(self._distance_m(x, self._x[:, :t]))  # (rows, t)
        ell = np.matmul(linv, k_old[..., None])[..., 0]  # (rows, t): L^-1 k
        d = np.sqrt(np.maximum(self.prior_var + NUGGET_BITS**2 - (ell * ell).sum(axis=1), 1e-12))
        self._linv[:, t, :t] = -np.matmul(ell[:, None, :], linv)[:, 0] / d[:, None]
        self._linv[:, t, t] = 1.0 / d
        v_new = self._cov(to_spots_m)  # (rows, K), then minus what the earlier spots explain
        v_new -= np.matmul(ell[:, None, :], v)[:, 0]
        v_new /= d[:, None]
        w_new = (y - (ell * w).sum(axis=1)) / d
        self._v[:, t], self._w[:, t], self._x[:, t] = v_new, w_new, x
        self.mean += v_new * w_new[:, None]
        self.var -= v_new * v_new
        self.observed = t + 1

    def _add_frame(self, x: np.ndarray, y: np.ndarray, to_spots_m: np.ndarray) -> None:
        """Append a frame's m observations per row (x: rows, m, 2) at once: the block form of m
        ``_add`` calls (the same posterior to rounding), which reads the (n, K) factor once instead
        of m times: 1.6-2.0x faster at m = 3 and 4, 0.8-0.9x at m = 2, where the small solves cost
        more than the read saves (``benchmarks/pooled_field_update.py``)."""
        t = self.observed
        m = min(x.shape[1], self.capacity - t)
        if m <= 0:
            return
        x, y, to_spots_m = x[:, :m], y[:, :m], to_spots_m[:, :m]
        linv, v, w = self._linv[:, :t, :t], self._v[:, :t], self._w[:, :t]
        # E = L^-1 k(old, new); the new points' covariance given the old, S = C C^T
        e = np.matmul(linv, self._cov(self._pairwise_m(self._x[:, :t], x)))  # (rows, t, m)
        e_t = e.transpose(0, 2, 1)
        s = self._cov(self._pairwise_m(x, x)) + NUGGET_BITS**2 * np.eye(m)
        s -= np.matmul(e_t, e)
        c_inv = np.linalg.inv(np.linalg.cholesky(s))  # (rows, m, m), lower triangular
        self._linv[:, t : t + m, :t] = -np.matmul(c_inv, np.matmul(e_t, linv))
        self._linv[:, t : t + m, t : t + m] = c_inv
        v_new = self._cov(to_spots_m)  # (rows, m, K), then minus what the earlier spots explain
        v_new -= np.matmul(e_t, v)
        v_new = np.matmul(c_inv, v_new)
        w_new = np.matmul(c_inv, (y - np.matmul(e_t, w[..., None])[..., 0])[..., None])[..., 0]
        self._v[:, t : t + m], self._w[:, t : t + m], self._x[:, t : t + m] = v_new, w_new, x
        self.mean += np.matmul(w_new[:, None], v_new)[:, 0]
        self.var -= (v_new * v_new).sum(axis=1)
        self.observed = t + m

    @staticmethod
    def _pairwise_m(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Distances (rows, p, q) between positions a (rows, p, 2) and b (rows, q, 2), m."""
        dx = b[:, None, :, 0] - a[:, :, None, 0]
        dy = b[:, None, :, 1] - a[:, :, None, 1]
        return np.sqrt(dx * dx + dy * dy)

    def _pick(
        self, x: np.ndarray, now_bits: np.ndarray, to_spots_m: np.ndarray
    ) -> dict[str, np.ndarray]:
        rows = np.arange(len(x))
        left = max(
            self.horizon_frames + 1 - self.frames, 0
        )  # decisions still to come, this one included
        score = np.divide(
            to_spots_m, self.r_max_m
        )  # (rows, K), in place from here: frames of travel,
        np.ceil(score, out=score)
        np.subtract(left, score, out=score)  # the frames left there,
        np.maximum(score, 0.0, out=score)
        mean, var = self.mean, self.var
        if self.shared_by > 1:  # each UAV's row of its fleet's posterior
            mean, var = np.repeat(mean, self.shared_by, axis=0), np.repeat(var, self.shared_by, 0)
        std = np.maximum(var, 0.0)
        np.sqrt(std, out=std)
        optimism = BETA * std
        optimism += mean
        score *= optimism  # times what it is worth
        best = score.argmax(axis=1)
        if self.frames == 1:
            self.pick = best
        else:
            switch = score[rows, best] > SWITCH_GAIN * score[rows, self.pick]
            self.pick = np.where(switch, best, self.pick)
        return {
            "place_pick_offset_m": self.spots_m[self.pick] - x,
            "place_pick_gain_bits": mean[rows, self.pick] - now_bits,
            "place_pick_std_bits": std[rows, self.pick],
        }
