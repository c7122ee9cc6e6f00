"""Thermal noise at the UE receiver."""

from __future__ import annotations

import math

from uavlink.config import RadioConfig


def noise_power_dbm(bandwidth_hz: float, radio: RadioConfig = RadioConfig()) -> float:
    """N = -174 dBm/Hz + 10 log10(B) + NF. For 10 MHz and NF 9 dB: -95.0 dBm."""
    return radio.thermal_noise_dbm_per_hz + 10.0 * math.log10(bandwidth_hz) + radio.noise_figure_db


def snr_db_without_fading(rx_power_dbm: float, radio: RadioConfig = RadioConfig()) -> float:
    """Wide-band SNR; transmit power and noise are both spread evenly over the RBs."""
    return rx_power_dbm - noise_power_dbm(radio.bandwidth_hz, radio)
