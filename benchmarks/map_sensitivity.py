"""How much a memory of place is worth on which channel (issue 23's sensitivity table).

On the spatial channel with the shadowing's std (``radio.shadowing_std_db``, 4 and 8 dB) and its
UAV-end decorrelation distance (``radio.shadowing_uav_decorrelation_m``, 25, 50 and 100 m) set by
radio overrides, each of ``genie`` (the full-knowledge limit), ``explore`` (the GPS-free rule), the
scenario's map policy (``policies/map/<scenario>.zip``, trained at 8 dB and 50 m) and the spatial
policy (``policies/spatial/<scenario>.zip``) flies the same seeded episodes as ``static``; the table
gives each one's throughput over static's with a 95 % paired-bootstrap interval. A short
decorrelation makes spots close together differ (a map finds a good one nearby); a long one makes
the field smooth (little to find); sigma scales what there is to find.

    python benchmarks/map_sensitivity.py                      # Markdown table (about 15 CPU-min)
    python benchmarks/map_sensitivity.py --episodes 10 --json # one JSON object
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SIGMAS_DB = (4.0, 8.0)
UAV_DECORRELATIONS_M = (25.0, 50.0, 100.0)
POLICIES = ("genie", "explore", "map", "spatial")


def run(scenarios: list[str], episodes: int, seed: int, progress: bool, map_folder: Path = ROOT / "policies" / "map",
        spatial_folder: Path = ROOT / "policies" / "spatial") -> dict:
    from uavlink.evaluation import evaluate_policy, paired_ratio_ci
    from uavlink.evaluation.tables import spatial_overrides
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.loader import policy_for_scenario

    rows = []
    for scenario, sigma_db, decorrelation_m in itertools.product(scenarios, SIGMAS_DB, UAV_DECORRELATIONS_M):
        overrides = spatial_overrides(EnvOverrides(scenario, None, {
            "radio.shadowing_std_db": sigma_db, "radio.shadowing_uav_decorrelation_m": decorrelation_m}))
        specs = {"static": "static", "genie": "genie", "explore": "explore",
                 "map": policy_for_scenario(map_folder, scenario),
                 "spatial": policy_for_scenario(spatial_folder, scenario)}
        loaded = dict(zip(specs, load_with_env(list(specs.values()), overrides), strict=True))
        rates = {}
        for name, (policy, cfg) in loaded.items():
            if progress:
                print(f"{scenario} sigma {sigma_db:g} dB, {decorrelation_m:g} m: {name}", file=sys.stderr, flush=True)
            rates[name] = evaluate_policy(policy, cfg, episodes, seed).episode_rate_mbps
        row = {"scenario": scenario, "shadowing_std_db": sigma_db, "uav_decorrelation_m": decorrelation_m,
               "static_mbps": round(float(rates["static"].mean()), 4)}
        for name in POLICIES:
            ratio, lo, hi = paired_ratio_ci(rates[name], rates["static"])
            row[name] = {"mbps": round(float(rates[name].mean()), 4), "over_static": round(ratio, 4),
                         "ci95": [round(lo, 4), round(hi, 4)]}
        rows.append(row)
    return {"benchmark": "map_sensitivity", "episodes": episodes, "seed": seed,
            "statistic": "mean throughput over static's on the same episodes, 95 % paired bootstrap",
            "rows": rows}


def markdown(report: dict) -> str:
    lines = [f"memory of place by channel ({report['episodes']} episodes, seed {report['seed']}; "
             "throughput over static's, 95 % paired interval)", "",
             "| scenario | sigma (dB) | UAV-end decorrelation (m) | static Mbps | "
             + " | ".join(POLICIES) + " |",
             "|---|---:|---:|---:|" + "---|" * len(POLICIES)]
    for r in report["rows"]:
        cells = [f"{100 * (r[p]['over_static'] - 1):+.1f} % [{100 * (r[p]['ci95'][0] - 1):+.1f}, "
                 f"{100 * (r[p]['ci95'][1] - 1):+.1f}]" for p in POLICIES]
        lines.append(f"| {r['scenario']} | {r['shadowing_std_db']:g} | {r['uav_decorrelation_m']:g} | "
                     f"{r['static_mbps']:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["no_move", "circular"])
    parser.add_argument("--map", type=Path, default=ROOT / "policies" / "map", help="the map policies' folder")
    parser.add_argument("--spatial", type=Path, default=ROOT / "policies" / "spatial",
                        help="the spatial policies' folder")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per cell (default 50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    args = parser.parse_args(argv)
    if args.episodes < 2:
        parser.error("--episodes must be >= 2 (a paired interval)")
    from uavlink.errors import UserError

    try:
        report = run(args.scenarios, args.episodes, args.seed, sys.stderr.isatty(), args.map, args.spatial)
    except UserError as exc:  # a scenario without a map or spatial policy, a bad override
        parser.error(str(exc))
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
