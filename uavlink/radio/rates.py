"""Round-robin scheduling, per-UE rates and the fair rate (paper eqs. 5-6)."""

from __future__ import annotations

import numpy as np


def round_robin_rbs(n_rbs: int, n_ues: int) -> np.ndarray:
    """RBs per UE per frame when RB k goes to UE k mod U: (U,) counts summing to ``n_rbs``."""
    counts = np.full(n_ues, n_rbs // n_ues)
    counts[: n_rbs % n_ues] += 1
    return counts


def rate_bps(sinr_eff_linear: np.ndarray, bandwidth_hz: float, n_ues: int) -> np.ndarray:
    """R_u = (B / U) log2(1 + SINR_eff): each UE gets 1/U of the band on average."""
    return (bandwidth_hz / n_ues) * np.log2(1.0 + sinr_eff_linear)


def fair_rate(rate_bps_per_ue: np.ndarray) -> np.ndarray:
    """R_fair = sum_u log10(R_u), R_u in bit/s, over the last axis (proportional fairness)."""
    return np.log10(np.maximum(rate_bps_per_ue, 1.0)).sum(axis=-1)
