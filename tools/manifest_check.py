"""Re-evaluate every shipped policy on the episodes its manifest recorded, and show the difference.

Each manifest's ``evaluation`` keeps the figure `uavlink evaluate` gave when the policy was shipped
(its scenario, episodes and seed). On the paper's channel the figures come back to the last digit on
any machine; on the spatial channel numpy's vectorised transcendental functions differ in the last
bit between CPUs, and a closed-loop policy can turn that into another path in a few episodes
(docs/design/code.md, "Reproducible by seed, to the last bit on one machine").

    python tools/manifest_check.py [--policies policies] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from uavlink.evaluation.core import evaluate_policy
from uavlink.policies.contract import EnvOverrides, load_with_env

ROOT = Path(__file__).resolve().parents[1]


def check(folder: Path) -> list[dict]:
    rows = []
    for manifest_path in sorted(folder.rglob("*.json")):
        manifest = json.loads(manifest_path.read_text())
        policy = manifest_path.with_suffix(".zip")
        if not isinstance(manifest.get("evaluation"), dict) or not policy.exists():
            continue  # a sweep record, not a policy's manifest
        for recorded in manifest["evaluation"].values():
            overrides = EnvOverrides.from_command_line(
                recorded["scenario"], recorded.get("aoa_noise_deg"), []
            )
            [(actor, cfg)] = load_with_env([str(policy)], overrides)
            now = evaluate_policy(actor, cfg, recorded["episodes"], recorded["seed"]).mean_rate_mbps
            rows.append(
                {
                    "policy": str(policy),
                    "scenario": recorded["scenario"],
                    "channel": cfg.radio.shadowing_model,
                    "episodes": recorded["episodes"],
                    "seed": recorded["seed"],
                    "recorded_mbps": recorded["mean_rate_mbps"],
                    "now_mbps": round(float(now), 6),
                    "diff_pct": round((float(now) / recorded["mean_rate_mbps"] - 1) * 100, 3),
                }
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--policies",
        type=Path,
        default=ROOT / "policies",
        help="folder of shipped policies, searched recursively (default: the repository's)",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = check(args.policies)
    if not rows:
        parser.error(f"{args.policies}: no policy zip with an evaluation in its manifest")
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print("| policy | scenario | channel | recorded (Mbps) | now (Mbps) | difference |")
    print("|---|---|---|---:|---:|---:|")
    for r in rows:
        print(
            f"| {r['policy']} | {r['scenario']} | {r['channel']} | {r['recorded_mbps']:.6f} | "
            f"{r['now_mbps']:.6f} | {r['diff_pct']:+.3f} % |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
