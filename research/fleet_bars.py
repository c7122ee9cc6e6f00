"""The any-size fleet policies against their bars, on episodes of a seed of your choice.

For each scenario's policy in ``--fleet`` (any-size, layout v6) and each fleet size D it flies: the
paired throughput ratio (95 % bootstrap interval) against the GPS ``kmeans`` rule and against the
policy's own warm-start teacher (rebuilt from its manifest, ``uavlink.learn.teachers.policy_teacher``;
the issue's bar is at D = 2) at the same D; at D = 2 also against the per-size D = 2 policy of
``--per-size``. Every
column flies the same seeded episodes. The genie's ratio is the results report's (100 episodes): at
~4-7 CPU-s per episode for D = 3 and 4 it does not fit 1,000 fresh episodes here.

    python research/fleet_bars.py --episodes 1000 --seed 7            # a seed no choice used
    python research/fleet_bars.py --episodes 100 --seed 0 --json      # results.md's episodes
    python research/fleet_bars.py --fleet DIR --scenario no_move       # DIR/no_move.zip alone
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from entry import run_script

SIZES = (2, 3, 4)


def episode_args(
    parser: argparse.ArgumentParser, argv: list[str] | None, episodes: int, seed: int
) -> argparse.Namespace:
    """``parser``'s arguments with the options every fleet research script takes (``--episodes``,
    ``--seed``, ``--json``) added, an ``--episodes`` below 1 refused in one line."""
    parser.add_argument("--episodes", type=int, default=episodes)
    parser.add_argument("--seed", type=int, default=seed)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    if args.episodes < 1:
        parser.error("--episodes must be positive")
    return args


def paired_ratio(a: Any, b: Any) -> list[float]:
    """Evaluation ``a``'s mean throughput over ``b``'s with its paired 95 % interval, rounded."""
    from uavlink.evaluation import paired_ratio_ci

    return [round(x, 4) for x in paired_ratio_ci(a.episode_rate_mbps, b.episode_rate_mbps)]


def ratio_text(r: list[float]) -> str:
    """A ``paired_ratio`` as ``ratio [low, high]``."""
    return f"{r[0]:.3f} [{r[1]:.3f}, {r[2]:.3f}]"


def run(
    fleet: Path,
    per_size: Path | None,
    episodes: int,
    seed: int,
    scenarios: tuple[str, ...] | None = None,
) -> dict[str, Any]:
    from uavlink.config import SCENARIOS
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.registry import make_baseline

    rows = []
    for scenario in scenarios or SCENARIOS:
        [(policy, built)] = load_with_env([fleet / f"{scenario}.zip"], EnvOverrides())
        for size in SIZES:
            cfg = built.replace(n_uavs=size).validate()
            ppo = evaluate_policy(policy, cfg, episodes, seed)
            kmeans = evaluate_policy(make_baseline("kmeans", cfg), cfg, episodes, seed)
            row: dict[str, Any] = {
                "scenario": scenario,
                "n_uavs": size,
                "ppo_mbps": round(ppo.mean_rate_mbps, 4),
                "kmeans_mbps": round(kmeans.mean_rate_mbps, 4),
                "vs_kmeans": paired_ratio(ppo, kmeans),
            }
            teacher, name = policy_teacher(policy, cfg)
            if teacher is not None:
                taught = evaluate_policy(teacher, cfg, episodes, seed)
                row |= {
                    "teacher": name,
                    "teacher_mbps": round(taught.mean_rate_mbps, 4),
                    "vs_teacher": paired_ratio(ppo, taught),
                }
            if size == 2 and per_size is not None:
                [(old, old_cfg)] = load_with_env([per_size / f"{scenario}.zip"], EnvOverrides())
                before = evaluate_policy(old, old_cfg, episodes, seed)
                row |= {
                    "per_size_mbps": round(before.mean_rate_mbps, 4),
                    "vs_per_size": paired_ratio(ppo, before),
                }
            rows.append(row)
    return {"fleet": str(fleet), "episodes": episodes, "seed": seed, "rows": rows}


def _cell(row: dict[str, Any], key: str) -> str:
    if key not in row:
        return "-"
    _, lo, hi = row[key]
    mark = " (above)" if lo > 1 else " (below)" if hi < 1 else ""
    return ratio_text(row[key]) + mark


def markdown(report: dict[str, Any]) -> str:
    lines = [
        f"{report['fleet']}: {report['episodes']} episodes, seed {report['seed']} (paired 95 % "
        "bootstrap intervals; (above) / (below): the interval clears 1)",
        "",
        "| scenario | D | PPO Mbps | kmeans Mbps | PPO / kmeans | PPO / per-size D2 | PPO / teacher |",
        "|---|---:|---:|---:|---|---|---|",
    ]
    for row in report["rows"]:
        teacher = _cell(row, "vs_teacher")
        if "teacher" in row:
            teacher += f" ({row['teacher']})"
        lines.append(
            f"| {row['scenario']} | {row['n_uavs']} | {row['ppo_mbps']:.2f} | "
            f"{row['kmeans_mbps']:.2f} | {_cell(row, 'vs_kmeans')} | "
            f"{_cell(row, 'vs_per_size')} | {teacher} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleet", type=Path, default=Path("policies/fleet"))
    parser.add_argument(
        "--per-size",
        type=Path,
        default=Path("policies/fleet_d2"),
        help="the per-size D = 2 policies to compare at D = 2 (a missing folder: skipped)",
    )
    parser.add_argument(
        "--scenario",
        action="append",
        dest="scenarios",
        choices=SCENARIOS,
        help="only this scenario's policy (repeatable; default: every scenario)",
    )
    args = episode_args(parser, argv, episodes=100, seed=0)
    per_size = args.per_size if args.per_size.is_dir() else None
    scenarios = tuple(args.scenarios) if args.scenarios else None
    report = run(args.fleet, per_size, args.episodes, args.seed, scenarios)
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    run_script(main)
