"""How a UAV flies to its position setpoint in a frame: the paper's instant move, or PX4's multicopter
position loop as ``sitl_stub`` flies it. Batched numpy over UAV rows, no randomness.

The paper's env puts the UAV at its setpoint each frame: a 12 m move from a hover in one second.
With PX4's horizontal acceleration limit (MPC_ACC_HOR_MAX, 5 m/s^2) a real multicopter covers
about 2.5 m in that second, and a reversal at full speed takes about five. ``PX4_MOTION`` integrates
the horizontal part of ``sitl_stub.flight.pos_control.track`` (the same controller, in the same
20 ms substeps): velocity setpoint min(MPC_XY_VEL_MAX, gain x error, sqrt(2 x 0.9 a x error)) along
the error, reached at no more than a per second squared. In offboard the setpoint is the previous
setpoint plus the policy's move (as ``uavlink fly`` sends it), not the position plus the move.

Two kernels do the same operations: numpy over every row at once (the env's thousands of UAVs), and
Python floats row by row for a few. A flight's transit guard predicts a fleet of two 300 substeps
ahead every decision: 38 ms in numpy's per-call overhead on a 2-core machine, 3 ms in floats
(``python benchmarks/transit_guard.py``), where a vehicle at 20x real time waits 50 ms for its next
setpoint (COM_OF_LOSS_T). Both round alike (IEEE doubles, ``sqrt`` correctly rounded, ``min``
exact), so a row is the same bits whichever kernel flies it (``tests/test_uav_motion.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uavlink.config.position_loop import (
    BRAKE_FRACTION,
    MPC_ACC_HOR_MAX_MPS2,
    MPC_XY_VEL_MAX_MPS,
    POS_GAIN_PER_S,
    SUBSTEP_S,
)

# up to this many rows (UAVs x setpoints) fly in Python floats: 300 substeps cost about 0.7 ms a row
# in floats and 34-38 ms in numpy for up to a hundred rows: even at about 54
FLOAT_KERNEL_MAX_ROWS = 48


@dataclass(frozen=True)
class PositionLoop:
    """PX4's horizontal position controller (mc_pos_control), as ``sitl_stub`` models it."""

    max_speed_mps: float = MPC_XY_VEL_MAX_MPS
    max_accel_mps2: float = MPC_ACC_HOR_MAX_MPS2
    gain_per_s: float = POS_GAIN_PER_S
    brake_fraction: float = BRAKE_FRACTION
    substep_s: float = SUBSTEP_S

    def fly(
        self,
        position_m: np.ndarray,
        velocity_mps: np.ndarray,
        setpoint_m: np.ndarray,
        duration_s: float,
        fence_m: float = math.inf,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity (..., 2) after flying ``duration_s`` towards ``setpoint_m``, inside
        the square fence ``|x|, |y| <= fence_m``."""
        # whole substeps of exactly substep_s, as a lockstep sitl_stub steps its vehicles
        # (subtracting 0.02 fifty times from 1.0 would leave a last step a few ulps short)
        whole = math.floor(duration_s / self.substep_s + 1e-9)
        rest = duration_s - whole * self.substep_s
        substeps_s = [self.substep_s] * whole + ([rest] if rest > 1e-12 else [])
        if not substeps_s:
            return np.array(position_m, dtype=float), np.array(velocity_mps, dtype=float)
        positions, velocity = self._fly_substeps(
            position_m, velocity_mps, setpoint_m, substeps_s, fence_m
        )
        return positions[-1], velocity

    def path(
        self,
        position_m: np.ndarray,
        velocity_mps: np.ndarray,
        setpoint_m: np.ndarray,
        steps: int,
        fence_m: float = math.inf,
    ) -> np.ndarray:
        """Positions (steps, ..., 2) at the end of each of the next ``steps`` substeps towards
        ``setpoint_m``: what :meth:`fly` passes through."""
        substeps_s = [self.substep_s] * steps
        return self._fly_substeps(position_m, velocity_mps, setpoint_m, substeps_s, fence_m)[0]

    def _fly_substeps(
        self,
        position_m: np.ndarray,
        velocity_mps: np.ndarray,
        setpoint_m: np.ndarray,
        substeps_s: list[float],
        fence_m: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Positions after each substep (len(substeps_s), ..., 2) and the last velocity (..., 2),
        by whichever kernel is faster for this many rows (the same bits)."""
        pos, vel = np.asarray(position_m, dtype=float), np.asarray(velocity_mps, dtype=float)
        shape = np.broadcast_shapes(pos.shape, vel.shape, np.shape(setpoint_m))
        positions = np.empty((len(substeps_s), *shape))
        if math.prod(shape[:-1]) > FLOAT_KERNEL_MAX_ROWS:
            for k, h in enumerate(substeps_s):
                pos, vel = self._substep(pos, vel, setpoint_m, h, fence_m)
                positions[k] = pos
            return positions, np.broadcast_to(vel, shape).copy()
        rows = (np.broadcast_to(a, shape).reshape(-1, 2).tolist() for a in (pos, vel, setpoint_m))
        flat = positions.reshape(len(substeps_s), -1, 2)  # a view: rows written in place
        last_vel = np.empty((flat.shape[1], 2))
        for m, ((px, py), (vx, vy), (sx, sy)) in enumerate(zip(*rows, strict=True)):
            flat[:, m], last_vel[m] = self._fly_row(px, py, vx, vy, sx, sy, substeps_s, fence_m)
        return positions, last_vel.reshape(shape)

    def _fly_row(
        self,
        px: float,
        py: float,
        vx: float,
        vy: float,
        sx: float,
        sy: float,
        substeps_s: list[float],
        fence_m: float,
    ) -> tuple[list[tuple[float, float]], tuple[float, float]]:
        """One row flown in Python floats: its positions after each substep and its last velocity.
        :meth:`_substep`'s operations in its order (``min`` picks what ``np.minimum`` does), inlined:
        a call per substep and per norm limit cost 40 % more."""
        sqrt, copysign = math.sqrt, math.copysign
        vmax, gain = self.max_speed_mps, self.gain_per_s
        brake = 2.0 * self.brake_fraction * self.max_accel_mps2
        positions = []
        for h in substeps_s:
            ex, ey = sx - px, sy - py
            dist = sqrt(ex * ex + ey * ey)
            speed = min(vmax, gain * dist, sqrt(brake * dist))
            wx = wy = 0.0
            if dist > 1e-9:
                wx, wy = ex / dist * speed, ey / dist * speed
                n = sqrt(wx * wx + wy * wy)
                if n > vmax:
                    wx, wy = wx * vmax / n, wy * vmax / n
            ax, ay, amax = wx - vx, wy - vy, self.max_accel_mps2 * h
            n = sqrt(ax * ax + ay * ay)
            if n > amax:
                ax, ay = ax * amax / n, ay * amax / n
            vx, vy = vx + ax, vy + ay
            n = sqrt(vx * vx + vy * vy)
            if n > vmax:
                vx, vy = vx * vmax / n, vy * vmax / n
            px, py = px + vx * h, py + vy * h
            if abs(px) > fence_m:
                px, vx = copysign(fence_m, px), 0.0
            if abs(py) > fence_m:
                py, vy = copysign(fence_m, py), 0.0
            positions.append((px, py))
        return positions, (vx, vy)

    def _substep(
        self, pos: np.ndarray, vel: np.ndarray, setpoint_m: np.ndarray, h: float, fence_m: float
    ) -> tuple[np.ndarray, np.ndarray]:
        # sitl_stub.flight.pos_control.track's operations in its order, element-wise, so that the
        # env's UAV and the SITL's vehicle fly the same setpoints to the same bits
        error = setpoint_m - pos
        dist = _norm(error)
        speed = np.minimum(
            np.minimum(self.max_speed_mps, self.gain_per_s * dist),
            np.sqrt(2.0 * self.brake_fraction * self.max_accel_mps2 * dist),
        )
        moving = (dist > 1e-9)[..., None]
        wanted = np.where(
            moving, error / np.where(moving, dist[..., None], 1.0) * speed[..., None], 0.0
        )
        wanted = _limit_norm(wanted, self.max_speed_mps)
        vel = _limit_norm(
            vel + _limit_norm(wanted - vel, self.max_accel_mps2 * h), self.max_speed_mps
        )
        pos = pos + vel * h
        # sitl_stub's hard fence (Vehicle._enforce_limits): an axis past it is put back on it and
        # stops; a vehicle carried past the area's edge by its velocity while it turns then
        # re-accelerates from rest along that axis
        out = np.abs(pos) > fence_m
        if out.any():
            pos, vel = np.where(out, np.copysign(fence_m, pos), pos), np.where(out, 0.0, vel)
        return pos, vel


def _norm(v: np.ndarray) -> np.ndarray:
    """Lengths of (..., 2) as sqrt(x x + y y), as sitl_stub's ``pos_control.norm``."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1])


def _limit_norm(v: np.ndarray, max_norm: float) -> np.ndarray:
    """``v`` scaled to ``max_norm`` where longer (v max / n, as sitl_stub's ``_limit_norm``)."""
    n = _norm(v)[..., None]
    return np.where(n > max_norm, v * max_norm / np.where(n > max_norm, n, 1.0), v)


PX4_MOTION = PositionLoop()
