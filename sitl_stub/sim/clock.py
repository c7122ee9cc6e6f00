"""Simulated time driven by the wall clock at a fixed speed factor."""

from __future__ import annotations

import math
import time
from collections.abc import Callable


class SimClock:
    """Simulated seconds since start, advancing ``speed`` times as fast as the wall clock.

    A stall longer than ``max_wall_step_s`` (a paused process, an overloaded machine) advances
    simulated time by at most ``speed * max_wall_step_s``: the simulation slows down rather than
    jumping.
    """

    def __init__(
        self,
        speed: float = 1.0,
        max_wall_step_s: float = 0.25,
        wall: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be a positive number, got {speed}")
        self.speed = float(speed)
        self.max_wall_step_s = max_wall_step_s
        self._wall = wall
        self._last_wall = wall()
        self.sim_s = 0.0

    def wall(self) -> float:
        """Wall-clock seconds (monotonic)."""
        return self._wall()

    def advance(self) -> float:
        """Move simulated time forward to match the wall clock; returns the new sim time."""
        now = self._wall()
        dt = min(max(now - self._last_wall, 0.0), self.max_wall_step_s)
        self._last_wall = now
        self.sim_s += dt * self.speed
        return self.sim_s
