"""Soak: one long-lived vehicle process serves many consecutive flights.

One ``python -m sitl_stub`` (one UAV, then ``--fleet 2``) serves N ``uavlink fly`` runs, one after
the other, each started as soon as the one before has exited (so each waits for the landing of the
one before, as back-to-back flights do). Each ``fly`` runs through the CLI's main in this process
(the policy's torch imported once). After each flight: the vehicle process's resident memory
(VmRSS in /proc/PID/status) and open file descriptors (/proc/PID/fd), and the flight's throughput
next to ``uavlink evaluate`` of the episode its summary names (its ``replay`` command).

Pass: every flight complete (``completed: true``, all frames); resident memory from the second
flight to the last within +10 % of the second's; open file descriptors the same after every
flight. Throughput against evaluation is reported, not judged here: on a loaded machine a starved
flight loop's failsafe holds cost throughput (the flight tests judge parity). The vehicles run with
``--param COM_OF_LOSS_T=5`` (``--offboard-loss-s``; PX4's default is 1 s of vehicle time, 50 ms of
wall time at --speed 20) so that a loop starved for a moment does not trip the offboard-loss
failsafe; 1 restores PX4's.

    python benchmarks/soak.py [--flights 20] [--fleet-flights 10] [--speed 20] [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shlex
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RSS_GROWTH_MAX = 0.10


def process_memory(pid: int) -> tuple[int, int]:
    """(VmRSS in KiB, open file descriptors) of process ``pid``."""
    status = Path(f"/proc/{pid}/status").read_text()
    rss_kib = next(
        int(line.split()[1]) for line in status.splitlines() if line.startswith("VmRSS:")
    )
    return rss_kib, len(os.listdir(f"/proc/{pid}/fd"))


def uavlink(*args: str) -> tuple[int, str, str]:
    """``uavlink ARGS`` through the CLI's main in this process: (status, stdout, stderr)."""
    from uavlink.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(list(args))
    return status, out.getvalue(), err.getvalue()


