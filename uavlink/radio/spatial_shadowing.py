"""Spatially consistent shadowing: one field per episode, a function of where both ends are.

S(p, q) = sigma sqrt(2/K) sum_k cos(w_k . p + v_k . q + phi_k) in dB, p the UE's and q the UAV's
horizontal position (SPEC "A spatially consistent channel"). With the wave vectors w_k and v_k drawn
independently from the 2-D spectrum of exp(-r/d) (a bivariate Cauchy) and uniform phases, the
covariance over episodes is exactly sigma^2 exp(-|dp|/d_ue) exp(-|dq|/d_uav) for any K (Gudmundson
at each end, the product ours: TR 38.901 7.6.3 gives no rule for both ends moving); K sets how far a
single episode's field departs from Gaussian. Radii are stratified in the spectrum's CDF so that even
K = 32 terms cover its heavy tail. Unlike the AR(1) model (``uavlink.radio.shadowing``), a UAV that
returns to a spot reads what it read there before: moving cannot re-roll a building's shadow.

Anchors: 3GPP TR 38.901 7.4.4 eq. 7.4-5 (exp(-dx/d_cor)), Table 7.5-6 (UMa decorrelation 37 m LOS,
50 m NLOS), 7.6.3 (spatial consistency as a 2-D random process over positions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import RadioConfig

N_TERMS = 32  # cosines per field (SPEC: K = 32)


def cauchy_wave_vectors(
    rng: np.random.Generator, n_envs: int, n_terms: int, decorrelation_m: float
) -> np.ndarray:
    """Wave vectors (N, K, 2) in rad/m from the 2-D spectrum of exp(-r/d).

    That spectrum's radial CDF is F(k) = 1 - (1 + d^2 k^2)^(-1/2), inverted at a stratified
    u in [i/K, (i+1)/K): k = sqrt((1-u)^-2 - 1) / d, at a uniform angle."""
    u = (np.arange(n_terms) + rng.random((n_envs, n_terms))) / n_terms
    radius = np.sqrt((1.0 - u) ** -2 - 1.0) / decorrelation_m
    angle = rng.uniform(-np.pi, np.pi, (n_envs, n_terms))
    return radius[..., None] * np.stack([np.cos(angle), np.sin(angle)], axis=-1)


@dataclass(frozen=True)
class SpatialShadowField:
    """One shadowing field per env: S(p, q) in dB for any UE and UAV positions.

    Phases and cosines are float32: numpy's vectorised float32 cosine is about ten times faster
    than float64's, and the field's precision needs are far below float32's (a value is a sum of 32
    cosines scaled to 8 dB). The same positions always give bit-identical values."""

    ue_wave_per_m: np.ndarray  # (N, 2, K) float32, UE-end wave vectors as columns
    uav_wave_per_m: np.ndarray  # (N, 2, K) float32
    phase_rad: np.ndarray  # (N, 1, K) float32
    amplitude_db: float  # sigma sqrt(2 / K)

    @classmethod
    def draw(
        cls, rng: np.random.Generator, n_envs: int, radio: RadioConfig, n_terms: int = N_TERMS
    ) -> SpatialShadowField:
        ue = cauchy_wave_vectors(rng, n_envs, n_terms, radio.shadowing_decorrelation_m)
        uav = cauchy_wave_vectors(rng, n_envs, n_terms, radio.shadowing_uav_decorrelation_m)
        # Pair the two ends' strata at random: with term k taking stratum k at both ends, long and
        # short waves would pair up and both ends moving would decorrelate less than the product.
        uav = np.take_along_axis(
            uav, rng.permuted(np.tile(np.arange(n_terms), (n_envs, 1)), axis=1)[..., None], axis=1
        )
        phase = rng.uniform(-np.pi, np.pi, (n_envs, 1, n_terms))
        as_columns = lambda waves: np.ascontiguousarray(waves.transpose(0, 2, 1), dtype=np.float32)  # noqa: E731
        return cls(
            as_columns(ue),
            as_columns(uav),
            phase.astype(np.float32),
            radio.shadowing_std_db * np.sqrt(2.0 / n_terms),
        )

    def shadow_db(self, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> np.ndarray:
        """Shadowing (N, U, D) in dB of every link, for UAVs (N, D, 2) and UEs (N, U, 2)."""
        uav_phase = uav_xy_m.astype(np.float32) @ self.uav_wave_per_m + self.phase_rad  # (N, D, K)
        if uav_phase.shape[1] == 1:
            # One UAV, the hot path of training: its phase rides in the same matrix product as the
            # UEs' ([p, 1] @ [w; phase]), with no (N, U, D, K) temporary.
            ue = np.concatenate(
                [ue_xy_m.astype(np.float32), np.ones((*ue_xy_m.shape[:2], 1), np.float32)], axis=2
            )
            phase = (ue @ np.concatenate([self.ue_wave_per_m, uav_phase], axis=1))[:, :, None, :]
        else:
            ue_phase = ue_xy_m.astype(np.float32) @ self.ue_wave_per_m  # (N, U, K)
            phase = ue_phase[:, :, None, :] + uav_phase[:, None, :, :]
        np.cos(phase, out=phase)
        # A plain sum, not a product with ones: BLAS may round rows differently, and two UAVs over
        # one spot must read the same value.
        return self.amplitude_db * phase.sum(axis=-1).astype(np.float64)
