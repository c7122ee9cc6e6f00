"""The transit guard's cost: milliseconds per decision of ``guard_transit`` for fleets of 2-4.

A flight loop runs the guard once per frame (one env, (D, 2)) before it sends the setpoints; the
env's ``uav_motion="px4"`` fleet runs it once per step over all its envs. Each call here guards a
fleet driven at one point (every move cut somewhere: the guard's worst case, each vehicle's grid of
shorter moves predicted) from vehicles moving at up to 12 m/s. No target: the figure tells how much
of a 1 s frame the guard takes (docs/design/radio.md, "A fleet in flight"). Each setting runs
twice, side by side: as in use (a flight's few rows in the position loop's Python-float kernel, its
cut moves' grid searched longest first; a batch in numpy, its grid flown at once) and with the
batch's way forced for every size; ``float_speedup`` is their ratio of medians.

    python benchmarks/transit_guard.py            # a table
    python benchmarks/transit_guard.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from run_record import command, machine

import uavlink.mobility.transit as transit
import uavlink.mobility.uav_motion as uav_motion
from uavlink.mobility.transit import guard_transit


def _fleets(rng: np.random.Generator, n_envs: int, n_uavs: int) -> tuple[np.ndarray, ...]:
    """Positions 30-60 m from a common point, moving, each move 12 m straight at that point."""
    angle = rng.uniform(0, 2 * np.pi, (n_envs, n_uavs))
    radius = rng.uniform(30, 60, (n_envs, n_uavs))
    actual = np.stack([np.cos(angle), np.sin(angle)], axis=-1) * radius[..., None]
    velocity = rng.uniform(-12, 12, actual.shape)
    new = actual - 12 * actual / radius[..., None]
    return actual, actual.copy(), new, velocity


def _call_ms(inputs: list[tuple[np.ndarray, ...]], one_env: bool) -> tuple[float, float]:
    """Best and median milliseconds per guard call over ``inputs``."""
    times = []
    for actual, current, new, velocity in inputs:
        start = time.perf_counter()
        guard_transit(actual[0] if one_env else actual, current, new, 20.0, velocity)
        times.append(time.perf_counter() - start)
    return min(times) * 1e3, float(np.median(times)) * 1e3


def measure(n_envs: int, n_uavs: int, calls: int, seed: int) -> dict:
    """Best and median milliseconds per call over ``calls`` calls on fresh fleets, with the kernel
    in use and with the batch's way forced (the same calls, one after the other)."""
    rng = np.random.default_rng(seed)
    inputs = [_fleets(rng, n_envs, n_uavs) for _ in range(calls)]
    best, median = _call_ms(inputs, n_envs == 1)
    in_use = uav_motion.FLOAT_KERNEL_MAX_ROWS, transit.SCAN_MAX_ENVS
    uav_motion.FLOAT_KERNEL_MAX_ROWS, transit.SCAN_MAX_ENVS = 0, 0
    try:
        _, numpy_median = _call_ms(inputs, n_envs == 1)
    finally:
        uav_motion.FLOAT_KERNEL_MAX_ROWS, transit.SCAN_MAX_ENVS = in_use
    return {
        "n_envs": n_envs,
        "n_uavs": n_uavs,
        "calls": calls,
        "best_ms": round(best, 3),
        "median_ms": round(median, 3),
        "numpy_median_ms": round(numpy_median, 3),
        "float_speedup": round(numpy_median / median, 2),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=50, help="per setting (default 50)")
    parser.add_argument("--envs", nargs="+", type=int, default=[1, 100])
    parser.add_argument("--uavs", nargs="+", type=int, default=[2, 3, 4])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = [measure(n, d, args.calls, args.seed) for n in args.envs for d in args.uavs]
    out = {
        "rows": rows,
        "machine": machine(),
        "command": command("transit_guard.py", argv),
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(
            "| envs | UAVs | best ms/call | median ms/call | numpy median ms/call | speed-up |\n"
            "|---|---|---|---|---|---|"
        )
        for r in rows:
            print(
                f"| {r['n_envs']} | {r['n_uavs']} | {r['best_ms']} | {r['median_ms']} "
                f"| {r['numpy_median_ms']} | {r['float_speedup']} |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
