"""Angle of arrival of the UEs' reference signals at the UAV, and circular statistics.

Angles are degrees counter-clockwise from east (the env frame), wrapped to [-180, 180).
"""

from __future__ import annotations

import numpy as np


def wrap_deg(angle_deg: np.ndarray | float) -> np.ndarray:
    """Wrap to [-180, 180)."""
    wrapped = (np.asarray(angle_deg) + 180.0) % 360.0 - 180.0
    # x % 360 rounds to 360.0 for x a hair below 0 (e.g. -1e-13), which would give +180.
    return wrapped - 360.0 * (wrapped >= 180.0)


def true_aoa_deg(uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> np.ndarray:
    """Azimuth of each UE seen from its UAV: positions (..., U, 2), broadcasting -> (..., U)."""
    delta = ue_xy_m - uav_xy_m
    return np.degrees(np.arctan2(delta[..., 1], delta[..., 0]))


def measured_aoa_deg(
    rng: np.random.Generator, true_deg: np.ndarray, noise_std_deg: float | np.ndarray
) -> np.ndarray:
    """AoA estimate: truth plus Gaussian noise of ``noise_std_deg`` (a scalar, or per env
    broadcasting against ``true_deg``), wrapped to [-180, 180)."""
    if np.any(np.asarray(noise_std_deg) > 0.0):
        true_deg = true_deg + noise_std_deg * rng.standard_normal(true_deg.shape)
    return wrap_deg(true_deg)


def circular_mean_std_deg(
    angle_deg: np.ndarray, mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Circular mean and std over the last axis (degrees), over the entries ``mask`` keeps when given.

    Mean = atan2(mean sin, mean cos); std = sqrt(-2 ln R) with R the mean resultant length (as
    scipy.stats.circstd). A naive mean of 179 and -179 gives 0; this gives -180. With no entry kept
    the mean is NaN and the std the largest the clip allows.
    """
    rad = np.radians(angle_deg)
    return circular_stats_deg(np.sin(rad), np.cos(rad), mask)


def circular_stats_deg(
    sin: np.ndarray, cos: np.ndarray, mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``circular_mean_std_deg`` from the angles' sines and cosines, so that several statistics of
    one set of angles (all UEs', one cell's) share one evaluation of the trigonometry."""
    if mask is None:
        s = sin.mean(axis=-1)
        c = cos.mean(axis=-1)
    else:
        count = mask.sum(axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            s = (sin * mask).sum(axis=-1) / count
            c = (cos * mask).sum(axis=-1) / count
    mean = wrap_deg(np.degrees(np.arctan2(s, c)))
    resultant = np.minimum(np.fmax(np.hypot(s, c), 1e-12), 1.0)  # fmax: an empty set's NaN -> 1e-12
    std = np.degrees(np.sqrt(-2.0 * np.log(resultant)))
    return mean, std
