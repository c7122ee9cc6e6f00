"""One row of a sweep's summary: a scenario x grid point and its finished seeds, with the
across-seed interval (Student t). A leaf: the summary (``aggregate``) and the figures (``plots``)
both read it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from uavlink.sweep.spec import BASELINE_COLUMNS

# Two-sided 95 % Student t quantiles, t(0.975, df), df = 1..30.
# fmt: off
_T975 = (
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
)
# fmt: on


def t975(df: int) -> float:
    """t(0.975, df); a Cornish-Fisher expansion beyond the table (error < 1e-3)."""
    if df < 1:
        return math.nan
    if df <= len(_T975):
        return _T975[df - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


@dataclass
class SettingRow:
    """One scenario x grid point and its finished seeds."""

    scenario: str
    point: dict[str, Any]
    expected_seeds: int
    results: list[dict[str, Any]] = field(default_factory=list)

    def column(self, policy: str) -> list[float]:
        return [r["evaluation"][policy]["mean_rate_mbps"] for r in self.results]

    @property
    def n(self) -> int:
        return len(self.results)

    def ppo_interval(self) -> tuple[float, float]:
        """(mean, 95 % half-width across seeds); half-width NaN with one seed."""
        values = self.column("ppo")
        mean = sum(values) / len(values)
        if len(values) < 2:
            return mean, math.nan
        std = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
        return mean, t975(len(values) - 1) * std / math.sqrt(len(values))

    def baseline(self, policy: str) -> float:
        values = self.column(policy)  # identical across seeds: same episodes, no training
        return sum(values) / len(values)

    def median_result(self) -> dict[str, Any]:
        """The seed whose PPO throughput is the median (the lower one of the middle two when even)."""
        ranked = sorted(
            self.results, key=lambda r: (r["evaluation"]["ppo"]["mean_rate_mbps"], r["seed"])
        )
        return ranked[(len(ranked) - 1) // 2]

    def wall_s(self) -> list[float]:
        return [r["timing"]["job_s"] for r in self.results]

    def numbers(self) -> dict[str, Any]:
        mean, hw = self.ppo_interval()
        static, oracle, aoa = (self.baseline(p) for p in BASELINE_COLUMNS)
        walls = self.wall_s()
        median = self.median_result()
        ppo = self.column("ppo")
        return {
            "scenario": self.scenario,
            **{k.split(".", 1)[1]: v for k, v in self.point.items()},
            "seeds": self.n,
            "seeds_expected": self.expected_seeds,
            "ppo_mbps": mean,
            "ppo_ci95_mbps": hw,
            "ppo_min_mbps": min(ppo),
            "ppo_max_mbps": max(ppo),
            "static_mbps": static,
            "oracle_mbps": oracle,
            "aoa_mbps": aoa,
            "gain_pct": 100 * (mean / static - 1),
            "gain_lo_pct": 100 * ((mean - hw) / static - 1),
            "gain_hi_pct": 100 * ((mean + hw) / static - 1),
            "oracle_share_pct": 100 * mean / oracle,
            "oracle_share_lo_pct": 100 * (mean - hw) / oracle,
            "oracle_share_hi_pct": 100 * (mean + hw) / oracle,
            "wall_s_mean": sum(walls) / len(walls),
            "wall_s_total": sum(walls),
            "median_seed": median["seed"],
            "median_job": median["name"],
        }
