"""What knowing the shadowing field is worth to a fleet: the genie beside a genie blind to the field.

The fleet genie (``uavlink.policies.genie``) knows each episode's future, the UEs' paths and the
spatial shadowing field, and plans every UAV's path. ``FieldBlindGenie`` is the same planner handed
the same future without the field: it plans on path loss alone, then flies its plan in the same
episodes, on the same channel (shadowing, fast fading) as every other column. So the gap between the
two is what the field is worth to a planner that already knows where every UE will be; a GPS-free
policy knows neither, and senses the field only where its UAVs have flown. Beside them the GPS
``kmeans`` rule and the shipped fleet policy (``--fleet``), each as a share of the genie with its
paired 95 % interval.

    python research/fleet_field_worth.py                                  # the split scenarios, D = 2, 3
    python research/fleet_field_worth.py --scenario hotspot --sizes 3 --episodes 10 --json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

from entry import run_script
from fleet_bars import episode_args, paired_ratio, ratio_text

# where the UEs part, and the genie bar is missed
SPLIT = ("straight_90", "straight_180", "hotspot")
COLUMNS = ("genie", "field-blind genie", "kmeans", "PPO")


def field_blind_genie(genie: Any) -> Any:
    """A copy of the fleet genie ``genie`` (the registry's: its env, references and workers) that
    plans without the shadowing field."""
    from uavlink.policies.genie import GeniePolicy

    class FieldBlindGenie(GeniePolicy):
        name = "field-blind genie"

        def plan(self, truth: Any) -> None:
            super().plan(dataclasses.replace(truth, shadow_field=None))

    return FieldBlindGenie(genie.cfg, genie.references, workers=genie.workers)


def run(
    fleet: Path, scenarios: tuple[str, ...], sizes: tuple[int, ...], episodes: int, seed: int
) -> dict[str, Any]:
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.registry import make_baseline

    rows = []
    for scenario in scenarios:
        [(policy, built)] = load_with_env([fleet / f"{scenario}.zip"], EnvOverrides())
        for size in sizes:
            cfg = built.replace(n_uavs=size).validate()
            genie = make_baseline("genie", cfg)
            flown = {
                "genie": genie,
                "field-blind genie": field_blind_genie(genie),
                "kmeans": make_baseline("kmeans", cfg),
                "PPO": policy,
            }
            results = {name: evaluate_policy(p, cfg, episodes, seed) for name, p in flown.items()}
            rows.append(
                {
                    "scenario": scenario,
                    "n_uavs": size,
                    "mbps": {k: round(r.mean_rate_mbps, 4) for k, r in results.items()},
                    "of_genie": {
                        k: paired_ratio(r, results["genie"])
                        for k, r in results.items()
                        if k != "genie"
                    },
                }
            )
    return {"fleet": str(fleet), "episodes": episodes, "seed": seed, "rows": rows}


def markdown(report: dict[str, Any]) -> str:
    lines = [
        f"{report['episodes']} episodes of seed {report['seed']}, spatial channel; Mbps, and each "
        "column's share of the genie (paired 95 % bootstrap interval)",
        "",
        "| scenario | D | "
        + " | ".join(f"{c} Mbps" for c in COLUMNS)
        + " | "
        + " | ".join(f"{c} / genie" for c in COLUMNS[1:])
        + " |",
        "|---|---:|" + "---:|" * len(COLUMNS) + "---|" * (len(COLUMNS) - 1),
    ]
    for row in report["rows"]:
        mbps = " | ".join(f"{row['mbps'][c]:.2f}" for c in COLUMNS)
        shares = " | ".join(ratio_text(row["of_genie"][c]) for c in COLUMNS[1:])
        lines.append(f"| {row['scenario']} | {row['n_uavs']} | {mbps} | {shares} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleet", type=Path, default=Path("policies/fleet"))
    parser.add_argument(
        "--scenario",
        action="append",
        dest="scenarios",
        choices=SCENARIOS,
        help=f"a scenario (repeatable; default: {', '.join(SPLIT)})",
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 3], choices=[2, 3, 4])
    args = episode_args(parser, argv, episodes=30, seed=1)
    scenarios = tuple(args.scenarios) if args.scenarios else SPLIT
    report = run(args.fleet, scenarios, tuple(args.sizes), args.episodes, args.seed)
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    run_script(main)
