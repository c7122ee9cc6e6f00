"""A fleet with a memory of place (layout v7, v8): does the lead teacher gain from a leader that reads it?

Where the team stays together the fleet's lead teacher has one UAV fly a single-UAV policy and the
others keep their cells empty (uavlink/learn/lead_teacher.py). One UAV alone gains from a memory of
place where the team holds still (the `explore` rule +12.5 % over the spatial policy on no_move,
docs/results.md). Here, on the same episodes: the shipped any-size fleet policy (v6; no_move's v8), the lead
teacher with the scenario's spatial policy leading (in v6, and in v7 where it reads the v1 fields
alone, which must fly the same), the lead teacher with `explore` leading in v7 (its v3 view:
the v1 fields and the leader's own memory of place), and the lead teacher with the scenario's map
policy leading: in v7 where that policy reads the memory alone (layout v3), in v8 where it reads a
model of the field too (v5: no_move's; each UAV keeps its own model, and the leader is not dashed;
the last column dashes it as every leader was before: what the dash costs a leader that searches).

    python research/fleet_memory_lead.py --scenario no_move --sizes 2 3 4 --episodes 100 --seed 1
    python research/fleet_memory_lead.py --scenario straight --sizes 2 --episodes 100 --seed 1
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from entry import run_script
from fleet_bars import episode_args, paired_ratio, ratio_text

PLACE_CELL_M = 12.0  # sweeps/map.toml's grid


def map_leader(scenario: str) -> tuple[str, str]:
    """The scenario's map policy and what its memory keeps (``place_model``: the cells, v3, or a
    model of the field too, v5), which the fleet's env must keep for every UAV (v7, v8)."""
    from uavlink.policies.contract import manifest_env
    from uavlink.policies.manifest import read_zip_manifest

    path = f"policies/map/{scenario}.zip"
    return path, manifest_env(read_zip_manifest(Path(path))).place_model


def run(scenario: str, sizes: list[int], episodes: int, seed: int) -> dict[str, Any]:
    from uavlink.config.env import PLACE_CELLS
    from uavlink.env.observation import ObservationLayout
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.lead_teacher import make_lead_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env

    mapped, place_model = map_leader(scenario)
    rows = []
    for d in sizes:
        [(fleet, own)] = load_with_env(
            [f"policies/fleet/{scenario}.zip"], EnvOverrides(settings={"n_uavs": d})
        )
        # the shipped policy's world without its memory (no_move's keeps a model: v8)
        v6 = own.replace(place_cell_m=0.0, place_model=PLACE_CELLS).validate()
        v7 = v6.replace(place_cell_m=PLACE_CELL_M).validate()
        leader = f"policies/spatial/{scenario}.zip"
        ppo = evaluate_policy(fleet, own, episodes, seed)
        lead_v6 = evaluate_policy(make_lead_teacher(v6, leader), v6, episodes, seed)
        lead_v7 = evaluate_policy(make_lead_teacher(v7, leader), v7, episodes, seed)
        explore = evaluate_policy(make_lead_teacher(v7, "explore"), v7, episodes, seed)
        with_map = v7.replace(place_model=place_model).validate()
        map_teacher = make_lead_teacher(with_map, mapped)
        lead_map = evaluate_policy(map_teacher, with_map, episodes, seed)
        # as every leader was dashed before v8: what the dash costs a leader that searches
        map_teacher.dash = True
        lead_map_dashed = evaluate_policy(map_teacher, with_map, episodes, seed)
        rows.append(
            {
                "n_uavs": d,
                "ppo_mbps": round(ppo.mean_rate_mbps, 4),
                "lead_spatial_v6_mbps": round(lead_v6.mean_rate_mbps, 4),
                "lead_spatial_v7_mbps": round(lead_v7.mean_rate_mbps, 4),
                "lead_explore_v7_mbps": round(explore.mean_rate_mbps, 4),
                "lead_explore_vs_lead_spatial": paired_ratio(explore, lead_v6),
                "lead_explore_vs_ppo": paired_ratio(explore, ppo),
                "lead_map_layout": ObservationLayout.for_config(with_map).version,
                "lead_map_mbps": round(lead_map.mean_rate_mbps, 4),
                "lead_map_vs_lead_spatial": paired_ratio(lead_map, lead_v6),
                "lead_map_vs_ppo": paired_ratio(lead_map, ppo),
                "lead_map_dashed_mbps": round(lead_map_dashed.mean_rate_mbps, 4),
            }
        )
    return {"scenario": scenario, "episodes": episodes, "seed": seed, "rows": rows}


def markdown(report: dict[str, Any]) -> str:
    lines = [
        "| D | fleet PPO (shipped) | lead, spatial leader (v6 / v7) | lead, explore leader (v7) "
        "| explore lead / spatial lead | explore lead / PPO | lead, map leader (layout) "
        "| map lead / spatial lead | map lead / PPO | map lead, dashed |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in report["rows"]:
        lines.append(
            f"| {row['n_uavs']} | {row['ppo_mbps']:.2f} | {row['lead_spatial_v6_mbps']:.2f} / "
            f"{row['lead_spatial_v7_mbps']:.2f} | {row['lead_explore_v7_mbps']:.2f} | "
            f"{ratio_text(row['lead_explore_vs_lead_spatial'])} | "
            f"{ratio_text(row['lead_explore_vs_ppo'])} | "
            f"{row['lead_map_mbps']:.2f} (v{row['lead_map_layout']}) | "
            f"{ratio_text(row['lead_map_vs_lead_spatial'])} | {ratio_text(row['lead_map_vs_ppo'])} | "
            f"{row['lead_map_dashed_mbps']:.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", choices=SCENARIOS, default="no_move")
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 3], choices=(2, 3, 4))
    args = episode_args(parser, argv, episodes=100, seed=1)
    report = run(args.scenario, args.sizes, args.episodes, args.seed)
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    run_script(main)
