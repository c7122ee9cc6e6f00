"""Per-decision policy inference latency: SB3 (torch) vs the exported ONNX (onnxruntime), one run.

The flight loop asks for one action per frame from ONE observation, so this times ``act`` on a
(1, obs) array: ``SB3Policy.act`` (``PPO.predict(deterministic=True)``, torch at 1 thread) and
``OnnxPolicy.act`` (onnxruntime, 1 thread, pre-bound buffers), in alternating blocks of 100 calls
so both see the same machine load, on observations the policy meets in seeded episodes.

Targets: ONNX p99 < 50 us per decision, and ONNX >= 3x faster than SB3 (p50 ratio).

    python benchmarks/inference_latency.py [--policy policies/circular.zip] [--calls 2000] [--json]

Without --policy it uses policies/circular.zip if present, else trains a tiny policy in a temp dir.
``--check`` exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_POLICY = ROOT / "policies" / "circular.zip"
ONNX_P99_TARGET_US = 50.0
SPEEDUP_TARGET = 3.0
BLOCK = 100


def tiny_policy(folder: Path) -> Path:
    """A quickly trained stand-in policy (same network shape as a real one: 3 x 128)."""
    from uavlink.config import EnvConfig
    from uavlink.training import TrainConfig, train

    out = folder / "tiny.zip"
    train(EnvConfig(scenario="no_move"), TrainConfig(episodes=40, n_envs=8, batch_size=256), out, None,
          progress=False)
    return out


def percentiles(samples_ns: list[int]) -> dict[str, float]:
    us = np.asarray(samples_ns, dtype=float) / 1e3
    return {"p50_us": round(float(np.percentile(us, 50)), 2), "p99_us": round(float(np.percentile(us, 99)), 2),
            "mean_us": round(float(us.mean()), 2), "max_us": round(float(us.max()), 2)}


def measure(zip_path: Path, onnx_path: Path, calls: int, warmup: int, seed: int) -> dict[str, Any]:
    import torch

    from uavlink.export import verification_observations
    from uavlink.policies.onnx_policy import OnnxPolicy
    from uavlink.policies.sb3_policy import SB3Policy

    torch.set_num_threads(1)
    sb3, onnx = SB3Policy(zip_path), OnnxPolicy(onnx_path)
    pool = verification_observations(sb3, 512, seed)
    singles = [pool[i:i + 1].copy() for i in range(len(pool))]
    timer = time.perf_counter_ns
    for i in range(warmup):
        sb3.act(singles[i % len(singles)])
        onnx.act(singles[i % len(singles)])
    # Alternate blocks of BLOCK calls: both paths see the same load over the run, while each
    # keeps its caches warm within a block, as in flight where only one path runs.
    sb3_ns: list[int] = []
    onnx_ns: list[int] = []
    for start in range(0, calls, BLOCK):
        block = [singles[i % len(singles)] for i in range(start, min(calls, start + BLOCK))]
        for policy, samples in ((sb3, sb3_ns), (onnx, onnx_ns)):
            for obs in block:
                begin = timer()
                policy.act(obs)
                samples.append(timer() - begin)
    stacked = np.concatenate(singles)
    max_diff = float(np.abs(sb3.act(stacked) - onnx.act(stacked)).max())
    sb3_stats, onnx_stats = percentiles(sb3_ns), percentiles(onnx_ns)
    speedup_p50 = sb3_stats["p50_us"] / onnx_stats["p50_us"]
    speedup_p99 = sb3_stats["p99_us"] / onnx_stats["p99_us"]
    return {
        "policy": str(zip_path), "obs_size": int(pool.shape[1]), "calls": calls, "warmup": warmup,
        "batch": 1, "threads": 1, "sb3": sb3_stats, "onnx": onnx_stats,
        "speedup_p50": round(speedup_p50, 2), "speedup_p99": round(speedup_p99, 2),
        "max_abs_action_diff": max_diff,
        "targets": {"onnx_p99_us_below": ONNX_P99_TARGET_US, "speedup_at_least": SPEEDUP_TARGET},
        "targets_met": onnx_stats["p99_us"] < ONNX_P99_TARGET_US and speedup_p50 >= SPEEDUP_TARGET,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path, default=None, help="SB3 policy zip (default policies/circular.zip)")
    parser.add_argument("--calls", type=int, default=2000, help="timed calls per path")
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0, help="seed of the episodes the observations come from")
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = parser.parse_args(argv)

    from uavlink.export import export_onnx

    with tempfile.TemporaryDirectory(prefix="uavlink-latency-") as tmp:
        zip_path = args.policy or (DEFAULT_POLICY if DEFAULT_POLICY.is_file() else None)
        if zip_path is None:
            print("policies/circular.zip not found; training a tiny stand-in policy", file=sys.stderr)
            zip_path = tiny_policy(Path(tmp))
        onnx_path = Path(tmp) / (zip_path.stem + ".onnx")
        export_onnx(zip_path, onnx_path, verify=True, n_verify=1000, seed=args.seed)
        result = measure(zip_path, onnx_path, args.calls, args.warmup, args.seed)

    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"policy {result['policy']} (obs {result['obs_size']}), {args.calls} single-observation calls, 1 thread")
        print(f"{'path':<6} {'p50 us':>8} {'p99 us':>8} {'mean us':>8}")
        for key in ("sb3", "onnx"):
            s = result[key]
            print(f"{key:<6} {s['p50_us']:>8.1f} {s['p99_us']:>8.1f} {s['mean_us']:>8.1f}")
        print(f"speed-up p50 {result['speedup_p50']:.1f}x, p99 {result['speedup_p99']:.1f}x; targets "
              f"(ONNX p99 < {ONNX_P99_TARGET_US:g} us, >= {SPEEDUP_TARGET:g}x) "
              f"{'met' if result['targets_met'] else 'MISSED'}")
    return 0 if result["targets_met"] or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
