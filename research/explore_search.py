"""Adaptive searches against `explore` on no_move (spatial channel): stop early at a good spot, search again
from a poor one, and probe the cells around the best spot.

`explore` always searches its 32-frame cross, then returns to the best spot it sensed. GPS-free
changes, read from the same observation (the memory of place and the SINRs now):
- stop: leave the search for the best spot once it is worth at least ``stop`` bits/s/Hz (mean over
  UEs of log2(1 + SINR));
- again: if the best spot is worth less than ``again`` bits when the UAV is back on it, fly a
  second cross (diagonals) from there;
- probe: on the best spot after the search, fly to a neighbouring cell never sensed (the memory's
  east, north, west, south); the memory then ranks it, and the UAV stays or goes back. The field
  decorrelates over 50 m but is rough: a cell next to the best one is often better;
- full return: go back to the best spot in one move (explore closes half the distance a frame,
  which suits PX4's motion, not the env's instant moves);
- leg: frames per leg of the search cross (explore: 4);
- spiral: 8 frames after the search, a small square spiral (6 m steps) around where the UAV is, then
  back to the best spot: new cells near it without a multicopter's reversals.
Each variant in each memory grid (``--cell-m``; the shipped map policies and explore's default: 12
m) against explore with its default grid and against today's spatial policy, on the same episodes
(paired ratios, 95 % bootstrap intervals). The target: 1.2x the spatial policy on no_move.

    python research/explore_search.py [--cell-m 12 6] [--episodes 100] [--seed 1] [--set KEY=VALUE] [--json]
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from entry import run_script

from uavlink.config import EnvConfig
from uavlink.env.core import GroundTruth
from uavlink.env.place_memory import sensed_value_bits
from uavlink.evaluation import EvalResult
from uavlink.evaluation.core import evaluate_policy, paired_ratio_ci
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.explore import ExplorePolicy

VARIANTS = {  # name: ExploreVariant's settings (the rest as explore)
    "explore": {},
    "stop 12, again 9": {"stop_bits": 12.0, "again_bits": 9.0},
    "probe": {"probe": True},
    "probe, full return": {"probe": True, "approach_gain": 1.0},
    "stop 11, again 9, probe, full return": {
        "stop_bits": 11.0,
        "again_bits": 9.0,
        "probe": True,
        "approach_gain": 1.0,
    },
    "leg 3, stop 12, again 9, probe, full return": {
        "stop_bits": 12.0,
        "again_bits": 9.0,
        "probe": True,
        "approach_gain": 1.0,
        "search_leg_frames": 3,
    },
    "leg 2, stop 12, again 9.5, probe, full return": {
        "stop_bits": 12.0,
        "again_bits": 9.5,
        "probe": True,
        "approach_gain": 1.0,
        "search_leg_frames": 2,
    },
    "leg 3, stop 12, spiral 12 x 6 m": {
        "stop_bits": 12.0,
        "search_leg_frames": 3,
        "spiral_frames": 12,
    },
}


def square_spiral_deg(frames: int) -> np.ndarray:
    """Headings (deg from east) of a square spiral of one-step legs 1, 1, 2, 2, 3, 3, ..."""
    out: list[float] = []
    leg, turn = 1, 0
    while len(out) < frames:
        for _ in range(2):
            out += [90.0 * turn] * leg
            turn = (turn + 1) % 4
        leg += 1
    return np.array(out[:frames])


class ExploreVariant(ExplorePolicy):
    """explore with an early stop at a good spot, a second cross from a poor one, probes of the
    cells around the best spot, or a small square spiral (``spiral_step_m`` a frame) from where the
    UAV is 8 frames after the search, which a multicopter flies without reversals; one UAV."""

    def __init__(
        self,
        cfg: EnvConfig,
        stop_bits: float | None = None,
        again_bits: float | None = None,
        probe: bool = False,
        approach_gain: float = 0.5,
        search_leg_frames: int = 4,
        spiral_frames: int = 0,
        spiral_step_m: float = 6.0,
    ) -> None:
        super().__init__(cfg, search_leg_frames=search_leg_frames, approach_gain=approach_gain)
        self.stop_bits, self.again_bits, self.probe = stop_bits, again_bits, probe
        self.spiral_deg, self.spiral_step_m = square_spiral_deg(spiral_frames), spiral_step_m
        self.cell_m = cfg.place_cell_m

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        action = super().act(obs, truth)
        frame = self.layout.newest_frame(obs)
        index = np.rint(frame["place_frames"]).astype(int) - 1
        best_bits = sensed_value_bits(frame["sinr_db"]) + np.maximum(
            frame["place_best_gain_bits"], 0.0
        )
        r_max = self.mapping.r_max_m
        offset = frame["place_best_offset_m"]
        go = frame["place_best_gain_bits"] > self.margin_bits
        to_best = self.mapping.towards(offset, np.where(go, self.approach_gain, 0.0))
        if self.stop_bits is not None:
            stop = (index < self.search_frames) & (best_bits >= self.stop_bits)
            action = np.where(stop[:, None], to_best, action)
        if self.again_bits is not None:  # from 8 frames after the first cross: time to get back
            leg, j = self.search_leg_frames, index - (self.search_frames + 8)
            second = (j >= 0) & (j < self.search_frames) & (best_bits < self.again_bits)
            out = (j % (4 * leg) < leg) | (j % (4 * leg) >= 3 * leg)
            heading = np.where(j < 4 * leg, np.where(out, 45.0, 225.0), np.where(out, 135.0, -45.0))
            action = np.where(
                second[:, None],
                self.mapping.from_polar(heading, np.full(len(index), r_max)),
                action,
            )
        if self.probe:
            on_best = np.hypot(offset[:, 0], offset[:, 1]) < self.cell_m / 2
            unknown = frame["place_neighbour_known"] < 0.5  # (rows, 4): east, north, west, south
            probe = (index >= self.search_frames) & on_best & unknown.any(axis=1)
            step = self.mapping.from_polar(
                90.0 * np.argmax(unknown, axis=1), np.full(len(index), min(self.cell_m, r_max))
            )
            action = np.where(probe[:, None], step, action)
        if len(self.spiral_deg):
            j = index - (self.search_frames + 8)
            spiral = (j >= 0) & (j < len(self.spiral_deg))
            step = self.mapping.from_polar(
                self.spiral_deg[np.clip(j, 0, len(self.spiral_deg) - 1)],
                np.full(len(index), self.spiral_step_m),
            )
            action = np.where(spiral[:, None], step, action)
        return action


def no_move_references(settings: list[str], episodes: int, seed: int) -> dict[str, EvalResult]:
    """Today's spatial no_move policy and explore on the same episodes, with ``settings``."""
    on_spatial = EnvOverrides.from_command_line("no_move", None, settings)
    loaded = load_with_env(["policies/spatial/no_move.zip", "explore"], on_spatial)
    return {
        name: evaluate_policy(policy, cfg, episodes, seed)
        for name, (policy, cfg) in zip(("spatial", "explore"), loaded, strict=True)
    }


