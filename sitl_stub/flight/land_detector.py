"""Land detection and the disarm after landing: PX4's ``land_detector`` module and commander's
COM_DISARM_LAND, in the small (no MAVLink).

On the ground: at most ``GROUND_EPS_M`` up, not climbing (under 0.3 m/s vertically) and not asked
to climb. A landed, armed vehicle disarms after COM_DISARM_LAND seconds once it has flown (above
``TAKEN_OFF_ALT_M``) or when it landed in a landing mode, as PX4's auto-disarm does; 0 disables it.
"""

from __future__ import annotations

from dataclasses import dataclass

from sitl_stub.flight.pos_control import GROUND_EPS_M

TAKEN_OFF_ALT_M = 1.0  # above this the vehicle counts as having flown
LANDED_MAX_CLIMB_MPS = 0.3


@dataclass
class LandDetector:
    landed: bool = True
    landed_since_s: float = 0.0
    has_flown: bool = False

    def armed(self, t_s: float) -> None:
        """A new flight begins: the disarm timer counts from arming, as if it had just landed."""
        self.has_flown, self.landed_since_s = False, t_s

    def update(self, t_s: float, alt_m: float, vz_mps: float, armed: bool, wants_up: bool) -> bool:
        """Detect this step; whether the vehicle touched down now (it was in the air)."""
        landed = alt_m <= GROUND_EPS_M and not wants_up and abs(vz_mps) < LANDED_MAX_CLIMB_MPS
        touched_down = landed and not self.landed
        if touched_down:
            self.landed_since_s = t_s
        self.landed = landed
        if armed and alt_m > TAKEN_OFF_ALT_M:
            self.has_flown = True
        return touched_down

    def disarm_due(self, t_s: float, disarm_after_s: float, landing_mode: bool) -> bool:
        """Whether an armed vehicle should disarm now (COM_DISARM_LAND)."""
        return (
            self.landed
            and disarm_after_s > 0
            and (self.has_flown or landing_mode)
            and t_s - self.landed_since_s >= disarm_after_s
        )
