"""Thermal noise at the UE receiver, and the mean SNR over it."""

from __future__ import annotations

import math

import numpy as np

from uavlink.config import RadioConfig
from uavlink.radio.pathloss import mean_rx_power_dbm

DEFAULT_RADIO = RadioConfig()


def noise_power_dbm(bandwidth_hz: float, radio: RadioConfig = DEFAULT_RADIO) -> float:
    """N = -174 dBm/Hz + 10 log10(B) + NF. For 10 MHz and NF 9 dB: -95.0 dBm."""
    return radio.thermal_noise_dbm_per_hz + 10.0 * math.log10(bandwidth_hz) + radio.noise_figure_db


def mean_snr_db(distance_m: np.ndarray | float, radio: RadioConfig = DEFAULT_RADIO) -> np.ndarray:
    """SNR over the whole band at a 3-D distance, without shadowing or fading (dB): the reward's
    bounds and the aoa rule's hover level (a UE straight below, at the UAV's altitude)."""
    return mean_rx_power_dbm(distance_m, radio) - noise_power_dbm(radio.bandwidth_hz, radio)
