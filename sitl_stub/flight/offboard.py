"""The offboard setpoint stream of PX4's commander in the small: the last position setpoint, its
yaw, when it came and what the vehicle made of the stream (counters for tests and logs).

OFFBOARD is entered only while the stream is alive and fails safe once the last setpoint is older
than COM_OF_LOSS_T (PX4 ``Commander`` offboard_control_mode checks). No MAVLink here.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from sitl_stub.flight.pos_control import wrap

Ned = tuple[float, float, float]


class OffboardStream:
    """The last accepted setpoint and the stream's counters."""

    def __init__(self) -> None:
        self.setpoint: Ned | None = None
        self.yaw_rad: float | None = None
        self.time_s = -math.inf
        self.setpoints_accepted = 0
        self.setpoints_rejected = 0
        self.setpoints_clamped = 0
        self.failsafes = 0
        self.max_age_s = 0.0  # the oldest setpoint ever flown on (the failsafe bounds it)

    def offer(
        self, ned: Ned, yaw_rad: float | None, t_s: float, fence: Callable[[Ned], Ned]
    ) -> Ned | None:
        """Take a setpoint at time ``t_s``: None (rejected) unless finite, else ``fence(ned)``."""
        if not all(math.isfinite(v) for v in ned):
            self.setpoints_rejected += 1
            return None
        north, east, down = ned
        sp = fence((float(north), float(east), float(down)))
        if sp != ned:
            self.setpoints_clamped += 1
        self.setpoint, self.time_s = sp, t_s
        self.yaw_rad = wrap(yaw_rad) if yaw_rad is not None and math.isfinite(yaw_rad) else None
        self.setpoints_accepted += 1
        return sp

    def alive(self, t_s: float, loss_timeout_s: float) -> bool:
        """True while the last setpoint is no older than ``loss_timeout_s`` (COM_OF_LOSS_T)."""
        return self.setpoint is not None and t_s - self.time_s <= loss_timeout_s

    def flown_at(self, t_s: float) -> None:
        """Record that the vehicle flew OFFBOARD on the stream at ``t_s``."""
        self.max_age_s = max(self.max_age_s, t_s - self.time_s)
