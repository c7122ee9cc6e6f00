"""The simulated battery, as PX4's SITL battery simulator drains it.

PX4 (src/modules/simulation/battery_simulator/BatterySimulator.cpp): while armed the charge falls
linearly, 100 % per SIM_BAT_DRAIN seconds (default 60), never below SIM_BAT_MIN_PCT (default 50 %);
disarmed, it is full again. The pack voltage is linear between the empty and full cell voltages
(PX4's BAT1_V_EMPTY 3.6 V, BAT1_V_CHARGED 4.05 V) times the cell count (4); there is no current
sensor (current -1). Times are simulated seconds. SIM_BAT_DRAIN and SIM_BAT_MIN_PCT are read from
the parameter store when it has them, so a parameter definition is all it takes to tune them live.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

SIM_BAT_DRAIN_S = 60.0
SIM_BAT_MIN_PCT = 50.0
CELL_EMPTY_V = 3.6
CELL_FULL_V = 4.05
CELL_COUNT = 4


@dataclass(frozen=True)
class BatteryReading:
    """What BATTERY_STATUS and SYS_STATUS report."""

    remaining_pct: float
    voltage_v: float

    @property
    def cell_voltage_v(self) -> float:
        return self.voltage_v / CELL_COUNT


class Battery:
    """Charge as a fraction in [0, 1], integrated over armed simulated time."""

    def __init__(self, params: Mapping[str, float] | None = None) -> None:
        self.params = params if params is not None else {}
        self.fraction = 1.0
        self._last_s: float | None = None

    def update(self, time_s: float, armed: bool) -> None:
        """Advance to ``time_s``: drain for the armed time since the last update, refill when
        disarmed."""
        if not armed:
            self.fraction, self._last_s = 1.0, None
            return
        drain_s = float(self.params.get("SIM_BAT_DRAIN", SIM_BAT_DRAIN_S))
        if self._last_s is not None and drain_s > 0:
            self.fraction -= max(time_s - self._last_s, 0.0) / drain_s
        self._last_s = time_s
        floor = float(self.params.get("SIM_BAT_MIN_PCT", SIM_BAT_MIN_PCT)) / 100.0
        self.fraction = max(self.fraction, floor)

    def reading(self) -> BatteryReading:
        cell_v = CELL_EMPTY_V + (CELL_FULL_V - CELL_EMPTY_V) * self.fraction
        return BatteryReading(100.0 * self.fraction, cell_v * CELL_COUNT)
