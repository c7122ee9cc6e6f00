"""How a UAV flies to its position setpoint in a frame: the paper's instant move, or PX4's multicopter
position loop as ``sitl_stub`` flies it. Batched numpy over UAV rows, no randomness.

The paper's env puts the UAV at its setpoint each frame: a 12 m move from a hover in one second.
With PX4's horizontal acceleration limit (MPC_ACC_HOR_MAX, 5 m/s^2) a real multicopter covers
about 2.5 m in that second, and a reversal at full speed takes about five. ``PX4_MOTION`` integrates
the horizontal part of ``sitl_stub.flight.pos_control.track`` (the same controller, in the same
20 ms substeps): velocity setpoint min(MPC_XY_VEL_MAX, gain x error, sqrt(2 x 0.9 a x error)) along
the error, reached at no more than a per second squared. In offboard the setpoint is the previous
setpoint plus the policy's move (as ``uavlink fly`` sends it), not the position plus the move.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PositionLoop:
    """PX4's horizontal position controller (mc_pos_control), as ``sitl_stub`` models it."""

    max_speed_mps: float = 12.0  # MPC_XY_VEL_MAX
    max_accel_mps2: float = 5.0  # MPC_ACC_HOR_MAX
    gain_per_s: float = 1.0  # MPC_XY_P (PX4 0.95)
    brake_fraction: float = 0.9  # braking curves use 90 % of the acceleration limit
    substep_s: float = 0.02  # sitl_stub's integration step

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
        pos, vel = position_m.astype(float, copy=True), velocity_mps.astype(float, copy=True)
        # whole substeps of exactly substep_s, as a lockstep sitl_stub steps its vehicles
        # (subtracting 0.02 fifty times from 1.0 would leave a last step a few ulps short)
        whole = math.floor(duration_s / self.substep_s + 1e-9)
        for _ in range(whole):
            pos, vel = self._substep(pos, vel, setpoint_m, self.substep_s, fence_m)
        rest = duration_s - whole * self.substep_s
        if rest > 1e-12:
            pos, vel = self._substep(pos, vel, setpoint_m, rest, fence_m)
        return pos, vel

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
        pos, vel = np.asarray(position_m, dtype=float), np.asarray(velocity_mps, dtype=float)
        out = np.empty((steps, *np.broadcast_shapes(pos.shape, np.shape(setpoint_m))))
        for k in range(steps):
            pos, vel = self._substep(pos, vel, setpoint_m, self.substep_s, fence_m)
            out[k] = pos
        return out

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
