"""Rician fast fading, drawn per resource block per frame.

The power gain of one RB is |h|^2 with h = sqrt(K/(K+1)) + sqrt(1/(K+1)) z, z ~ CN(0, 1), so
E|h|^2 = 1. Written with real normals x, y: |h|^2 = ((x + nu)^2 + y^2) / (2 (K+1)), nu = sqrt(2K),
i.e. a scaled non-central chi-square with 2 degrees of freedom.
"""

from __future__ import annotations

import numpy as np


def rician_power_gain(rng: np.random.Generator, shape: tuple[int, ...], k_db: float) -> np.ndarray:
    """Independent per-RB power gains |h|^2 (mean 1) of the given shape."""
    k = 10.0 ** (k_db / 10.0)
    x = rng.standard_normal(shape) + np.sqrt(2.0 * k)
    y = rng.standard_normal(shape)
    return (x * x + y * y) / (2.0 * (k + 1.0))


def mean_rician_power_gain(
    rng: np.random.Generator, shape: tuple[int, ...], n_rbs: np.ndarray, k_db: float
) -> np.ndarray:
    """Mean of ``n_rbs`` independent per-RB gains |h|^2, drawn exactly in one go.

    The sum of n per-RB gains times 2(K+1) is non-central chi-square with 2n degrees of freedom
    and non-centrality 2nK, which equals (z + sqrt(2nK))^2 + 2 Gamma(n - 1/2) with z ~ N(0, 1).
    Drawing that instead of 2n normals gives the same distribution of the effective (RB-averaged)
    SINR for a link without interference, about 5x faster at 5 RBs per UE. ``n_rbs`` broadcasts
    against the trailing axes of ``shape``.
    """
    k = 10.0 ** (k_db / 10.0)
    n = np.broadcast_to(np.asarray(n_rbs, dtype=float), shape)
    z = rng.standard_normal(shape) + np.sqrt(2.0 * n * k)
    chi2 = 2.0 * rng.standard_gamma(n - 0.5, size=shape)
    return (z * z + chi2) / (2.0 * n * (k + 1.0))
