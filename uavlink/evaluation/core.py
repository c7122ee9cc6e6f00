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
from uavlink.policies.contract import check_policy_env
from uavlink.rollout import chunks
from uavlink.seeding import EVAL


@dataclass
class Trajectory:
    """Positions over one episode (frames + 1 entries, the start included), for plots."""

    uav_xy_m: np.ndarray  # (T+1, D, 2)
    ue_xy_m: np.ndarray  # (T+1, U, 2)
    rate_mbps: np.ndarray  # (T,) mean UE rate per frame
    serving: np.ndarray  # (T+1, U) each UE's UAV


@dataclass
class _Tally:
    """Per-episode sums over the frames of one chunk (n envs, U UEs, D UAVs)."""

    rate_mbps: list = field(default_factory=list)
    fair: list = field(default_factory=list)
    jain: list = field(default_factory=list)
    ue_rate_mbps: list = field(default_factory=list)
    cell_size: list = field(default_factory=list)

    def add(self, result, readings, n_uavs: int) -> None:
        rate = readings.rate_bps
        self.rate_mbps.append(result.mean_rate_mbps)
        self.fair.append(result.fair_rate)
        self.jain.append(rate.sum(axis=1) ** 2 / (rate.shape[1] * (rate**2).sum(axis=1)))
        self.ue_rate_mbps.append(rate * 1e-6)
        cells = (readings.serving[:, :, None] == np.arange(n_uavs)).sum(axis=1)
        # busiest first: a UAV's index says nothing of its role, which moves between UAVs from
        # episode to episode (a lead teacher's leader is whichever serves most)
        self.cell_size.append(-np.sort(-cells, axis=1))


@dataclass
class EvalResult:
    """What ``evaluate_policy`` measured: ``episodes`` seeded episodes (E) of ``scenario`` flown by
    ``policy`` (its name), from ``seed`` on the ``EVAL`` stream, with AoA noise ``aoa_noise_deg``
    (deg, the env's std). Per episode, means over its frames:

    * ``episode_rate_mbps`` (E,): the mean UE rate, Mbit/s (a UE's rate is its round-robin share of
      the band's Shannon rate at its SINR); ``mean_rate_mbps`` is their mean, the throughput every
      table reports, and ``ci95_mbps`` the half-width of its 95 % interval, Mbit/s;
    * ``episode_fair_rate`` (E,): R_fair, the sum over the UEs of log10 of each UE's rate in bit/s
      (proportional fairness, what the reward normalises: ``uavlink.env.reward``), dimensionless;
      ``mean_fair_rate`` is their mean (10 UEs at 1 Mbit/s each: 60);
    * ``episode_jain`` (E,): Jain's index of the UE rates, 1/U to 1 (``jain_index``: the mean);
    * ``ue_rate_mbps`` (E, U): each UE's mean rate, Mbit/s (``p5_ue_rate_mbps``: the 5th percentile);
    * ``episode_ues_per_uav`` (E, D): UEs the busiest UAV of each frame serves, the next busiest,
      and so on (``ues_per_uav``: their means), which says how a fleet shares the team whichever
      UAV takes which role.

    ``trajectory``: episode 0's positions when asked for (``record_trajectory``), else None."""

    scenario: str
    policy: str
    episodes: int
    seed: int
    aoa_noise_deg: float
    episode_rate_mbps: np.ndarray
    episode_fair_rate: np.ndarray
    episode_jain: np.ndarray  # (E,) Jain's index of the UE rates, mean over frames
    ue_rate_mbps: np.ndarray  # (E, U) each UE's mean rate over its episode
    episode_ues_per_uav: np.ndarray  # (E, D) UEs per UAV, busiest first, mean over frames
    trajectory: Trajectory | None = field(default=None, repr=False)

    @property
    def mean_rate_mbps(self) -> float:
        """The mean UE rate, Mbit/s, mean over frames and episodes."""
        return float(self.episode_rate_mbps.mean())

    @property
    def ci95_mbps(self) -> float:
        """Half-width of the 95 % normal-approximation interval of the mean over episodes."""
        n = len(self.episode_rate_mbps)
        return 0.0 if n < 2 else float(1.96 * self.episode_rate_mbps.std(ddof=1) / math.sqrt(n))

    @property
    def mean_fair_rate(self) -> float:
        """R_fair (sum over UEs of log10 of the rate in bit/s), mean over frames and episodes."""
        return float(self.episode_fair_rate.mean())

    @property
    def jain_index(self) -> float:
        """Jain's fairness index of the UE rates, (sum r)^2 / (U sum r^2), mean over frames and episodes."""
        return float(self.episode_jain.mean())

    @property
    def p5_ue_rate_mbps(self) -> float:
        """5th percentile of the UEs' mean rates over their episodes (the cell-edge rate)."""
        return float(np.percentile(self.ue_rate_mbps, 5))

    @property
    def ues_per_uav(self) -> np.ndarray:
        """(D,) UEs the busiest UAV serves, the next busiest, ...: means over frames and episodes."""
        return self.episode_ues_per_uav.mean(axis=0)

    def to_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "policy": self.policy,
            "episodes": self.episodes,
            "seed": self.seed,
            "aoa_noise_deg": self.aoa_noise_deg,
            "mean_rate_mbps": round(self.mean_rate_mbps, 6),
            "ci95_mbps": round(self.ci95_mbps, 6),
            "mean_fair_rate": round(self.mean_fair_rate, 6),
            "episode_rate_mbps": [round(float(x), 6) for x in self.episode_rate_mbps],
            "jain_index": round(self.jain_index, 6),
            "p5_ue_rate_mbps": round(self.p5_ue_rate_mbps, 6),
            "ues_per_uav": [round(float(x), 4) for x in self.ues_per_uav],
        }


