"""Seeded, batched evaluation of any policy on a scenario.

Episodes come from the ``EVAL`` stream (``uavlink.seeding``, run by ``uavlink.rollout``), so results
depend on nothing but (policy, config, episodes, seed). The SITL radio payload uses chunk 0's seed,
so ``fly --seed S`` meets the same UE trajectories as episode 0 here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from uavlink.config import EnvConfig
from uavlink.policies.base import Policy
from uavlink.rollout import chunks
from uavlink.seeding import EVAL


@dataclass
class Trajectory:
    """Positions over one episode (frames + 1 entries, the start included), for plots."""

    uav_xy_m: np.ndarray  # (T+1, 2)
    ue_xy_m: np.ndarray  # (T+1, U, 2)
    rate_mbps: np.ndarray  # (T,) mean UE rate per frame


@dataclass
class EvalResult:
    scenario: str
    policy: str
    episodes: int
    seed: int
    aoa_noise_deg: float
    episode_rate_mbps: np.ndarray
    episode_fair_rate: np.ndarray
    trajectory: Trajectory | None = field(default=None, repr=False)

    @property
    def mean_rate_mbps(self) -> float:
        return float(self.episode_rate_mbps.mean())

    @property
    def ci95_mbps(self) -> float:
        """Half-width of the 95 % normal-approximation interval of the mean over episodes."""
        n = len(self.episode_rate_mbps)
        return 0.0 if n < 2 else float(1.96 * self.episode_rate_mbps.std(ddof=1) / math.sqrt(n))

    @property
    def mean_fair_rate(self) -> float:
        return float(self.episode_fair_rate.mean())

    def to_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario, "policy": self.policy, "episodes": self.episodes,
            "seed": self.seed, "aoa_noise_deg": self.aoa_noise_deg,
            "mean_rate_mbps": round(self.mean_rate_mbps, 6), "ci95_mbps": round(self.ci95_mbps, 6),
            "mean_fair_rate": round(self.mean_fair_rate, 6),
            "episode_rate_mbps": [round(float(x), 6) for x in self.episode_rate_mbps],
        }


def evaluate_policy(policy: Policy, cfg: EnvConfig, episodes: int = 100, seed: int = 0,
                    record_trajectory: bool = False) -> EvalResult:
    """Run ``episodes`` seeded episodes; the trajectory of episode 0 is kept on request."""
    rates, fairs, trajectory = [], [], None
    for chunk in chunks(cfg, EVAL, episodes, seed):
        keep = record_trajectory and chunk.index == 0
        uav, ue = [chunk.env.uav_xy_m[0].copy()], [chunk.env.mobility.position_m[0].copy()]
        frame_rates, frame_fair = [], []
        for frame in chunk.frames(policy):
            frame_rates.append(frame.result.mean_rate_mbps)
            frame_fair.append(frame.result.fair_rate)
            if keep:
                uav.append(frame.env.uav_xy_m[0].copy())
                ue.append(frame.env.mobility.position_m[0].copy())
        rates.append(np.mean(frame_rates, axis=0))
        fairs.append(np.mean(frame_fair, axis=0))
        if keep:
            trajectory = Trajectory(np.array(uav), np.array(ue), np.array(frame_rates)[:, 0])
    return EvalResult(cfg.scenario, policy.name, episodes, seed, cfg.radio.aoa_noise_deg,
                      np.concatenate(rates), np.concatenate(fairs), trajectory)


def paired_ratio_ci(num: np.ndarray, den: np.ndarray, n_boot: int = 2000) -> tuple[float, float, float]:
    """mean(num)/mean(den) with a 95 % paired-bootstrap interval (episodes share seeds)."""
    rng = np.random.default_rng(0)
    idx = rng.integers(0, len(num), size=(n_boot, len(num)))
    ratios = num[idx].mean(axis=1) / den[idx].mean(axis=1)
    lo, hi = np.percentile(ratios, [2.5, 97.5])
    return float(num.mean() / den.mean()), float(lo), float(hi)


@dataclass(frozen=True)
class PairedComparison:
    """Policy ``a`` against policy ``b`` over the same seeded episodes."""

    scenario: str
    a: str
    b: str
    episodes: int
    throughput_ratio: tuple[float, float, float]  # mean(a)/mean(b), 95 % paired-bootstrap interval
    fair_rate_difference: float  # mean R_fair of a minus that of b
    a_better_episodes: int  # episodes where a's throughput beats b's

    def describe(self) -> str:
        ratio, lo, hi = self.throughput_ratio
        return (f"{self.scenario}: {self.a} vs {self.b}: throughput {100 * (ratio - 1):+.2f} % "
                f"[{100 * (lo - 1):+.2f}, {100 * (hi - 1):+.2f}] (95 %, paired over {self.episodes} episodes), "
                f"R_fair {self.fair_rate_difference:+.3f}, better in {self.a_better_episodes} of {self.episodes} episodes")

    def to_dict(self) -> dict[str, Any]:
        ratio, lo, hi = self.throughput_ratio
        return {"scenario": self.scenario, "a": self.a, "b": self.b, "episodes": self.episodes,
                "throughput_ratio": round(ratio, 6), "throughput_ratio_ci95": [round(lo, 6), round(hi, 6)],
                "fair_rate_difference": round(self.fair_rate_difference, 6),
                "a_better_episodes": self.a_better_episodes}


def compare(a: EvalResult, b: EvalResult) -> PairedComparison:
    """Pair two evaluations episode by episode; they must have flown the same episodes."""
    if (a.scenario, a.episodes, a.seed, a.aoa_noise_deg) != (b.scenario, b.episodes, b.seed, b.aoa_noise_deg):
        raise ValueError(f"cannot pair {a.policy!r} and {b.policy!r}: they flew different episodes")
    return PairedComparison(a.scenario, a.policy, b.policy, a.episodes,
                            paired_ratio_ci(a.episode_rate_mbps, b.episode_rate_mbps),
                            a.mean_fair_rate - b.mean_fair_rate,
                            int((a.episode_rate_mbps > b.episode_rate_mbps).sum()))
