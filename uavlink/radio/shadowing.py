"""Log-normal shadowing, time-correlated per link (Gudmundson 1991).

Each UE-UAV link carries a Gaussian shadow value S (dB) with std ``sigma``. Between frames it follows
the AR(1) update S' = rho S + sqrt(1 - rho^2) sigma n with rho = exp(-delta / d_corr), where delta is
the link's combined UE + UAV displacement (m) and d_corr the decorrelation distance (50 m).
"""

from __future__ import annotations

import numpy as np

from uavlink.config import RadioConfig


def initial_shadowing_db(
    rng: np.random.Generator, shape: tuple[int, ...], radio: RadioConfig
) -> np.ndarray:
    """Stationary draw of the shadow values, shape (..., U, D); zeros when shadowing is off."""
    if not radio.shadowing:
        return np.zeros(shape)
    return rng.standard_normal(shape) * radio.shadowing_std_db


def update_shadowing_db(
    rng: np.random.Generator,
    shadow_db: np.ndarray,
    displacement_m: np.ndarray,
    radio: RadioConfig,
) -> np.ndarray:
    """Advance the shadow values (..., U, D) given each link's displacement (..., U, D) in metres."""
    if not radio.shadowing:
        return shadow_db
    rho = np.exp(-displacement_m / radio.shadowing_decorrelation_m)
    innovation = rng.standard_normal(shadow_db.shape)
    return rho * shadow_db + np.sqrt(1.0 - rho * rho) * radio.shadowing_std_db * innovation
