"""Flight-loop latency: radio report in -> setpoint out, over a real flight at --speed 20.

Flies one 128-frame episode through the embedded SITL (a separate process, loopback UDP) with each
policy runtime, side by side in one run: the SB3 zip, its ONNX export, and the `aoa` rule. Reports
per policy: decision latency (report arrival to setpoint sent) p50/p99, per-decision inference
time p50/p99, the speed factor the loop sustained, and the episode's wall time.

Targets: latency p99 < 5 ms with the SB3 policy; a 128-frame episode in < 10 s
of wall time at --speed 20; ONNX inference p99 < 50 us and >= 3x faster than SB3.

    python benchmarks/flight_latency.py [--policy policies/circular.zip] [--json]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def fly(policy: str, scenario: str, seed: int, speed: float, out: Path) -> dict:
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
        "--speed",
        f"{speed:g}",
        "--out",
        str(out),
        "--json",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=300)
    if proc.returncode != 0:
        raise SystemExit(f"fly failed for {policy}: {proc.stderr.strip()}")
    return json.loads(proc.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="policies/circular.zip")
    parser.add_argument("--scenario", default="circular")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--speed", type=float, default=20.0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        onnx = Path(tmp) / "policy.onnx"
        export = subprocess.run(
            [sys.executable, "-m", "uavlink.cli", "export", args.policy, "--out", str(onnx)],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=300,
        )
        runtimes = {"sb3": args.policy, "aoa": "aoa"}
        if export.returncode == 0:
            runtimes["onnx"] = str(onnx)
        for name, policy in runtimes.items():
            rows[name] = fly(policy, args.scenario, args.seed, args.speed, Path(tmp) / name)
    keys = (
        "latency_ms_p50",
        "latency_ms_p99",
        "inference_us_p50",
        "inference_us_p99",
        "speed_factor",
        "episode_wall_s",
        "mean_rate_mbps",
    )
    result = {
        "scenario": args.scenario,
        "seed": args.seed,
        "speed": args.speed,
        "runtimes": {n: {k: r[k] for k in keys} for n, r in rows.items()},
    }
    if "onnx" in rows:
        result["onnx_inference_speedup_p99"] = round(
            rows["sb3"]["inference_us_p99"] / rows["onnx"]["inference_us_p99"], 2
        )
        result["onnx_inference_speedup_p50"] = round(
            rows["sb3"]["inference_us_p50"] / rows["onnx"]["inference_us_p50"], 2
        )
    if args.json:
        print(json.dumps(result, indent=2))
        return
    print(
        "| runtime | latency p50 (ms) | latency p99 (ms) | inference p50 (µs) | inference p99 (µs) | speed factor | episode wall (s) | Mbps |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, r in result["runtimes"].items():
        print(f"| {name} | " + " | ".join(f"{r[k]}" for k in keys) + " |")
    if "onnx" in rows:
        print(
            f"\nONNX inference speed-up over SB3: p50 {result['onnx_inference_speedup_p50']}x, "
            f"p99 {result['onnx_inference_speedup_p99']}x"
        )


if __name__ == "__main__":
    main()
