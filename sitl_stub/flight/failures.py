"""Failures injected with MAV_CMD_INJECT_FAILURE (MAVSDK's failure plugin), as PX4's failure
injector applies them in SITL, in the small. No MAVLink import; units and types are MAVLink's
FAILURE_UNIT / FAILURE_TYPE values.

Modelled (type OFF injects, OK restores): GPS (GPS_RAW_INT shows no fix, the GPS health bit
clears), the battery (its health bit clears) and the motors (any instance: no thrust, the
vehicle falls and, once on the ground, auto-disarms). Other units and types are UNSUPPORTED.
PX4 refuses all of it unless SYS_FAILURE_EN is 1.
"""

from __future__ import annotations

from sitl_stub.core.vehicle_state import ACCEPTED, Outcome, Result

FAILURE_UNIT_SENSOR_GPS = 4
FAILURE_UNIT_SYSTEM_BATTERY = 100
FAILURE_UNIT_SYSTEM_MOTOR = 101
FAILURE_TYPE_OK = 0
FAILURE_TYPE_OFF = 1

#: unit -> the name it has in :attr:`FailureState.active` (and VehicleState.failures)
MODELLED_UNITS = {
    FAILURE_UNIT_SENSOR_GPS: "gps",
    FAILURE_UNIT_SYSTEM_BATTERY: "battery",
    FAILURE_UNIT_SYSTEM_MOTOR: "motor",
}


class FailureState:
    """Which modelled failures are active."""

    def __init__(self) -> None:
        self.active: set[str] = set()

    @property
    def motors_off(self) -> bool:
        return "motor" in self.active

    def inject(self, unit: int, failure_type: int) -> Outcome:
        """Apply FAILURE_TYPE ``failure_type`` to FAILURE_UNIT ``unit`` (OK restores it)."""
        name = MODELLED_UNITS.get(unit)
        if name is None or failure_type not in (FAILURE_TYPE_OK, FAILURE_TYPE_OFF):
            return Outcome(
                Result.UNSUPPORTED,
                f"Failure injection: unit {unit} type {failure_type} not simulated",
            )
        if failure_type == FAILURE_TYPE_OFF:
            self.active.add(name)
        else:
            self.active.discard(name)
        return ACCEPTED
