"""Distance-dependent path loss, TR 25.814 urban macro (Table A.2.1.1-3)."""

from __future__ import annotations

import numpy as np

from uavlink.config import RadioConfig

DEFAULT_RADIO = RadioConfig()


def distance_3d_m(uav_xy_m: np.ndarray, ue_xy_m: np.ndarray, altitude_m: float) -> np.ndarray:
    """3-D distance between UAVs (..., D, 2) and UEs (..., U, 2) on the ground -> (..., U, D)."""
    delta = ue_xy_m[..., :, None, :] - uav_xy_m[..., None, :, :]
    return np.sqrt(np.einsum("...k,...k->...", delta, delta) + altitude_m * altitude_m)


def path_loss_db(distance_m: np.ndarray | float, radio: RadioConfig = DEFAULT_RADIO) -> np.ndarray:
    """L = 128.1 + 37.6 log10(d / 1 km) dB, with d floored at ``radio.min_distance_m`` (35 m)."""
    d_km = np.maximum(distance_m, radio.min_distance_m) * 1e-3
    return radio.path_loss_intercept_db + radio.path_loss_slope_db * np.log10(d_km)


def mean_rx_power_dbm(
    distance_m: np.ndarray | float, radio: RadioConfig = DEFAULT_RADIO
) -> np.ndarray:
    """Received power without shadowing or fading: P_tx + G_antenna - L - L_o2i (dBm, whole band)."""
    return (
        radio.tx_power_dbm
        + radio.antenna_gain_db
        - radio.outdoor_to_indoor_loss_db
        - path_loss_db(distance_m, radio)
    )
