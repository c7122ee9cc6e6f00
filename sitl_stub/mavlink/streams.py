"""Which telemetry message is due when: rates in simulated time, capped in wall time.

Default rates are close to PX4's "normal" (GCS) MAVLink mode. A stream's interval is simulated
time, so ``--speed 20`` sends 20x as often in wall time, up to ``max_wall_hz`` per stream (50 Hz)
so a fast simulation does not flood the link. The heartbeat is special: once per simulated second
and at least once per wall second at any speed (MAVSDK drops a link after 3 s of wall time
without one). SET_MESSAGE_INTERVAL changes a rate (interval in simulated microseconds; -1
disables, 0 restores the default).
"""

from __future__ import annotations

import math

DEFAULT_RATES_HZ: dict[str, float] = {
    "SYS_STATUS": 1.0,
    "BATTERY_STATUS": 0.5,
    "EXTENDED_SYS_STATE": 1.0,
    "HOME_POSITION": 0.5,
    "GPS_RAW_INT": 1.0,
    "GLOBAL_POSITION_INT": 10.0,
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE": 10.0,
    "ATTITUDE_QUATERNION": 0.0,
    "ODOMETRY": 0.0,  # off until asked (MAVSDK's set_rate_odometry), as PX4's normal mode
    "ALTITUDE": 0.0,
    "VFR_HUD": 4.0,
    "MISSION_CURRENT": 1.0,
    "ORBIT_EXECUTION_STATUS": 2.0,  # sent only while orbiting
}

HEARTBEAT_SIM_PERIOD_S = 1.0
HEARTBEAT_WALL_PERIOD_S = 1.0


class StreamScheduler:
    """Tracks per-stream rates and last send times (simulated and wall)."""

    def __init__(self, defaults: dict[str, float] | None = None, max_wall_hz: float = 50.0) -> None:
        self.defaults = dict(DEFAULT_RATES_HZ if defaults is None else defaults)
        self.rates = dict(self.defaults)
        self.min_wall_gap_s = 1.0 / max_wall_hz
        self._last_sim = {name: -1e9 for name in self.rates}
        self._last_wall = {name: -1e9 for name in self.rates}
        self._hb_sim = -1e9
        self._hb_wall = -1e9

    def __contains__(self, name: str) -> bool:
        return name in self.rates

    def set_interval(self, name: str, interval_us: float) -> bool:
        """Apply SET_MESSAGE_INTERVAL; False for an unknown stream or a bad interval (NaN,
        infinite, or negative other than -1)."""
        if name not in self.rates or not math.isfinite(interval_us):
            return False
        if interval_us < 0 and interval_us != -1:
            return False
        if interval_us == -1:
            self.rates[name] = 0.0
        elif interval_us == 0:
            self.rates[name] = self.defaults[name]
        else:
            self.rates[name] = 1e6 / interval_us
        return True

    def interval_us(self, name: str) -> int:
        """GET_MESSAGE_INTERVAL semantics: -1 disabled, else the interval."""
        rate = self.rates[name]
        return -1 if rate <= 0 else int(round(1e6 / rate))

    def due(self, sim_s: float, wall_s: float) -> list[str]:
        """Streams to send now; marks them sent."""
        out = []
        for name, rate in self.rates.items():
            if rate <= 0:
                continue
            if (
                sim_s - self._last_sim[name] >= 1.0 / rate - 1e-9
                and wall_s - self._last_wall[name] >= self.min_wall_gap_s - 1e-9
            ):
                self._last_sim[name] = sim_s
                self._last_wall[name] = wall_s
                out.append(name)
        return out

    def heartbeat_due(self, sim_s: float, wall_s: float) -> bool:
        """True (and marks sent) once per simulated second, with a 1 Hz wall-time floor."""
        if wall_s - self._hb_wall < self.min_wall_gap_s - 1e-9:
            return False
        if (
            sim_s - self._hb_sim >= HEARTBEAT_SIM_PERIOD_S - 1e-9
            or wall_s - self._hb_wall >= HEARTBEAT_WALL_PERIOD_S
        ):
            self._hb_sim = sim_s
            self._hb_wall = wall_s
            return True
        return False
