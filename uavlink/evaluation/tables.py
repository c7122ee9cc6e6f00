"""The results report's tables, below its parts (``report``, ``report_spatial``, ``report_fleet``):
the paper's Table I and II figures, one row of evaluations per scenario, Table I and II from them, the
Markdown and CSV writers, and the command line's overrides on the spatial channel. A leaf of the
package: it imports no report module, so the parts import it and not each other."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavlink.config import MIXED, EnvConfig
from uavlink.evaluation.core import EvalResult, evaluate_policy, paired_ratio_ci
from uavlink.mobility import SCENARIOS
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.loader import policy_file


@dataclass(frozen=True)
class ReportRun:
    """What every part of one results report shares: the seeded episodes each cell flies
    (``episodes`` from ``seed`` under ``overrides``), the folder its files go to (``out``), the
    Markdown file that links them, where progress is told and how many processes the fleet part's
    evaluations may use (``workers``; the figures do not depend on it)."""

    episodes: int
    seed: int
    overrides: EnvOverrides
    out: Path
    markdown: Path
    progress: Callable[[str], None] = lambda _: None
    workers: int = 1

    @property
    def rel(self) -> Path:
        """``out`` as the Markdown links it (seen from its folder)."""
        return Path(os.path.relpath(self.out, self.markdown.parent))


# The paper's Table I (PPO, static) and Table II (straight under AoA noise), Mbps (SPEC).
PAPER_TABLE_ONE = {
    "no_move": (8.00, 7.95),
    "straight": (7.87, 4.59),
    "circular": (7.08, 3.59),
    "straight_90": (6.27, 5.33),
    "straight_180": (5.91, 5.31),
    "hotspot": (5.19, 4.77),
}
PAPER_TABLE_TWO = {0: 7.87, 1: 7.84, 5: 7.82, 10: 7.80, 50: 7.70, 100: 7.16}


@dataclass
class ScenarioRow:
    scenario: str
    results: dict[str, EvalResult]  # by column: ppo, static, oracle, aoa (+ ppo_mixed)
    cfg: EnvConfig  # the env of the scenario's policy, which the baselines flew too

    def target_mbps(self) -> tuple[float, str]:
        """The SPEC's per-scenario target for PPO and which rule set it."""
        paper_ppo, paper_static = PAPER_TABLE_ONE[self.scenario]
        static = self.results["static"].mean_rate_mbps
        oracle = self.results["oracle"].mean_rate_mbps
        by_gain = static * paper_ppo / paper_static
        if by_gain <= oracle:
            return max(by_gain, 0.9 * oracle), "paper gain"
        return max(min(paper_ppo, 0.95 * oracle), 0.9 * oracle), "min(paper PPO, 95% oracle)"


# Table I's baselines (SPEC; the paper's static and oracle, and our aoa rule), in its column order:
# the report's table and a sweep's evaluate the same ones.
TABLE_ONE_BASELINES = ("static", "oracle", "aoa")


def evaluate_scenarios(
    policy_folder: Path,
    episodes: int,
    seed: int,
    overrides: EnvOverrides,
    progress: Callable[[str], None] = lambda _: None,
    extra: tuple[str, ...] = (),
) -> list[ScenarioRow]:
    """Per scenario: its policy, the baselines in that policy's env (and the ``extra`` ones, e.g. the
    genie on the spatial channel), and the mixed policy if any."""
    rows = []
    mixed = policy_file(policy_folder, MIXED)
    columns: dict[str, str | Path] = {
        "ppo": policy_folder,
        **{name: name for name in (*TABLE_ONE_BASELINES, *extra)},
        **({"ppo_mixed": mixed} if mixed is not None else {}),
    }
    for scenario in SCENARIOS:
        loaded = load_with_env(list(columns.values()), overrides.on(scenario))
        results = {}
        for column, (policy, cfg) in zip(columns, loaded, strict=True):
            progress(f"{scenario}: {column}")
            keep = column not in ("ppo_mixed", *extra)
            results[column] = evaluate_policy(policy, cfg, episodes, seed, record_trajectory=keep)
        rows.append(ScenarioRow(scenario, results, loaded[0][1]))
    return rows


