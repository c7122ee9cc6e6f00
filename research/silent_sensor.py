"""Can a fleet's second UAV sense the field near the team and stay silent?

Every UAV hears every UE's uplink reference signal from where it flies, serving or not
(``uavlink.radio.channel``: ``heard_sinr_db``), so a UAV that serves no UE could still sense the
field for the one that does. But a UE attaches to the UAV it receives best (full reuse, SPEC "A
fleet"), so a UAV near the team takes UEs and interferes. Here the first UAV hovers over the UEs'
centroid (truth: a yardstick, not a policy) and the second keeps ``r`` metres from it in a fixed
direction drawn per episode, or in the corner of the area farthest from the centroid; for each
``r``: the share of frames in which the second UAV serves no UE, the fleet's mean throughput, and
the mean SNR the second UAV hears of the UEs (dB). Spatial channel, D = 2.

    python research/silent_sensor.py                              # no_move and straight, 200 episodes
    python research/silent_sensor.py --scenario no_move --distances 40 80 --episodes 20 --json
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from entry import run_script
from fleet_bars import episode_args

CORNER = -1.0  # a distance standing for "the far corner"


def run(scenarios: list[str], distances_m: list[float], episodes: int, seed: int) -> dict[str, Any]:
    from uavlink.config import EnvConfig
    from uavlink.env.core import BatchedUavEnv

    rows = []
    for scenario in scenarios:
        cfg = EnvConfig(scenario=scenario, n_uavs=2, fleet_slots=1)
        cfg = cfg.replace(**{"radio.shadowing_model": "spatial"}).validate()
        half = cfg.area.half_width_m
        angle = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, episodes)
        direction = np.stack([np.cos(angle), np.sin(angle)], axis=1)
        for r_m in distances_m:
            env = BatchedUavEnv(cfg, n_envs=episodes, seed=seed)  # the same episodes for every r
            env.reset()
            silent, rate, heard = [], [], []
            for _ in range(cfg.episode_frames):
                assert env.mobility is not None  # reset() set it
                centroid = env.mobility.position_m.mean(axis=1)  # (N, 2)
                if r_m == CORNER:
                    second = np.where(centroid >= 0.0, -0.95 * half, 0.95 * half)
                else:
                    second = centroid + r_m * direction
                step = env.step_to(np.stack([centroid, second], axis=1).reshape(-1, 2))
                assert env.readings is not None  # step_to() set them
                silent.append((env.readings.serving != 1).all(axis=1))
                rate.append(step.mean_rate_mbps)
                heard.append(env.readings.heard_sinr_db[:, 1].mean(axis=1))
            rows.append(
                {
                    "scenario": scenario,
                    "distance_m": "corner" if r_m == CORNER else r_m,
                    "silent_share": round(float(np.mean(silent)), 4),
                    "mean_rate_mbps": round(float(np.mean(rate)), 4),
                    "heard_snr_db": round(float(np.mean(heard)), 2),
                }
            )
    return {"episodes": episodes, "seed": seed, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenario", action="append", choices=SCENARIOS,
        help="repeatable (default: no_move, straight)",
    )  # fmt: skip
    parser.add_argument(
        "--distances", type=float, nargs="+", default=[40, 60, 80, 100, 130, 160, CORNER],
        help="metres from the first UAV; -1: the far corner",
    )  # fmt: skip
    args = episode_args(parser, argv, episodes=200, seed=1)
    scenarios = args.scenario or ["no_move", "straight"]
    report = run(scenarios, args.distances, args.episodes, args.seed)
    if args.json:
        print(json.dumps(report))
        return 0
    print(
        "| scenario | second UAV from the first | frames it serves no UE | Mbps | SNR it hears (dB) |"
    )
    print("|---|---|---|---|---|")
    for row in report["rows"]:
        where = row["distance_m"] if row["distance_m"] == "corner" else f"{row['distance_m']:g} m"
        print(
            f"| {row['scenario']} | {where} | {row['silent_share']:.3f} | "
            f"{row['mean_rate_mbps']:.2f} | {row['heard_snr_db']:.1f} |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
