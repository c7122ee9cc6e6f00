"""Adaptive searches against `explore` on no_move (spatial channel): stop early at a good spot, search again
from a poor one.

`explore` always searches its 32-frame cross, then returns to the best spot it sensed. Two GPS-free
changes, read from the same observation (the memory of place and the SINRs now):
- stop: leave the search for the best spot once it is worth at least ``stop`` bits/s/Hz (mean over
  UEs of log2(1 + SINR));
- again: if the best spot is worth less than ``again`` bits when the UAV is back on it, fly a
  second cross (diagonals) from there.
Each variant against explore on the same episodes (paired ratio, 95 % bootstrap interval). Issue 23
asks for 1.2x today's spatial policy on no_move, about +6.6 % over explore.

    python benchmarks/explore_search.py [--episodes 100] [--seed 1] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from uavlink.env.place_memory import sensed_value_bits
from uavlink.evaluation.core import evaluate_policy, paired_ratio_ci
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.explore import ExplorePolicy

VARIANTS = {"stop 11": (11.0, None), "stop 12": (12.0, None), "stop 13": (13.0, None),
            "again 9": (None, 9.0), "stop 12, again 9": (12.0, 9.0), "stop 13, again 9": (13.0, 9.0)}


class AdaptiveExplore(ExplorePolicy):
    """explore, with an early stop at a good spot and a second cross from a poor one."""

    def __init__(self, cfg, stop_bits: float | None, again_bits: float | None) -> None:
        super().__init__(cfg)
        self.stop_bits, self.again_bits = stop_bits, again_bits

    def act(self, obs: np.ndarray, truth=None) -> np.ndarray:
        action = super().act(obs, truth)
        frame = self.layout.newest_frame(obs)
        index = np.rint(frame["place_frames"]).astype(int) - 1
        best_bits = sensed_value_bits(frame["sinr_db"]) + np.maximum(frame["place_best_gain_bits"], 0.0)
        r_max = self.mapping.r_max_m
        offset = frame["place_best_offset_m"]
        distance = np.minimum(self.approach_gain * np.hypot(offset[:, 0], offset[:, 1]), r_max)
        go = frame["place_best_gain_bits"] > self.margin_bits
        to_best = self.mapping.from_polar(np.degrees(np.arctan2(offset[:, 1], offset[:, 0])),
                                          np.where(go, distance, 0.0))
        if self.stop_bits is not None:
            stop = (index < self.search_frames) & (best_bits >= self.stop_bits)
            action = np.where(stop[:, None], to_best, action)
        if self.again_bits is not None:  # from 8 frames after the first cross: time to get back
            leg, j = self.search_leg_frames, index - (self.search_frames + 8)
            second = (j >= 0) & (j < self.search_frames) & (best_bits < self.again_bits)
            out = (j % (4 * leg) < leg) | (j % (4 * leg) >= 3 * leg)
            heading = np.where(j < 4 * leg, np.where(out, 45.0, 225.0), np.where(out, 135.0, -45.0))
            action = np.where(second[:, None], self.mapping.from_polar(heading, np.full(len(index), r_max)),
                              action)
        return action


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=1, help="evaluation seed (1: validation episodes)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    overrides = EnvOverrides.from_command_line("no_move", None, ["radio.shadowing_model=spatial"])
    [(explore, cfg)] = load_with_env(["explore"], overrides)
    base = evaluate_policy(explore, cfg, args.episodes, args.seed)
    rows = [{"variant": "explore", "mean_rate_mbps": round(base.mean_rate_mbps, 4)}]
    for name, (stop, again) in VARIANTS.items():
        result = evaluate_policy(AdaptiveExplore(cfg, stop, again), cfg, args.episodes, args.seed)
        ratio, low, high = paired_ratio_ci(result.episode_rate_mbps, base.episode_rate_mbps)
        rows.append({"variant": name, "mean_rate_mbps": round(result.mean_rate_mbps, 4),
                     "vs_explore_pct": [round((x - 1) * 100, 2) for x in (ratio, low, high)]})
    if args.json:
        print(json.dumps({"episodes": args.episodes, "seed": args.seed, "rows": rows}, indent=1))
        return 0
    print("| variant | Mbps | vs explore |\n|---|---:|---|")
    for r in rows:
        gain = r.get("vs_explore_pct")
        print(f"| {r['variant']} | {r['mean_rate_mbps']:.3f} | "
              + (f"{gain[0]:+.1f} % [{gain[1]:+.1f}, {gain[2]:+.1f}]" if gain else "") + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
