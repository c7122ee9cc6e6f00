"""What the genie costs: seconds per evaluated episode, one UAV and a fleet, on the spatial channel.

The genie plans each episode when it starts (``uavlink.policies.genie``): the grid's received powers,
the DP, and for a fleet the per-UAV rounds; then the episode is flown like any policy's. It plans a
batch's episodes on one thread per CPU (``GeniePolicy.workers``). Measured here, in one run on the
same episodes: wall and process-CPU seconds per episode of ``evaluate_policy`` with the genie on
one thread and on its default threads, and the static baseline (the rollout alone). Target:
100 episodes of one UAV in minutes, not hours: ``projected_100_episodes_min`` is 100 x the
threaded wall seconds per episode.

    python benchmarks/genie_cost.py --json
    python benchmarks/genie_cost.py --episodes 8 --uavs 1 2 3
"""

from __future__ import annotations

import argparse
import json
import time

from run_record import command, machine

from uavlink.config import EnvConfig
from uavlink.evaluation import evaluate_policy
from uavlink.policies.registry import make_baseline

TARGET_100_MIN = 10.0  # "minutes, not hours"


def timed(
    name: str, cfg: EnvConfig, episodes: int, seed: int, workers: int | None = None
) -> tuple[float, float, float, object]:
    """(wall s, CPU s, mean Mbps, the policy) of evaluating baseline ``name`` over ``episodes`` (the
    genie on ``workers`` threads, its default when None)."""
    policy = make_baseline(name, cfg)
    if workers is not None:
        policy.workers = workers
    wall, cpu = time.perf_counter(), time.process_time()
    result = evaluate_policy(policy, cfg, episodes, seed)
    return time.perf_counter() - wall, time.process_time() - cpu, result.mean_rate_mbps, policy


def measure(scenario: str, n_uavs: int, episodes: int, seed: int) -> dict:
    cfg = (
        EnvConfig(scenario=scenario)
        .replace(**{"radio.shadowing_model": "spatial", "n_uavs": n_uavs})
        .validate()
    )
    static_wall, static_cpu, _, _ = timed("static", cfg, episodes, seed)
    serial_wall, serial_cpu, serial_mbps, _ = timed("genie", cfg, episodes, seed, workers=1)
    wall, cpu, mbps, genie = timed("genie", cfg, episodes, seed)
    if mbps != serial_mbps:
        raise AssertionError(f"the threaded plan flew {mbps} Mbps, the serial one {serial_mbps}")
    return {
        "scenario": scenario,
        "n_uavs": n_uavs,
        "episodes": episodes,
        "seed": seed,
        "threads": genie.workers,
        "genie_wall_s_per_episode": round(wall / episodes, 3),
        "genie_cpu_s_per_episode": round(cpu / episodes, 3),
        "genie_one_thread_wall_s_per_episode": round(serial_wall / episodes, 3),
        "genie_one_thread_cpu_s_per_episode": round(serial_cpu / episodes, 3),
        "thread_speedup": round(serial_wall / wall, 2),
        "static_wall_s_per_episode": round(static_wall / episodes, 4),
        "static_cpu_s_per_episode": round(static_cpu / episodes, 4),
        "projected_100_episodes_min": round(100 * wall / episodes / 60, 2),
        "genie_mbps": round(mbps, 3),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=8, help="per run (default 8)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--scenario", default="straight_180")
    parser.add_argument("--uavs", nargs="+", type=int, default=[1, 2])
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = [measure(args.scenario, d, args.episodes, args.seed) for d in args.uavs]
    one = next((r for r in rows if r["n_uavs"] == 1), None)
    out = {
        "rows": rows,
        "target_100_min": TARGET_100_MIN,
        "met": None if one is None else one["projected_100_episodes_min"] <= TARGET_100_MIN,
        "machine": machine(),
        "command": command("genie_cost.py", argv),
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for r in rows:
            print(
                f"D={r['n_uavs']}: genie {r['genie_wall_s_per_episode']:.2f} s/episode wall on {r['threads']} "
                f"threads, {r['genie_one_thread_wall_s_per_episode']:.2f} s on one ({r['thread_speedup']:.2f}x; "
                f"static {r['static_wall_s_per_episode']:.3f} s); 100 episodes ~ "
                f"{r['projected_100_episodes_min']:.1f} min"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
