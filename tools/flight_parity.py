"""Flown against evaluated, episode by episode: `uavlink fly --lockstep` (and, with --free, without it).

For each seed, one 128-frame flight through the embedded SITL and the same episode evaluated twice,
`uavlink evaluate --episodes 1 --seed S` with the env's instant moves and with `--set
uav_motion=px4` (the UAV flown to its setpoint as the vehicle flies it). Reports each seed's
figures and, per way of flying, how many flights lie within 5 % of each evaluation (the target
for the map policy: "within 5 % of its one-episode evaluation at the same seed"). A lockstep
flight equals its PX4-motion evaluation only while the SITL held every frame for its decision:
each row gives the flight summary's count of frames it stopped holding (`lockstep_timeouts`, 2 s
of wall time each: a loaded machine), which should be 0.

    python tools/flight_parity.py [--policy policies/map/no_move.zip] [--scenario no_move]
        [--seeds 0 1 2 ...] [--free] [--json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from uavlink.evaluation.core import evaluate_policy
from uavlink.policies.contract import EnvOverrides, load_with_env

ROOT = Path(__file__).resolve().parents[1]


def fly(policy: str, scenario: str, seed: int, lockstep: bool, out: Path) -> dict:
    cmd = [
        sys.executable,
        "-m",
        "uavlink.cli",
        "fly",
        "--policy",
        policy,
        "--scenario",
        scenario,
        "--seed",
        str(seed),
        "--out",
        str(out),
        "--json",
        "--no-picture",
        *(["--lockstep"] if lockstep else []),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    if proc.returncode != 0:
        raise SystemExit(f"fly failed at seed {seed}: {proc.stderr.strip()[-500:]}")
    return json.loads(proc.stdout)


def evaluate(policy: str, scenario: str, seed: int, settings: list[str]) -> float:
    [(actor, cfg)] = load_with_env(
        [policy], EnvOverrides.from_command_line(scenario, None, settings)
    )
    return float(evaluate_policy(actor, cfg, episodes=1, seed=seed).mean_rate_mbps)


def within(
    flown: list[float], evaluated: list[float], share: float = 0.05, abs_tol: float = 0.0
) -> int:
    pairs = zip(flown, evaluated, strict=True)
    return int(sum(abs(f - e) <= share * e + abs_tol for f, e in pairs))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="policies/map/no_move.zip")
    parser.add_argument("--scenario", default="no_move")
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(16)))
    parser.add_argument("--free", action="store_true", help="also fly each seed without --lockstep")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)

    modes = {"lockstep": True, **({"free": False} if args.free else {})}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            row = {
                "seed": seed,
                "evaluated_instant": evaluate(args.policy, args.scenario, seed, []),
                "evaluated_px4": evaluate(args.policy, args.scenario, seed, ["uav_motion=px4"]),
            }
            for mode, lockstep in modes.items():
                flown = fly(args.policy, args.scenario, seed, lockstep, Path(tmp) / f"{mode}{seed}")
                row[f"flown_{mode}"] = flown["mean_rate_mbps"]
                if lockstep:
                    row["lockstep_timeouts"] = flown["lockstep_timeouts"]
            rows.append(row)
    column = {k: [r[k] for r in rows] for k in rows[0] if k != "lockstep_timeouts"}
    summary = {}
    for mode in modes:
        flown = column[f"flown_{mode}"]
        for ev in ("instant", "px4"):
            diff = np.array(flown) / np.array(column[f"evaluated_{ev}"]) - 1
            summary[f"{mode}_vs_{ev}"] = {
                "within_5pct": within(flown, column[f"evaluated_{ev}"]),
                # the flight's summary rounds to six decimals
                "equal": within(flown, column[f"evaluated_{ev}"], share=0.0, abs_tol=1e-6),
                "flights": len(flown),
                "max_abs_diff_pct": round(float(np.abs(diff).max()) * 100, 2),
                "mean_of_flights_vs_mean_evaluated_pct": round(
                    (float(np.mean(flown)) / float(np.mean(column[f"evaluated_{ev}"])) - 1) * 100, 2
                ),
            }
    result = {"policy": args.policy, "scenario": args.scenario, "rows": rows, "summary": summary}
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "---|" * len(keys))
    for r in rows:
        print(
            "| "
            + " | ".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys)
            + " |"
        )
    print()
    for name, s in summary.items():
        print(
            f"{name}: {s['within_5pct']} of {s['flights']} flights within 5 % ({s['equal']} equal), "
            f"largest difference {s['max_abs_diff_pct']} %, "
            f"mean of the flights {s['mean_of_flights_vs_mean_evaluated_pct']:+} %"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