def soak(
    policy: str, scenario: str, seed: int, flights: int, speed: float, loss_s: float, tmp: Path
) -> dict:
    """``flights`` consecutive flights of ``policy`` against one vehicle process started with
    ``seed``; a row per flight and the pass criteria."""
    from sitl_stub.launcher import vehicle_process
    from uavlink.flight.vehicles import vehicle_args
    from uavlink.mavlink.connection import free_udp_port
    from uavlink.policies.contract import EnvOverrides, load_with_env

    [(_, cfg)] = load_with_env([policy], EnvOverrides.from_command_line(scenario, None, []))
    ports = [free_udp_port() for _ in range(cfg.n_uavs)]
    fly = [
        "fly",
        "--policy",
        policy,
        "--scenario",
        scenario,
        "--json",
        "--quiet",
        "--connect",
        ",".join(f"udpin:127.0.0.1:{p}" for p in ports),
    ]
    rows = []
    with vehicle_process(
        [f"udpout:127.0.0.1:{p}" for p in ports],
        speed,
        [*vehicle_args(cfg, seed), "--param", f"COM_OF_LOSS_T={loss_s:g}"],
        log_path=tmp / f"vehicle-{cfg.n_uavs}.log",
    ) as vehicle:
        vehicle.wait_started(60)  # up: its links open, its first episode built
        rss0, fds0 = process_memory(vehicle.proc.pid)
        for k in range(flights):
            status, out, err = uavlink(*fly, "--out", str(tmp / f"d{cfg.n_uavs}-flight{k}"))
            rss, fds = process_memory(vehicle.proc.pid)
            summary = json.loads(out) if out.strip() else {}
            row = {
                "flight": k,
                "exit": status,
                "completed": summary.get("completed", False),
                "frames": summary.get("frames"),
                "episode_seed": summary.get("seed"),
                "mean_rate_mbps": summary.get("mean_rate_mbps"),
                "evaluated_mbps": None,
                "offboard_reentries": summary.get("offboard_reentries"),
                "wall_s": summary.get("wall_s"),
                "vehicle_rss_kib": rss,
                "vehicle_fds": fds,
            }
            if status != 0:
                row["error"] = err.strip().splitlines()[-1] if err.strip() else f"exit {status}"
            if summary.get("replay"):
                _, evaluated, _ = uavlink(*shlex.split(summary["replay"])[1:], "--json")
                row["evaluated_mbps"] = json.loads(evaluated)["mean_rate_mbps"]
                row["flown_vs_evaluated_pct"] = (
                    round(100 * (row["mean_rate_mbps"] / row["evaluated_mbps"] - 1), 2)
                    if row["mean_rate_mbps"]
                    else None
                )
            rows.append(row)
            print(
                f"{cfg.n_uavs} UAV(s), flight {k}: {json.dumps(row)}", file=sys.stderr, flush=True
            )
    rss = [r["vehicle_rss_kib"] for r in rows]
    growth = max(rss[1:]) / rss[1] - 1 if len(rss) > 1 else 0.0
    checks = {
        "every_flight_complete": all(r["completed"] and r["frames"] == 128 for r in rows),
        "rss_growth_from_second_flight": round(growth, 4),
        "rss_within_10pct": growth <= RSS_GROWTH_MAX,
        "fds_constant": len({r["vehicle_fds"] for r in rows}) == 1,
    }
    return {
        "policy": policy,
        "scenario": scenario,
        "n_uavs": cfg.n_uavs,
        "vehicle_seed": seed,
        "flights": flights,
        "vehicle_before_first_flight": {"rss_kib": rss0, "fds": fds0},
        "rows": rows,
        "checks": checks,
        "pass": checks["every_flight_complete"]
        and checks["rss_within_10pct"]
        and checks["fds_constant"],
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="policies/circular.zip", help="the one-UAV policy")
    parser.add_argument(
        "--fleet-policy", default="policies/fleet_d2/circular.zip", help="the fleet's (D = 2)"
    )
    parser.add_argument("--scenario", default="circular")
    parser.add_argument(
        "--seed", type=int, default=0, help="the vehicles' --seed (their first episode)"
    )
    parser.add_argument("--flights", type=int, default=20, help="flights of the one-UAV vehicle")
    parser.add_argument(
        "--fleet-flights", type=int, default=10, help="flights of the fleet (0: no fleet run)"
    )
    parser.add_argument("--speed", type=float, default=20.0, help="the vehicles' --speed")
    parser.add_argument(
        "--offboard-loss-s",
        type=float,
        default=5.0,
        help="the vehicles' COM_OF_LOSS_T, vehicle seconds (PX4: 1)",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    if args.flights < 1 or args.fleet_flights < 0:
        parser.error("--flights must be >= 1 and --fleet-flights >= 0")
    with tempfile.TemporaryDirectory(prefix="soak_") as tmp:
        common = (args.scenario, args.seed)
        runs = [
            soak(str(ROOT / policy), *common, flights, args.speed, args.offboard_loss_s, Path(tmp))
            for policy, flights in (
                (args.policy, args.flights),
                (args.fleet_policy, args.fleet_flights),
            )
            if flights > 0
        ]
    result = {
        "speed": args.speed,
        "com_of_loss_t_s": args.offboard_loss_s,
        "runs": runs,
        "pass": all(r["pass"] for r in runs),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for run in runs:
            print(
                f"\n{run['n_uavs']} UAV(s), {run['flights']} flights of {Path(run['policy']).name}: "
                f"{run['checks']}"
            )
            print(
                "| flight | episode seed | complete | Mbps flown | Mbps evaluated | vehicle RSS (KiB) | fds |"
            )
            print("|---|---|---|---|---|---|---|")
            for r in run["rows"]:
                print(
                    f"| {r['flight']} | {r['episode_seed']} | {r['completed']} | {r['mean_rate_mbps']} | "
                    f"{r['evaluated_mbps']} | {r['vehicle_rss_kib']} | {r['vehicle_fds']} |"
                )
        print(f"\npass: {result['pass']}")
    return 0 if result["pass"] else 1


if __name__ == "__main__":
    sys.exit(main())
