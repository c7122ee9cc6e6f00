"""Is the genie the yardstick it claims to be? ``genie`` against every baseline and shipped policy on the
same episodes, every scenario, on the spatial channel, one UAV and a fleet of two.

D = 1: static, oracle, aoa, kmeans and the spatial policy (``policies/spatial/<scenario>.zip``); D = 2:
the fleet baselines and the fleet policy (``policies/fleet/<scenario>.zip``); each in the env of its
policy's manifest, the genie and the baselines in the same one. Per scenario and D: each column's mean
(Mbps), the genie's paired ratio to it with a 95 % bootstrap interval, the episodes it wins, and
whether the genie's mean is >= every other column's (the yardstick's check). Realised figures (real
fading): the genie plans on the mean-fading channel, so single episodes may fall a hair short.

    python research/genie_check.py --episodes 20 --json > genie_check.json
    python research/genie_check.py --episodes 2 --scenarios no_move --uavs 1   # a quick look
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from entry import run_script

from uavlink.config import SCENARIOS
from uavlink.evaluation import evaluate_policy, paired_ratio_ci
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.registry import make_baseline

SPATIAL = {"radio.shadowing_model": "spatial"}
FOLDERS = {1: Path("policies/spatial"), 2: Path("policies/fleet")}
OTHERS = ("static", "oracle", "aoa", "kmeans")


def check(scenario: str, n_uavs: int, episodes: int, seed: int, log) -> dict:
    """Every column on the same episodes; the genie's ratio to each."""
    [(ppo, cfg)] = load_with_env([FOLDERS[n_uavs]], EnvOverrides(scenario, 0.0, SPATIAL))
    results, seconds = {}, {}
    for name in (*OTHERS, "ppo", "genie"):
        start = time.perf_counter()
        policy = ppo if name == "ppo" else make_baseline(name, cfg)
        results[name] = evaluate_policy(policy, cfg, episodes, seed)
        seconds[name] = round(time.perf_counter() - start, 1)
        log(
            f"{scenario} D={n_uavs} {name}: {results[name].mean_rate_mbps:.3f} Mbps ({seconds[name]} s)"
        )
    genie = results["genie"].episode_rate_mbps
    versus = {}
    for name in (*OTHERS, "ppo"):
        ratio, lo, hi = paired_ratio_ci(genie, results[name].episode_rate_mbps)
        versus[name] = {
            "ratio": round(ratio, 4),
            "ci95": [round(lo, 4), round(hi, 4)],
            "genie_wins": int((genie > results[name].episode_rate_mbps).sum()),
        }
    best_other = max((*OTHERS, "ppo"), key=lambda n: results[n].mean_rate_mbps)
    return {
        "scenario": scenario,
        "n_uavs": n_uavs,
        "episodes": episodes,
        "seed": seed,
        "policy": str(FOLDERS[n_uavs] / f"{scenario}.zip"),
        "mean_mbps": {n: round(r.mean_rate_mbps, 4) for n, r in results.items()},
        "genie_vs": versus,
        "genie_at_least_every_other": bool(
            results["genie"].mean_rate_mbps >= results[best_other].mean_rate_mbps
        ),
        "seconds": seconds,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument(
        "--seed", type=int, default=2027, help="evaluation seed (default 2027, the SPEC sketch's)"
    )
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=SCENARIOS)
    parser.add_argument("--uavs", nargs="+", type=int, default=[1, 2], choices=[1, 2])
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object (progress on stderr)"
    )
    args = parser.parse_args(argv)

    def log(message: str) -> None:  # noqa: E306
        print(message, file=sys.stderr, flush=True)

    rows = [check(s, d, args.episodes, args.seed, log) for d in args.uavs for s in args.scenarios]
    summary = {
        "all_met": all(r["genie_at_least_every_other"] for r in rows),
        "rows": rows,
        "command": "python research/genie_check.py "
        + " ".join(sys.argv[1:] if argv is None else argv),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        for r in rows:
            means = ", ".join(f"{n} {v:.2f}" for n, v in r["mean_mbps"].items())
            print(
                f"{r['scenario']:<13} D={r['n_uavs']}: {means}; genie >= all: {r['genie_at_least_every_other']}"
            )
    return 0


if __name__ == "__main__":
    run_script(main)