def table_one(rows: list[ScenarioRow]) -> tuple[list[str], list[list[str]]]:
    has_mixed, has_genie = "ppo_mixed" in rows[0].results, "genie" in rows[0].results
    header = [
        "scenario",
        "PPO",
        *TABLE_ONE_BASELINES,
        *(["genie"] if has_genie else []),
        *(["PPO mixed"] if has_mixed else []),
        "gain over static",
        "paper gain",
        "PPO / oracle",
        *(["PPO / genie"] if has_genie else []),
        "PPO vs aoa",
        "R_fair PPO / static / oracle / aoa",
        "target",
        "met",
    ]
    body = []
    for row in rows:
        r = row.results
        ppo, static, oracle = (r[k].episode_rate_mbps for k in ("ppo", "static", "oracle"))
        gain, glo, ghi = paired_ratio_ci(ppo, static)
        share, slo, shi = paired_ratio_ci(ppo, oracle)
        vs_aoa, alo, ahi = paired_ratio_ci(ppo, r["aoa"].episode_rate_mbps)
        paper_ppo, paper_static = PAPER_TABLE_ONE[row.scenario]
        target, rule = row.target_mbps()

        def cell(key: str, r: dict[str, EvalResult] = r) -> str:
            return f"{r[key].mean_rate_mbps:.2f} ± {r[key].ci95_mbps:.2f}"

        body.append(
            [
                row.scenario,
                cell("ppo"),
                *(cell(b) for b in TABLE_ONE_BASELINES),
                *([cell("genie")] if has_genie else []),
                *([cell("ppo_mixed")] if has_mixed else []),
                gain_cell(gain, glo, ghi),
                f"{100 * (paper_ppo / paper_static - 1):+.1f} %",
                share_cell(share, slo, shi),
                *([_share(ppo, r["genie"].episode_rate_mbps)] if has_genie else []),
                gain_cell(vs_aoa, alo, ahi),
                " / ".join(f"{r[k].mean_fair_rate:.2f}" for k in ("ppo", *TABLE_ONE_BASELINES)),
                f"{target:.2f} ({rule})",
                "yes" if r["ppo"].mean_rate_mbps >= target else "no",
            ]
        )
    return header, body


def gain_cell(ratio: float, lo: float, hi: float) -> str:
    """A ratio with its interval as a gain: 1.021 [1.015, 1.027] -> "+2.1 % [+1.5, +2.7]"."""
    return f"{100 * (ratio - 1):+.1f} % [{100 * (lo - 1):+.1f}, {100 * (hi - 1):+.1f}]"


def share_cell(ratio: float, lo: float, hi: float) -> str:
    """A ratio with its interval as a share: 0.724 [0.702, 0.746] -> "72.4 % [70.2, 74.6]"."""
    return f"{100 * ratio:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}]"


def _share(num: np.ndarray, den: np.ndarray) -> str:
    return share_cell(*paired_ratio_ci(num, den))


def table_two(
    policy_folder: Path, episodes: int, seed: int, overrides: EnvOverrides
) -> tuple[list[str], list[list[str]]]:
    header = ["AoA noise std (deg)", "PPO (Mbps)", "drop from 0 deg", "paper (Mbps)", "paper drop"]
    body, clean = [], None
    for std, paper in PAPER_TABLE_TWO.items():
        noisy = EnvOverrides("straight", float(std), overrides.settings)
        [(policy, cfg)] = load_with_env([policy_folder], noisy)
        result = evaluate_policy(policy, cfg, episodes, seed)
        clean = result.mean_rate_mbps if clean is None else clean
        body.append(
            [
                str(std),
                f"{result.mean_rate_mbps:.2f} ± {result.ci95_mbps:.2f}",
                f"{clean - result.mean_rate_mbps:.2f}",
                f"{paper:.2f}",
                f"{PAPER_TABLE_TWO[0] - paper:.2f}",
            ]
        )
    return header, body


def markdown_table(header: list[str], body: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in body]
    return "\n".join(lines)


def write_csv(path: Path, header: list[str], body: list[list[str]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(body)


SPATIAL = {"radio.shadowing_model": "spatial"}


def spatial_overrides(overrides: EnvOverrides) -> EnvOverrides:
    """The command line's overrides on the spatial channel (a radio override: allowed for any policy)."""
    return EnvOverrides(
        overrides.scenario, overrides.aoa_noise_deg, {**overrides.settings, **SPATIAL}
    )
