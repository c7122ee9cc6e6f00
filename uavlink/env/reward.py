"""Reward: R_fair min-max normalised with fixed bounds (SPEC "The learning problem")."""

from __future__ import annotations

import math
from dataclasses import dataclass

from uavlink.config import EnvConfig
from uavlink.radio.noise import mean_snr_db


@dataclass(frozen=True)
class RewardBounds:
    """max = U log10(rate hovering overhead), min = U log10(rate at the far corner), no fading."""

    min_fair_rate: float
    max_fair_rate: float

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> RewardBounds:
        alt, radio = cfg.area.uav_altitude_m, cfg.radio
        far_corner_m = 2.0 * math.sqrt(2.0) * cfg.area.half_width_m  # 566 m across the diagonal

        def fair_rate_at(horizontal_m: float) -> float:
            snr_db = mean_snr_db(math.hypot(horizontal_m, alt), radio)
            rate = radio.bandwidth_hz / cfg.n_ues * math.log2(1.0 + 10.0 ** (snr_db / 10.0))
            return cfg.n_ues * math.log10(rate)

        return cls(min_fair_rate=fair_rate_at(far_corner_m), max_fair_rate=fair_rate_at(0.0))

    def normalise(self, fair_rate):
        return (fair_rate - self.min_fair_rate) / (self.max_fair_rate - self.min_fair_rate)
