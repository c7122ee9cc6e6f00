"""Per-decision policy inference latency: SB3 (torch) vs the exported ONNX (onnxruntime), one run.

The flight loop asks for one action per frame from ONE observation, so this times ``act`` on a
(1, obs) array, three ways: ``PPO.predict(deterministic=True)`` as SB3 users call it; ``SB3Policy.act``
(the flight loop's torch path: the same computation without predict's per-call checks, torch at 1
thread); and ``OnnxPolicy.act`` (onnxruntime, 1 thread, pre-bound buffers). They run in alternating
blocks of 500 timed calls (each after 20 untimed ones, since in flight only one path runs
and its caches stay warm) so all see the same machine load, on observations the policy meets in seeded
episodes, with the garbage collector off while timing (as ``timeit`` does).

Targets: ONNX p99 < 50 us per decision, and ONNX >= 3x faster than the flight loop's SB3 path
(``SB3Policy.act``, the stricter comparison) at p50 and p99.

    python benchmarks/inference_latency.py [--policy policies/circular.zip] [--calls 5000] [--json]

Without --policy it uses policies/circular.zip if present, else trains a tiny policy in a temp dir.
``--check`` exits 1 when a target is missed.
"""

from __future__ import annotations

import argparse
import gc
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
BLOCK = 500
BLOCK_WARMUP = 20  # untimed calls when a path resumes: in flight only one path runs, warm


def tiny_policy(folder: Path) -> Path:
    """A quickly trained stand-in policy (same network shape as a real one: 3 x 128)."""
    from uavlink.config import EnvConfig, TrainConfig
    from uavlink.learn.training import train

    out = folder / "tiny.zip"
    train(
        EnvConfig(scenario="no_move"),
        TrainConfig(episodes=40, n_envs=8, batch_size=256),
        out,
        None,
        progress=False,
    )
    return out


def percentiles(samples_ns: list[int]) -> dict[str, float]:
    us = np.asarray(samples_ns, dtype=float) / 1e3
    return {
        "p50_us": round(float(np.percentile(us, 50)), 2),
        "p99_us": round(float(np.percentile(us, 99)), 2),
        "mean_us": round(float(us.mean()), 2),
        "max_us": round(float(us.max()), 2),
    }


def measure(zip_path: Path, onnx_path: Path, calls: int, warmup: int, seed: int) -> dict[str, Any]:
    import torch

    from uavlink.export import verification_observations
    from uavlink.policies.onnx_policy import OnnxPolicy
    from uavlink.policies.sb3_policy import SB3Policy

    torch.set_num_threads(1)
    sb3, onnx = SB3Policy(zip_path), OnnxPolicy(onnx_path)
    pool = verification_observations(sb3, 512, seed)
    singles = [pool[i : i + 1].copy() for i in range(len(pool))]
    timer = time.perf_counter_ns
    for i in range(warmup):
        sb3.act(singles[i % len(singles)])
        onnx.act(singles[i % len(singles)])
    paths = {
        "sb3_predict": lambda obs: sb3.model.predict(obs, deterministic=True),
        "sb3": sb3.act,
        "onnx": onnx.act,
    }
    samples: dict[str, list[int]] = {name: [] for name in paths}
    gc.disable()
    try:
        for start in range(0, calls, BLOCK):
            block = [singles[i % len(singles)] for i in range(start, min(calls, start + BLOCK))]
            for name, act in paths.items():
                for obs in block[:BLOCK_WARMUP]:
                    act(obs)
                for obs in block:
                    begin = timer()
                    act(obs)
                    samples[name].append(timer() - begin)
    finally:
        gc.enable()
    stacked = np.concatenate(singles)
    max_diff = float(np.abs(sb3.act(stacked) - onnx.act(stacked)).max())
    stats = {name: percentiles(ns) for name, ns in samples.items()}
    onnx_stats = stats["onnx"]
    speedups = {
        f"{q}_vs_{ref}": round(stats[ref][f"{q}_us"] / onnx_stats[f"{q}_us"], 2)
        for ref in ("sb3", "sb3_predict")
        for q in ("p50", "p99")
    }
    return {
        "policy": str(zip_path),
        "obs_size": int(pool.shape[1]),
        "calls": calls,
        "warmup": warmup,
        "batch": 1,
        "threads": 1,
        **stats,
        "onnx_speedup": speedups,
        "max_abs_action_diff": max_diff,
        "targets": {"onnx_p99_us_below": ONNX_P99_TARGET_US, "speedup_at_least": SPEEDUP_TARGET},
        "targets_missed": [
            name
            for name, met in (
                (
                    f"ONNX p99 < {ONNX_P99_TARGET_US:g} us (was {onnx_stats['p99_us']:.1f})",
                    onnx_stats["p99_us"] < ONNX_P99_TARGET_US,
                ),
                (
                    f">= {SPEEDUP_TARGET:g}x vs SB3Policy.act (was {min(speedups['p50_vs_sb3'], speedups['p99_vs_sb3']):.1f}x)",
                    min(speedups["p50_vs_sb3"], speedups["p99_vs_sb3"]) >= SPEEDUP_TARGET,
                ),
            )
            if not met
        ],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--policy", type=Path, default=None, help="SB3 policy zip (default policies/circular.zip)"
    )
    parser.add_argument("--calls", type=int, default=5000, help="timed calls per path")
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the episodes the observations come from"
    )
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = parser.parse_args(argv)

    from uavlink.export import export_onnx

    with tempfile.TemporaryDirectory(prefix="uavlink-latency-") as tmp:
        zip_path = args.policy or (DEFAULT_POLICY if DEFAULT_POLICY.is_file() else None)
        if zip_path is None:
            print(
                "policies/circular.zip not found; training a tiny stand-in policy", file=sys.stderr
            )
            zip_path = tiny_policy(Path(tmp))
        onnx_path = Path(tmp) / (zip_path.stem + ".onnx")
        export_onnx(zip_path, onnx_path, verify=True, n_verify=1000, seed=args.seed)
        result = measure(zip_path, onnx_path, args.calls, args.warmup, args.seed)

    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"policy {result['policy']} (obs {result['obs_size']}), {args.calls} single-observation calls, 1 thread"
        )
        print("| path | p50 (µs) | p99 (µs) | mean (µs) |\n|---|---:|---:|---:|")
        for key in ("sb3_predict", "sb3", "onnx"):
            s = result[key]
            print(f"| {key} | {s['p50_us']:.1f} | {s['p99_us']:.1f} | {s['mean_us']:.1f} |")
        sp = result["onnx_speedup"]
        print(
            f"\nONNX speed-up: vs SB3Policy.act p50 {sp['p50_vs_sb3']:.1f}x, p99 {sp['p99_vs_sb3']:.1f}x; "
            f"vs PPO.predict p50 {sp['p50_vs_sb3_predict']:.1f}x, p99 {sp['p99_vs_sb3_predict']:.1f}x; "
            f"targets (ONNX p99 < {ONNX_P99_TARGET_US:g} us, >= {SPEEDUP_TARGET:g}x vs SB3Policy.act) "
            + (
                "met"
                if not result["targets_missed"]
                else "MISSED: " + "; ".join(result["targets_missed"])
            )
        )
    return 0 if not result["targets_missed"] or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
