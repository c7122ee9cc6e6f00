"""``uavlink policies``: the shipped policies, one row each, from their manifests."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from uavlink.errors import UserError


def policy_row(name: str, path: Path) -> dict[str, Any]:
    """One shipped policy as ``uavlink policies`` lists it: what it was built for (its manifest
    beside it), the runtimes it can fly with and its shipped evaluation figure."""
    from uavlink.config import fleet_sizes_of
    from uavlink.policies.contract import manifest_env
    from uavlink.policies.loader import zip_twin

    manifest = json.loads(path.with_suffix(".json").read_text())
    env = manifest_env(manifest)
    scenario = env.scenario
    evaluation = manifest.get("evaluation", {})
    own = evaluation.get(scenario)
    runtimes = []
    if path.with_suffix(".onnx").is_file():
        # a twin exported from other bytes than the zip's is never flown (policies.loader)
        twin = zip_twin(path) if path.suffix == ".zip" else None
        stale = twin is not None and not twin[1]
        runtimes.append("onnx: stale, uavlink export again" if stale else "onnx [fly]")
    if path.suffix == ".zip":
        runtimes.append("sb3 [train]")
    return {
        "name": name,
        "file": str(path),
        "channel": env.radio.shadowing_model,
        "scenario": scenario,
        "n_uavs": env.n_uavs,
        # an any-size fleet's policy flies every size of fleet_sizes_of (--set n_uavs=D)
        "fleet_sizes": list(fleet_sizes_of(env.fleet_slots)) if env.fleet_slots else None,
        "layout": manifest["observation_layout"]["version"],
        "runtimes": runtimes,
        "mean_rate_mbps": own["mean_rate_mbps"] if own else None,
        "evaluation": evaluation,  # per scenario: episodes, seed, figures
    }


def _figure(row: dict[str, Any]) -> str:
    if row["mean_rate_mbps"] is not None:
        own = row["evaluation"][row["scenario"]]
        return f"{row['mean_rate_mbps']:.2f} ({own['episodes']} ep, seed {own['seed']})"
    rates = [e["mean_rate_mbps"] for e in row["evaluation"].values()]
    return f"{sum(rates) / len(rates):.2f} (mean of {len(rates)} scenarios)" if rates else "-"


def cmd_policies(args: argparse.Namespace) -> int:
    from uavlink.policies.loader import shipped_policies, shipped_root

    shipped = shipped_policies()
    if not shipped:
        raise UserError("no shipped policies found (neither uavlink/shipped nor policies/ exists)")
    rows = [policy_row(name, path) for name, path in shipped.items()]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    header = ("name", "channel", "scenario", "UAVs", "layout", "runtimes", "Mbps (manifest)")
    table = [
        (
            r["name"],
            r["channel"],
            r["scenario"],
            f"{r['fleet_sizes'][0]}-{r['fleet_sizes'][-1]}"
            if r["fleet_sizes"]
            else str(r["n_uavs"]),
            f"v{r['layout']}",
            ", ".join(r["runtimes"]),
            _figure(r),
        )
        for r in rows
    ]
    widths = [max(len(line[i]) for line in (header, *table)) for i in range(len(header))]
    for line in (header, *table):
        print("  ".join(cell.ljust(w) for cell, w in zip(line, widths, strict=True)).rstrip())
    print(f"\n{len(rows)} policies in {shipped_root()}; fly one by name: uavlink fly --policy NAME")
    return 0


def add_policies_parser(sub) -> None:
    p = sub.add_parser(
        "policies",
        help="list the shipped policies",
        description="List the shipped policies: name (what --policy takes), channel, scenario, "
        "UAVs, observation layout, the runtimes it flies with (ONNX needs only the [fly] extra) "
        "and the evaluation figure its manifest records.",
    )
    p.add_argument("--json", action="store_true", help="print the list as JSON")
    p.set_defaults(func=cmd_policies)
