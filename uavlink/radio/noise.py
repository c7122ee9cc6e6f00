"""Thermal noise at the UE receiver."""

from __future__ import annotations

import math

from uavlink.config import RadioConfig

DEFAULT_RADIO = RadioConfig()


def noise_power_dbm(bandwidth_hz: float, radio: RadioConfig = DEFAULT_RADIO) -> float:
    """N = -174 dBm/Hz + 10 log10(B) + NF. For 10 MHz and NF 9 dB: -95.0 dBm."""
    return radio.thermal_noise_dbm_per_hz + 10.0 * math.log10(bandwidth_hz) + radio.noise_figure_db

