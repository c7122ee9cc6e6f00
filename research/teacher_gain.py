"""What PPO added over the rule it copied: each policy file against its own warm-start teacher.

The teacher is rebuilt from the policy's manifest (``training.hyperparameters.warm_start``: the rule,
its variant's speed span and shadow gate, and a shadowing estimator refitted on the same number of
episodes of the training seed, as ``uavlink.learn.training`` builds it:
``uavlink.learn.teachers.policy_teacher``), and flies the policy's env
on the same seeded episodes as the policy; the gain is the paired throughput ratio with its 95 %
bootstrap interval. A policy trained without a warm start has no teacher and is skipped.

    python research/teacher_gain.py policies/map/*.zip [--episodes 100] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json

from entry import run_script


def run(paths: list[str], episodes: int, seed: int) -> dict:
    from uavlink.evaluation import evaluate_policy, paired_ratio_ci
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env

    rows = []
    for path in paths:
        [(policy, cfg)] = load_with_env([path], EnvOverrides())
        teacher, name = policy_teacher(policy, cfg)
        if teacher is None:
            continue
        ppo = evaluate_policy(policy, cfg, episodes, seed)
        rule = evaluate_policy(teacher, cfg, episodes, seed)
        ratio, lo, hi = paired_ratio_ci(ppo.episode_rate_mbps, rule.episode_rate_mbps)
        rows.append(
            {
                "policy": path,
                "scenario": cfg.scenario,
                "teacher": name,
                "ppo_mbps": round(ppo.mean_rate_mbps, 4),
                "teacher_mbps": round(rule.mean_rate_mbps, 4),
                "gain": round(ratio - 1, 4),
                "ci95": [round(lo - 1, 4), round(hi - 1, 4)],
                "beats_teacher": lo > 1,
            }
        )
    return {"benchmark": "teacher_gain", "episodes": episodes, "seed": seed, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policies", nargs="+", help="policy files (.zip with a manifest)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    args = parser.parse_args(argv)
    if args.episodes < 2:
        parser.error("--episodes must be >= 2 (a paired interval)")
    from uavlink.errors import UserError

    try:
        report = run(args.policies, args.episodes, args.seed)
    except UserError as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"{args.episodes} episodes, seed {args.seed}\n")
    print(
        "| policy | scenario | teacher | PPO Mbps | teacher Mbps | PPO vs teacher |\n|---|---|---|---:|---:|---|"
    )
    for r in report["rows"]:
        lo, hi = r["ci95"]
        print(
            f"| {r['policy']} | {r['scenario']} | {r['teacher']} | {r['ppo_mbps']:.3f} | {r['teacher_mbps']:.3f} "
            f"| {100 * r['gain']:+.1f} % [{100 * lo:+.1f}, {100 * hi:+.1f}] |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
