"""PX4 flight-mode encoding, shared by the flight loop and the SITL vehicle (no MAVLink import).

PX4 reports its mode in HEARTBEAT.custom_mode as ``main << 16 | sub << 24``
(``src/modules/commander/px4_custom_mode.h``); AUTO's sub modes name what it is doing.
"""

from __future__ import annotations

PX4_MAIN_MANUAL = 1
PX4_MAIN_ALTCTL = 2
PX4_MAIN_POSCTL = 3
PX4_MAIN_AUTO = 4
PX4_MAIN_ACRO = 5
PX4_MAIN_OFFBOARD = 6
PX4_MAIN_STABILIZED = 7
PX4_MAIN_RATTITUDE = 8

PX4_SUB_AUTO_READY = 1
PX4_SUB_AUTO_TAKEOFF = 2
PX4_SUB_AUTO_LOITER = 3
PX4_SUB_AUTO_MISSION = 4
PX4_SUB_AUTO_RTL = 5
PX4_SUB_AUTO_LAND = 6

_MAIN_NAMES = {
    PX4_MAIN_MANUAL: "MANUAL",
    PX4_MAIN_ALTCTL: "ALTCTL",
    PX4_MAIN_POSCTL: "POSCTL",
    PX4_MAIN_AUTO: "AUTO",
    PX4_MAIN_ACRO: "ACRO",
    PX4_MAIN_OFFBOARD: "OFFBOARD",
    PX4_MAIN_STABILIZED: "STABILIZED",
    PX4_MAIN_RATTITUDE: "RATTITUDE",
}
_AUTO_SUB_NAMES = {
    PX4_SUB_AUTO_READY: "READY",
    PX4_SUB_AUTO_TAKEOFF: "TAKEOFF",
    PX4_SUB_AUTO_LOITER: "LOITER",
    PX4_SUB_AUTO_MISSION: "MISSION",
    PX4_SUB_AUTO_RTL: "RTL",
    PX4_SUB_AUTO_LAND: "LAND",
}


def encode_custom_mode(main: int, sub: int) -> int:
    """PX4 ``custom_mode`` from main and sub mode."""
    return (int(main) & 0xFF) << 16 | (int(sub) & 0xFF) << 24


def decode_custom_mode(custom_mode: int) -> tuple[int, int]:
    """(main, sub) from a PX4 ``custom_mode``."""
    return (int(custom_mode) >> 16) & 0xFF, (int(custom_mode) >> 24) & 0xFF


def px4_mode_name(main: int, sub: int) -> str:
    """PX4's name for a mode, e.g. ``AUTO.LOITER``, ``OFFBOARD``; ``mode 9.0`` when unknown."""
    if main == PX4_MAIN_AUTO:
        return f"AUTO.{_AUTO_SUB_NAMES.get(sub, sub)}"
    return _MAIN_NAMES.get(main, f"mode {main}.{sub}")
