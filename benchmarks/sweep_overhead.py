"""Sweep engine: overhead per job and the speed-up of 2 Dask workers over a sequential run.

Runs the same N CPU-bound jobs (short PPO trainings on `straight`, one per seed, plus their
evaluations) three ways, side by side, each end to end through ``run_sweep`` into a fresh folder:
  (a) sequential: in this process, one after another, no Dask (``--workers 0``);
  (b) Dask, embedded LocalCluster with 1 worker process: wall time minus the jobs' own summed time
      (measured inside each job on its worker) is the engine's cost; divided by N, per job. It
      includes starting and stopping the cluster, each worker's imports, shipping results back
      and writing them;
  (c) Dask, LocalCluster with 2 worker processes x 1 thread: speed-up = wall(a) / wall(c).
Each run pays the same one-off torch/SB3 import once per process. On a shared machine other
processes take cores from the workers: the load averages before and after, and each run's
``job_cpu_share`` (the jobs' CPU time over their wall time; 1.0 when every job had a core to
itself), are in the output so a contended measurement shows as one.

Targets: < 1 s of engine overhead per job; >= 1.6x speed-up with 2 workers on 2 cores.

    python benchmarks/sweep_overhead.py               # Markdown table
    python benchmarks/sweep_overhead.py --json        # one JSON object
    python benchmarks/sweep_overhead.py --jobs 8 --episodes 64      # quicker, fixed costs weigh more
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
from pathlib import Path
from typing import Any

from uavlink.sweep.runner import SweepOutcome, run_sweep
from uavlink.sweep.sweep_file import parse_spec

TARGET_OVERHEAD_S = 1.0
TARGET_SPEEDUP = 1.6


def _spec(jobs: int, episodes: int):
    return parse_spec(
        {
            "name": "bench",
            "scenarios": ["straight"],
            "seeds": jobs,
            "train": {"episodes": episodes, "n_envs": 8, "batch_size": 256, "n_epochs": 4},
            "eval": {"episodes": 8, "seed": 0},
        }
    )


def _run(
    label: str, workers: int, jobs: int, episodes: int, root: Path, quiet: bool
) -> dict[str, Any]:
    log = (lambda _: None) if quiet else (lambda msg: print(f"[{label}] {msg}", file=sys.stderr))
    outcome: SweepOutcome = run_sweep(
        _spec(jobs, episodes), root / label, workers=workers, progress=False, log=log
    )
    if outcome.finished != jobs:
        raise SystemExit(
            f"{label}: only {outcome.finished}/{jobs} jobs finished ({outcome.failed})"
        )
    jobs_s = sum(outcome.job_s)
    parallel = max(workers, 1)
    return {
        "label": label,
        "workers": workers,
        "jobs": jobs,
        "wall_s": round(outcome.wall_s, 3),
        "jobs_summed_s": round(jobs_s, 3),
        "job_s_mean": round(jobs_s / jobs, 3),
        # Wall time beyond the jobs' own, per job (with P workers the jobs' own share is sum / P).
        "overhead_per_job_s": round((outcome.wall_s - jobs_s / parallel) / jobs, 3),
        # CPU time / wall time of the jobs: 1.0 when each job had a core to itself.
        "job_cpu_share": round(sum(outcome.cpu_s) / jobs_s, 3),
        "engine": outcome.engine or "in-process, sequential",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=8, help="jobs per run (default 8)")
    parser.add_argument(
        "--episodes", type=int, default=256, help="training episodes per job (default 256)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args()

    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="uavlink-sweep-bench-") as tmp:
        root = Path(tmp)
        sequential = _run("sequential", 0, args.jobs, args.episodes, root, args.json)
        one = _run("dask-1-worker", 1, args.jobs, args.episodes, root, args.json)
        two = _run("dask-2-workers", 2, args.jobs, args.episodes, root, args.json)
    speedup = sequential["wall_s"] / two["wall_s"]
    report = {
        "benchmark": "sweep_overhead",
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "load_avg_before": [round(x, 2) for x in load_before],
            "load_avg_after": [round(x, 2) for x in os.getloadavg()],
        },
        "job": {
            "scenario": "straight",
            "train_episodes": args.episodes,
            "env_steps": args.episodes * 128,
            "eval_episodes_per_policy": 8,
        },
        "runs": [sequential, one, two],
        "engine_overhead_per_job_s": one["overhead_per_job_s"],
        "speedup_2_workers": round(speedup, 3),
        "targets": {
            "overhead_per_job_s_below": TARGET_OVERHEAD_S,
            "speedup_at_least": TARGET_SPEEDUP,
        },
        "met": {
            "overhead": one["overhead_per_job_s"] < TARGET_OVERHEAD_S,
            "speedup": speedup >= TARGET_SPEEDUP,
        },
    }
    if args.json:
        print(json.dumps(report, indent=2))
        return
    print(
        f"{args.jobs} jobs of {args.episodes * 128:,} PPO env steps each on {os.cpu_count()} CPUs "
        f"(load {load_before[0]:.1f} before)\n"
    )
    print("| run | wall (s) | jobs' own, summed (s) | overhead per job (s) | job CPU share |")
    print("|---|---|---|---|---|")
    for run in report["runs"]:
        print(
            f"| {run['label']} | {run['wall_s']:.1f} | {run['jobs_summed_s']:.1f} | "
            f"{run['overhead_per_job_s']:.2f} | {run['job_cpu_share']:.2f} |"
        )
    print(
        f"\nengine overhead per job (1 worker): {one['overhead_per_job_s']:.2f} s (target < {TARGET_OVERHEAD_S} s)"
    )
    print(f"speed-up of 2 workers over sequential: {speedup:.2f}x (target >= {TARGET_SPEEDUP}x)")


if __name__ == "__main__":
    main()
