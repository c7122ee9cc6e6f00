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
    ) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity (..., 2) after flying ``duration_s`` towards ``setpoint_m``."""
        pos, vel = position_m.astype(float, copy=True), velocity_mps.astype(float, copy=True)
        left = float(duration_s)
        while left > 1e-12:
            h = min(self.substep_s, left)
            pos, vel = self._substep(pos, vel, setpoint_m, h)
            left -= h
        return pos, vel

    def path(
        self, position_m: np.ndarray, velocity_mps: np.ndarray, setpoint_m: np.ndarray, steps: int
    ) -> np.ndarray:
        """Positions (steps, ..., 2) at the end of each of the next ``steps`` substeps towards
        ``setpoint_m``: what :meth:`fly` passes through."""
        pos, vel = np.asarray(position_m, dtype=float), np.asarray(velocity_mps, dtype=float)
        out = np.empty((steps, *np.broadcast_shapes(pos.shape, np.shape(setpoint_m))))
        for k in range(steps):
            pos, vel = self._substep(pos, vel, setpoint_m, self.substep_s)
            out[k] = pos
        return out

    def _substep(
        self, pos: np.ndarray, vel: np.ndarray, setpoint_m: np.ndarray, h: float
    ) -> tuple[np.ndarray, np.ndarray]:
        error = setpoint_m - pos
        dist = np.hypot(error[..., 0], error[..., 1])
        speed = np.minimum(
            np.minimum(self.max_speed_mps, self.gain_per_s * dist),
            np.sqrt(2.0 * self.brake_fraction * self.max_accel_mps2 * dist),
        )
        wanted = error * (speed / np.maximum(dist, 1e-9))[..., None]
        change = _limit_norm(wanted - vel, self.max_accel_mps2 * h)
        vel = _limit_norm(vel + change, self.max_speed_mps)
        return pos + vel * h, vel


def _limit_norm(v: np.ndarray, max_norm: float) -> np.ndarray:
    n = np.hypot(v[..., 0], v[..., 1])
    return v * np.minimum(1.0, max_norm / np.maximum(n, 1e-300))[..., None]


PX4_MOTION = PositionLoop()
