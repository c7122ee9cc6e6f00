"""What the SITL vehicle reports: request outcomes (valued as MAV_RESULT), event severities and
the immutable :class:`VehicleState` snapshot the server, telemetry and payloads read.

Frame: LOCAL_NED, origin at the area centre on the ground (= home): north = env y, east = env x,
down = -altitude. Safety monitors for tests and logs: the largest horizontal distance from the
centre on either axis ever reached (``max_abs_xy_m``) and the oldest setpoint the vehicle ever flew
OFFBOARD on (``max_offboard_setpoint_age_s``; the failsafe keeps it at COM_OF_LOSS_T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING

from sitl_stub.core.modes import FlightMode, LandedState

if TYPE_CHECKING:
    from sitl_stub.flight.guidance import Orbit

# MAV_SEVERITY values for vehicle events (reported as STATUSTEXT by the server).
SEVERITY_CRITICAL = 2
SEVERITY_WARNING = 4
SEVERITY_INFO = 6


class Result(IntEnum):
    """Outcome of a request, valued as MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4


@dataclass(frozen=True)
class Outcome:
    """A request's result and, when refused, PX4-style reason text."""

    result: Result
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.result is Result.ACCEPTED


ACCEPTED = Outcome(Result.ACCEPTED)


@dataclass(frozen=True)
class VehicleState:
    """Snapshot of the vehicle at ``time_s`` (simulated seconds since boot), LOCAL_NED."""

    time_s: float
    north_m: float
    east_m: float
    down_m: float
    vn_mps: float
    ve_mps: float
    vd_mps: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    yaw_rate_radps: float
    armed: bool
    mode: FlightMode
    landed_state: LandedState
    setpoint_ned: tuple[float, float, float] | None
    setpoints_accepted: int
    setpoints_rejected: int
    setpoints_clamped: int
    offboard_failsafes: int
    max_abs_xy_m: float = 0.0
    max_offboard_setpoint_age_s: float = 0.0
    fence_breached: bool = False  # a geofence is breached now (SYS_STATUS reports it unhealthy)
    mission_current: tuple[int, int, int, int] = (
        0,
        0,
        1,
        0,
    )  # MISSION_CURRENT seq, total, state, mode
    failures: frozenset[str] = frozenset()  # injected failures: "gps", "battery", "motor"
    orbit: Orbit | None = None  # the orbit flown in ORBIT mode
    armings: int = 0  # times armed since boot: each begins a flight (the radio payload's episode)

    @property
    def x_east_m(self) -> float:
        """Environment x (east)."""
        return self.east_m

    @property
    def y_north_m(self) -> float:
        """Environment y (north)."""
        return self.north_m

    @property
    def altitude_m(self) -> float:
        """Height above home (the ground), m."""
        return -self.down_m

    @property
    def ground_speed_mps(self) -> float:
        return math.hypot(self.vn_mps, self.ve_mps)

    @property
    def in_air(self) -> bool:
        return self.landed_state is not LandedState.ON_GROUND
