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


def bearing_fix_xy_m(uav_xy_m: np.ndarray, aoa_deg: np.ndarray, ridge: float = 1e-6) -> np.ndarray:
    """Where each UE is, from the bearings several UAVs hear of it: the point nearest (least squares)
    to every UAV's line of bearing. ``uav_xy_m`` (N, D, 2), ``aoa_deg`` (N, D, U) -> (N, U, 2).

    Each line contributes its normal projector ``I - e e^T`` (``e`` the bearing's unit vector); the
    normal equations sum them. Where the lines are (nearly) parallel, a UE in line with the UAVs, the
    ``ridge`` pulls the fix towards the UAVs' centroid along the line, so it stays finite; with
    exact bearings from two UAVs not in line with the UE the fix is the UE's position. Pure
    geometry on what the fleet senses (positions of its own UAVs, AoAs): no UE GPS."""
    rad = np.radians(aoa_deg)
    e = np.stack([np.cos(rad), np.sin(rad)], axis=-1)  # (N, D, U, 2)
    normal = np.eye(2) - e[..., :, None] * e[..., None, :]  # (N, D, U, 2, 2)
    centroid = uav_xy_m.mean(axis=1)  # (N, 2)
    a = normal.sum(axis=1) + ridge * np.eye(2)  # (N, U, 2, 2)
    b = np.einsum("ndukl,ndl->nuk", normal, uav_xy_m) + ridge * centroid[:, None, :]
    det = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    x = (a[..., 1, 1] * b[..., 0] - a[..., 0, 1] * b[..., 1]) / det
    y = (a[..., 0, 0] * b[..., 1] - a[..., 1, 0] * b[..., 0]) / det
    return np.stack([x, y], axis=-1)
