"""The flight modes this vehicle flies and its landed states (no MAVLink import).

PX4's mode encoding lives in ``uavlink.mavlink.px4_modes``. Only the modes this stub flies are
members; others (MANUAL, POSCTL, ...) are refused.
"""

from __future__ import annotations

from enum import Enum, IntEnum

from uavlink.mavlink.px4_modes import (
    PX4_MAIN_ACRO,
    PX4_MAIN_ALTCTL,
    PX4_MAIN_AUTO,
    PX4_MAIN_MANUAL,
    PX4_MAIN_OFFBOARD,
    PX4_MAIN_POSCTL,
    PX4_MAIN_RATTITUDE,
    PX4_MAIN_STABILIZED,
    PX4_SUB_AUTO_LAND,
    PX4_SUB_AUTO_LOITER,
    PX4_SUB_AUTO_MISSION,
    PX4_SUB_AUTO_RTL,
    PX4_SUB_AUTO_TAKEOFF,
    encode_custom_mode,
    px4_mode_name,
)

#: PX4's POSCTL sub mode for ORBIT (``px4_custom_mode.h`` PX4_CUSTOM_SUB_MODE_POSCTL_ORBIT).
PX4_SUB_POSCTL_ORBIT = 1

#: PX4 main modes that need a manual-control (RC) link, which this vehicle never has.
MANUAL_MAIN_MODES = frozenset(
    {
        PX4_MAIN_MANUAL,
        PX4_MAIN_ALTCTL,
        PX4_MAIN_POSCTL,
        PX4_MAIN_ACRO,
        PX4_MAIN_STABILIZED,
        PX4_MAIN_RATTITUDE,
    }
)


class FlightMode(Enum):
    """The modes the stub flies, valued ``(main, sub)`` as PX4 encodes them."""

    TAKEOFF = (PX4_MAIN_AUTO, PX4_SUB_AUTO_TAKEOFF)
    LOITER = (PX4_MAIN_AUTO, PX4_SUB_AUTO_LOITER)  # "Hold" in QGC/MAVSDK
    MISSION = (PX4_MAIN_AUTO, PX4_SUB_AUTO_MISSION)
    RTL = (PX4_MAIN_AUTO, PX4_SUB_AUTO_RTL)
    LAND = (PX4_MAIN_AUTO, PX4_SUB_AUTO_LAND)
    OFFBOARD = (PX4_MAIN_OFFBOARD, 0)
    ORBIT = (PX4_MAIN_POSCTL, PX4_SUB_POSCTL_ORBIT)  # entered by MAV_CMD_DO_ORBIT only

    @property
    def main(self) -> int:
        return self.value[0]

    @property
    def sub(self) -> int:
        return self.value[1]

    @property
    def custom_mode(self) -> int:
        """HEARTBEAT.custom_mode in PX4's encoding."""
        return encode_custom_mode(self.main, self.sub)

    @property
    def px4_name(self) -> str:
        """PX4's name, e.g. ``AUTO.LOITER``."""
        if self is FlightMode.ORBIT:
            return "POSCTL.ORBIT"
        return px4_mode_name(self.main, self.sub)

    @classmethod
    def from_main_sub(cls, main: int, sub: int) -> FlightMode | None:
        """The mode for PX4's (main, sub), or None when the stub does not fly it.

        OFFBOARD ignores the sub mode, as PX4 commander does.
        """
        if main == PX4_MAIN_OFFBOARD:
            return cls.OFFBOARD
        for mode in cls:
            if mode.value == (main, sub):
                return mode
        return None


class LandedState(IntEnum):
    """MAV_LANDED_STATE values (EXTENDED_SYS_STATE.landed_state)."""

    UNDEFINED = 0
    ON_GROUND = 1
    IN_AIR = 2
    TAKEOFF = 3
    LANDING = 4