def evaluate_policy(
    policy: Policy,
    cfg: EnvConfig,
    episodes: int = 100,
    seed: int = 0,
    record_trajectory: bool = False,
) -> EvalResult:
    """Run ``episodes`` seeded episodes; the trajectory of episode 0 is kept on request. ``cfg`` must
    be the env ``policy`` was built for (``uavlink.policies.contract.check_policy_env``): a policy
    file's manifest env (``load_with_env``) with world changes only, a baseline's
    ``registry.baseline_env``; otherwise a one-line ``UserError`` says how to get it."""
    check_policy_env(policy, cfg.validate())
    per_chunk, trajectory, d = [], None, cfg.n_uavs
    for chunk in chunks(cfg, EVAL, episodes, seed):
        keep = record_trajectory and chunk.index == 0
        env = chunk.env
        assert env.mobility is not None and env.readings is not None  # the chunk's env is reset
        uav, ue, serving = (
            [env.uav_xy_m[:d].copy()],
            [env.mobility.position_m[0].copy()],
            [env.readings.serving[0].copy()],
        )
        tally = _Tally()
        for frame in chunk.frames(policy):
            tally.add(frame.result, env.readings, d)
            if keep:
                uav.append(env.uav_xy_m[:d].copy())
                ue.append(env.mobility.position_m[0].copy())
                serving.append(env.readings.serving[0].copy())
        per_chunk.append({k: np.mean(v, axis=0) for k, v in vars(tally).items()})
        if keep:
            rate = np.array(tally.rate_mbps)[:, 0]
            trajectory = Trajectory(np.array(uav), np.array(ue), rate, np.array(serving))
    joined = {k: np.concatenate([c[k] for c in per_chunk]) for k in per_chunk[0]}
    return EvalResult(
        cfg.scenario,
        policy.name,
        episodes,
        seed,
        cfg.radio.aoa_noise_deg,
        joined["rate_mbps"],
        joined["fair"],
        joined["jain"],
        joined["ue_rate_mbps"],
        joined["cell_size"],
        trajectory,
    )


def paired_ratio_ci(
    num: np.ndarray, den: np.ndarray, n_boot: int = 2000
) -> tuple[float, float, float]:
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
        return (
            f"{self.scenario}: {self.a} vs {self.b}: throughput {100 * (ratio - 1):+.2f} % "
            f"[{100 * (lo - 1):+.2f}, {100 * (hi - 1):+.2f}] (95 %, paired over {self.episodes} episodes), "
            f"R_fair {self.fair_rate_difference:+.3f}, better in {self.a_better_episodes} of {self.episodes} episodes"
        )

    def to_dict(self) -> dict[str, Any]:
        ratio, lo, hi = self.throughput_ratio
        return {
            "scenario": self.scenario,
            "a": self.a,
            "b": self.b,
            "episodes": self.episodes,
            "throughput_ratio": round(ratio, 6),
            "throughput_ratio_ci95": [round(lo, 6), round(hi, 6)],
            "fair_rate_difference": round(self.fair_rate_difference, 6),
            "a_better_episodes": self.a_better_episodes,
        }


def compare(a: EvalResult, b: EvalResult) -> PairedComparison:
    """Pair two evaluations episode by episode; they must have flown the same episodes."""
    if (a.scenario, a.episodes, a.seed, a.aoa_noise_deg) != (
        b.scenario,
        b.episodes,
        b.seed,
        b.aoa_noise_deg,
    ):
        raise ValueError(f"cannot pair {a.policy!r} and {b.policy!r}: they flew different episodes")
    return PairedComparison(
        a.scenario,
        a.policy,
        b.policy,
        a.episodes,
        paired_ratio_ci(a.episode_rate_mbps, b.episode_rate_mbps),
        a.mean_fair_rate - b.mean_fair_rate,
        int((a.episode_rate_mbps > b.episode_rate_mbps).sum()),
    )
