"""Where the spread kmeans teacher's two constants come from: a grid against kmeans itself.

``uavlink.learn.teachers.SpreadTeacher`` is kmeans's split with each UAV aiming ``lead_frames``
frames ahead of its group's centroid (along the group's mean velocity) and ``spread_m`` further from
the other groups. Each row flies one (spread_m, lead_frames) pair and kmeans on the same seeded
episodes of the scenario's fleet env at D UAVs (the shipped any-size policy's env: spatial channel,
layout v6), with the paired throughput ratio and its 95 % bootstrap interval, beside the shipped
policy's own ratio to kmeans on those episodes, and paired with the shipped rule (20 m from the
others' mean, a frame ahead) on the same episodes. ``--away nearest`` spreads each UAV from the
nearest other group instead of the others' mean (the same rule at D = 2). Both rules read GPS:
this chooses a teacher, not a policy. Seconds on 2 cores.

    python research/spread_search.py --episodes 100 --seed 1
    python research/spread_search.py --scenario hotspot --sizes 2 --spread-m 0 20 --lead-frames 0 1
    python research/spread_search.py --scenario hotspot --sizes 3 4 --spread-m 20 30 40 \
        --lead-frames 1 --away nearest
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from entry import run_script
from fleet_bars import episode_args, paired_ratio, ratio_text


def nearest_spread_teacher(cfg: Any, spread_m: float, lead_frames: float) -> Any:
    """The spread teacher with each UAV pushed away from the nearest other group's target instead
    of the other groups' mean (the same at D = 2): interference falls with distance, so the nearest
    neighbour's cell is the one that costs most."""
    import numpy as np

    from uavlink.learn.teachers import SpreadTeacher

    class NearestSpread(SpreadTeacher):
        def others_m(self, target_m: Any) -> Any:
            gap = np.linalg.norm(target_m[:, :, None] - target_m[:, None], axis=-1)
            gap[:, np.arange(self.cfg.n_uavs), np.arange(self.cfg.n_uavs)] = np.inf
            return target_m[np.arange(len(target_m))[:, None], gap.argmin(axis=2)]

    return NearestSpread(cfg, spread_m, lead_frames)


def run(
    scenarios: list[str],
    sizes: list[int],
    spreads_m: list[float],
    leads: list[float],
    episodes: int,
    seed: int,
    away: str = "mean",
) -> dict[str, Any]:
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.teachers import SpreadTeacher
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.registry import make_baseline

    rows = []
    for scenario in scenarios:
        for d in sizes:
            [(policy, cfg)] = load_with_env(
                [f"policies/fleet/{scenario}.zip"], EnvOverrides(settings={"n_uavs": d})
            )
            kmeans = evaluate_policy(make_baseline("kmeans", cfg), cfg, episodes, seed)
            shipped = paired_ratio(evaluate_policy(policy, cfg, episodes, seed), kmeans)
            shipped_rule = evaluate_policy(SpreadTeacher(cfg), cfg, episodes, seed)
            for spread_m in spreads_m:
                for lead in leads:
                    make = SpreadTeacher if away == "mean" else nearest_spread_teacher
                    rule = evaluate_policy(make(cfg, spread_m, lead), cfg, episodes, seed)
                    rows.append(
                        {
                            "scenario": scenario,
                            "n_uavs": d,
                            "spread_m": spread_m,
                            "lead_frames": lead,
                            "spread_mbps": round(rule.mean_rate_mbps, 4),
                            "kmeans_mbps": round(kmeans.mean_rate_mbps, 4),
                            "spread_vs_kmeans": paired_ratio(rule, kmeans),
                            "spread_vs_shipped_rule": paired_ratio(rule, shipped_rule),
                            "policy_vs_kmeans": shipped,
                        }
                    )
    return {"episodes": episodes, "seed": seed, "away": away, "rows": rows}


def markdown(report: dict[str, Any]) -> str:
    lines = [
        "| scenario | D | spread_m | lead_frames | spread Mbps | kmeans Mbps | spread / kmeans "
        "| spread / the shipped rule | shipped policy / kmeans |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in report["rows"]:
        lines.append(
            f"| {row['scenario']} | {row['n_uavs']} | {row['spread_m']:g} | {row['lead_frames']:g} "
            f"| {row['spread_mbps']:.2f} | {row['kmeans_mbps']:.2f} | "
            f"{ratio_text(row['spread_vs_kmeans'])} | {ratio_text(row['spread_vs_shipped_rule'])} | "
            f"{ratio_text(row['policy_vs_kmeans'])} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenario",
        action="append",
        dest="scenarios",
        choices=SCENARIOS,
        help="a scenario whose fleet env is flown (repeatable; default straight_180 and hotspot)",
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 3, 4], choices=(2, 3, 4))
    parser.add_argument("--spread-m", type=float, nargs="+", default=[0.0, 10.0, 15.0, 20.0, 30.0])
    parser.add_argument("--lead-frames", type=float, nargs="+", default=[0.0, 1.0, 2.0])
    parser.add_argument(
        "--away",
        choices=("mean", "nearest"),
        default="mean",
        help="what each UAV spreads away from: the other groups' mean (the shipped teacher) or "
        "the nearest other group",
    )
    args = episode_args(parser, argv, episodes=100, seed=1)
    report = run(
        args.scenarios or ["straight_180", "hotspot"],
        args.sizes,
        args.spread_m,
        args.lead_frames,
        args.episodes,
        args.seed,
        args.away,
    )
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    run_script(main)
