"""How much a memory of place is worth on which channel.

On the spatial channel with the shadowing's std (``radio.shadowing_std_db``, 4 and 8 dB) and its
UAV-end decorrelation distance (``radio.shadowing_uav_decorrelation_m``, 25, 50 and 100 m) set by
radio overrides, each of ``genie`` (the full-knowledge limit), ``explore`` (the GPS-free rule), the
scenario's map policy (trained at 8 dB and 50 m) and its spatial policy flies the same seeded
episodes as ``static``; each one's throughput over static's comes with a 95 % paired-bootstrap
interval. A short decorrelation makes spots close together differ (a map finds a good one nearby); a
long one makes the field smooth (little to find); sigma scales what there is to find.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from pathlib import Path

from uavlink.evaluation.core import evaluate_policy, paired_ratio_ci
from uavlink.evaluation.tables import gain_cell, spatial_overrides
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.loader import policy_for_scenario

SIGMAS_DB = (4.0, 8.0)
UAV_DECORRELATIONS_M = (25.0, 50.0, 100.0)
POLICIES = ("genie", "explore", "map", "spatial")
SENSITIVITY_SCENARIOS = ("no_move", "circular")


def sensitivity(
    map_folder: Path,
    spatial_folder: Path,
    episodes: int,
    seed: int,
    scenarios: tuple[str, ...] | list[str] = SENSITIVITY_SCENARIOS,
    progress: Callable[[str], None] = lambda _: None,
    base: EnvOverrides | None = None,
) -> dict:
    """One row per (scenario, sigma, decorrelation): static's Mbps and each policy's over static's;
    ``base`` is what else the command line overrides (the channel's two settings win)."""
    base = base or EnvOverrides()
    rows = []
    for scenario, sigma_db, decorrelation_m in itertools.product(
        scenarios, SIGMAS_DB, UAV_DECORRELATIONS_M
    ):
        overrides = spatial_overrides(
            EnvOverrides(
                scenario,
                base.aoa_noise_deg,
                {
                    **base.settings,
                    "radio.shadowing_std_db": sigma_db,
                    "radio.shadowing_uav_decorrelation_m": decorrelation_m,
                },
            )
        )
        specs: dict[str, str | Path] = {
            "static": "static",
            "genie": "genie",
            "explore": "explore",
            "map": policy_for_scenario(map_folder, scenario),
            "spatial": policy_for_scenario(spatial_folder, scenario),
        }
        loaded = dict(zip(specs, load_with_env(list(specs.values()), overrides), strict=True))
        rates = {}
        for name, (policy, cfg) in loaded.items():
            progress(f"sensitivity {scenario} sigma {sigma_db:g} dB, {decorrelation_m:g} m: {name}")
            rates[name] = evaluate_policy(policy, cfg, episodes, seed).episode_rate_mbps
        row = {
            "scenario": scenario,
            "shadowing_std_db": sigma_db,
            "uav_decorrelation_m": decorrelation_m,
            "static_mbps": round(float(rates["static"].mean()), 4),
        }
        for name in POLICIES:
            ratio, lo, hi = paired_ratio_ci(rates[name], rates["static"])
            row[name] = {
                "mbps": round(float(rates[name].mean()), 4),
                "over_static": round(ratio, 4),
                "ci95": [round(lo, 4), round(hi, 4)],
            }
        rows.append(row)
    return {
        "episodes": episodes,
        "seed": seed,
        "statistic": "mean throughput over static's on the same episodes, 95 % paired bootstrap",
        "rows": rows,
    }


def sensitivity_table(report: dict) -> str:
    """The rows as a Markdown table: each policy's gain over static with its interval."""
    lines = [
        "| scenario | sigma (dB) | UAV-end decorrelation (m) | static Mbps | "
        + " | ".join(POLICIES)
        + " |",
        "|---|---:|---:|---:|" + "---|" * len(POLICIES),
    ]
    for r in report["rows"]:
        cells = [gain_cell(r[p]["over_static"], *r[p]["ci95"]) for p in POLICIES]
        lines.append(
            f"| {r['scenario']} | {r['shadowing_std_db']:g} | {r['uav_decorrelation_m']:g} | "
            f"{r['static_mbps']:.2f} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines)
