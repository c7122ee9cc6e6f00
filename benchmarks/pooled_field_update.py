"""What a pooled model of the field costs a frame: a fleet's D readings as one block, or one by one.

A listening fleet's model (layout v9, ``FieldModel(shared_by=D)``) takes every UAV's reading each
frame. ``FieldModel.update`` adds the D readings as one block update, reading the (n, K) factor
once; ``FieldModel.observe`` adds one reading, so D calls read it D times. Measured here, in one
run on the same random walk of a whole episode (``--rows`` fleets side by side): milliseconds a
frame of each, their ratio, and the largest gap between the two posteriors' means (the same to
rounding, or the run fails).

    python benchmarks/pooled_field_update.py --json
    python benchmarks/pooled_field_update.py --sizes 3 --rows 256
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from run_record import command, machine

from uavlink.config import EnvConfig
from uavlink.env.field_model import FieldModel

EPISODE_FRAMES = EnvConfig().episode_frames  # a whole episode
R_MAX_M = EnvConfig().r_max_m  # a frame's largest move


def walk(rows: int, d: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions (frames, rows x d, 2), m, and sensed values (frames, rows x d), bits/s/Hz: each UAV
    a random walk of frame-sized steps from near the centre."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(-R_MAX_M, R_MAX_M, (EPISODE_FRAMES + 1, rows * d, 2))
    steps[0] = rng.uniform(-60.0, 60.0, (rows * d, 2))
    return np.cumsum(steps, axis=0), rng.normal(6.0, 1.5, (EPISODE_FRAMES + 1, rows * d))


def measure(d: int, rows: int, seed: int) -> dict:
    xy_m, value_bits = walk(rows, d, seed)
    block = FieldModel(rows, EPISODE_FRAMES, R_MAX_M, shared_by=d)
    one_by_one = FieldModel(rows, EPISODE_FRAMES, R_MAX_M, sensors=d)
    block.reset()
    one_by_one.reset()
    start = time.perf_counter()
    for frame in range(EPISODE_FRAMES + 1):
        block.update(xy_m[frame], value_bits[frame])
    block_s = time.perf_counter() - start
    start = time.perf_counter()
    for frame in range(EPISODE_FRAMES + 1):
        for uav in range(d):
            one_by_one.observe(xy_m[frame, uav::d], value_bits[frame, uav::d])
    one_by_one_s = time.perf_counter() - start
    gap_bits = float(np.abs(block.mean - one_by_one.mean).max())
    if gap_bits > 1e-6:
        raise AssertionError(f"the block update's posterior mean is {gap_bits} bits off")
    frames = EPISODE_FRAMES + 1
    return {
        "n_uavs": d,
        "rows": rows,
        "block_ms_per_frame": round(1e3 * block_s / frames, 3),
        "one_by_one_ms_per_frame": round(1e3 * one_by_one_s / frames, 3),
        "speedup": round(one_by_one_s / block_s, 2),
        "max_mean_gap_bits": gap_bits,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=[2, 3, 4], help="fleet sizes D")
    parser.add_argument("--rows", type=int, default=32, help="fleets side by side (default 32)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = [measure(d, args.rows, args.seed) for d in args.sizes]
    out = {
        "rows": rows,
        "machine": machine(),
        "command": command("pooled_field_update.py", argv),
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for r in rows:
            print(
                f"D={r['n_uavs']}, {r['rows']} fleets: block {r['block_ms_per_frame']:.2f} ms/frame, "
                f"one by one {r['one_by_one_ms_per_frame']:.2f} ms ({r['speedup']:.2f}x)"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