def versus(result: EvalResult, references: dict[str, EvalResult]) -> dict[str, list[float]]:
    """``vs_<name>``: ``result`` over each reference, paired, with its 95 % interval."""
    return {
        f"vs_{name}": [
            round(x, 4) for x in paired_ratio_ci(result.episode_rate_mbps, base.episode_rate_mbps)
        ]
        for name, base in references.items()
    }


def print_summary(
    episodes: int,
    seed: int,
    settings: list[str],
    references: dict[str, EvalResult],
    rows: list[dict],
    as_json: bool,
) -> bool:
    """Print the run as JSON (then True: nothing more to print) or the references' heading line."""
    summary = {
        "episodes": episodes,
        "seed": seed,
        "settings": settings,
        **{f"{name}_mbps": round(r.mean_rate_mbps, 4) for name, r in references.items()},
        "rows": rows,
    }
    if as_json:
        print(json.dumps(summary, indent=1))
        return True
    print(
        f"spatial policy {summary['spatial_mbps']:.3f} Mbps, explore {summary['explore_mbps']:.3f} Mbps "
        f"({episodes} episodes, seed {seed}, {' '.join(settings)})\n"
    )
    return False


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cell-m", type=float, nargs="+", default=[12.0, 6.0], help="memory grids to try (m)"
    )
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--seed", type=int, default=1, help="evaluation seed (1: validation episodes)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="env overrides for every run, e.g. uav_motion=px4",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    settings = ["radio.shadowing_model=spatial", *args.overrides]
    references = no_move_references(settings, args.episodes, args.seed)
    rows = []
    for cell_m in args.cell_m:
        [(_, cfg)] = load_with_env(
            ["explore"],
            EnvOverrides.from_command_line(
                "no_move", None, [*settings, f"place_cell_m={cell_m:g}"]
            ),
        )
        for name, variant in VARIANTS.items():
            result = evaluate_policy(ExploreVariant(cfg, **variant), cfg, args.episodes, args.seed)
            rows.append(
                {
                    "cell_m": cell_m,
                    "variant": name,
                    "mean_rate_mbps": round(result.mean_rate_mbps, 4),
                    **versus(result, references),
                }
            )
    if print_summary(args.episodes, args.seed, settings, references, rows, args.json):
        return 0
    print("| cell (m) | variant | Mbps | vs explore | vs spatial policy |\n|---|---|---:|---|---|")
    for r in rows:
        cells = [
            f"{(x[0] - 1) * 100:+.1f} % [{(x[1] - 1) * 100:+.1f}, {(x[2] - 1) * 100:+.1f}]"
            for x in (r["vs_explore"], r["vs_spatial"])
        ]
        print(
            f"| {r['cell_m']:g} | {r['variant']} | {r['mean_rate_mbps']:.3f} | {cells[0]} | {cells[1]} |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
