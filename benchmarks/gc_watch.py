"""Garbage-collection passes during a flight: `uavlink fly ARGS` run in this process, every pass of
Python's cyclic collector longer than --min-ms logged with its generation, its length and when it
ended, in seconds from the end of the mission (take-off to landing; negative: before it ended) and
whether it fell inside the mission; as `fly` flies (the heap frozen: uavlink/flight/steady.py) or,
with --no-freeze, as it flew before the freeze. research/log/flight.md, "A pause in the fleet's flights":

    python benchmarks/gc_watch.py [--no-freeze] [--json] -- --policy policies/fleet_d2/straight_180.zip \\
        --seed 1 --out /tmp/gc-fly
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import io
import json
import time
from pathlib import Path


def watch(fly_args: list[str], min_ms: float, freeze: bool) -> dict:
    import uavlink.flight.fly
    from uavlink.cli import main

    if not freeze:  # fly as before the freeze: both entry points' heap left as it is
        uavlink.flight.fly.steady_heap = contextlib.nullcontext
    passes, started, mission = [], {}, {}

    def timed(fly):  # the mission's window, take-off to landing
        def run(*args, **kwargs):
            mission["start"] = time.perf_counter()
            try:
                return fly(*args, **kwargs)
            finally:
                mission["end"] = time.perf_counter()

        return run

    uavlink.flight.fly.fly_vehicle = timed(uavlink.flight.fly.fly_vehicle)
    uavlink.flight.fly.fly_fleet = timed(uavlink.flight.fly.fly_fleet)

    def on_gc(phase: str, info: dict) -> None:
        if phase == "start":
            started["t"] = time.perf_counter()
        elif (ms := 1e3 * (time.perf_counter() - started["t"])) > min_ms:
            passes.append(
                {
                    "generation": info["generation"],
                    "ms": round(ms, 1),
                    "ended_at": time.perf_counter(),
                }
            )

    gc.callbacks.append(on_gc)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            code = main(["fly", *fly_args, "--json"])
    finally:
        gc.callbacks.remove(on_gc)
    for p in passes:
        ended = p.pop("ended_at")
        p["in_mission"] = mission["start"] <= ended and ended - p["ms"] / 1e3 <= mission["end"]
        p["s_from_mission_end"] = round(ended - mission["end"], 2)
    out = Path(fly_args[fly_args.index("--out") + 1]) if "--out" in fly_args else Path("runs/fly")
    summary = json.loads((out / "summary.json").read_text())
    # holds: a fleet's vehicles count them; stale reports: frames a held-up loop observed, not decided
    counts = ("decisions", "stale_radio_reports", "holds", "offboard_reentries")
    vehicles = [{k: v[k] for k in counts if k in v} for v in summary.get("vehicles") or [summary]]
    return {
        "benchmark": "gc_watch",
        "fly": fly_args,
        "frozen_heap": freeze,
        "exit_status": code,
        "min_ms": min_ms,
        "passes": passes,
        "episode_wall_s": summary.get("episode_wall_s"),
        "vehicles": vehicles,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--no-freeze", action="store_true", help="fly without the frozen heap, as before"
    )
    parser.add_argument(
        "--min-ms", type=float, default=20.0, help="log passes longer than this (default 20)"
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of lines"
    )
    parser.add_argument("fly", nargs=argparse.REMAINDER, help="-- then `uavlink fly`'s arguments")
    args = parser.parse_args(argv)
    fly_args = args.fly[1:] if args.fly[:1] == ["--"] else args.fly
    report = watch(fly_args, args.min_ms, not args.no_freeze)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"frozen heap: {report['frozen_heap']}; episode {report['episode_wall_s']} s wall; vehicles "
        + ", ".join(" / ".join(f"{n} {k}" for k, n in v.items()) for v in report["vehicles"])
    )
    for p in report["passes"]:
        where = "in the mission" if p["in_mission"] else "outside the mission"
        print(
            f"  generation {p['generation']}: {p['ms']} ms, {where}, ended {p['s_from_mission_end']:+} s "
            "from its end"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
