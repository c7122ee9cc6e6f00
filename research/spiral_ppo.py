"""Does PPO keep (or beat) the spiral search it copies? A no_move map policy on a 6 m memory grid,
warm-started from ``explore_search.py``'s "leg 3, stop 12, spiral 12 x 6 m" rule.

map.toml's no_move recipe (24,000 episodes, PPO after a 512-episode copy at log std -2.5), with the
rule in place of `explore` as the teacher: the factory the warm start calls is wrapped for this
script only, so `train` runs unchanged. The policies go to a temporary folder (not shipped). Each
seed's PPO and the rule against today's spatial no_move policy, with instant moves and with PX4's
(paired ratios, 95 % bootstrap intervals).

    python research/spiral_ppo.py [--seeds 0 1] [--train-episodes 24000] [--episodes 100] [--seed 1] [--json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from entry import run_script
from explore_search import ExploreVariant

import uavlink.learn.teachers as teachers
from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.fields import with_changes
from uavlink.evaluation.core import evaluate_policy, paired_ratio_ci
from uavlink.learn.training import train
from uavlink.policies.contract import EnvOverrides, load_with_env

SPIRAL = {"stop_bits": 12.0, "search_leg_frames": 3, "spiral_frames": 12}
CELL_M = 6.0


def spiral_teacher_factory(make_teacher):
    """``make_teacher`` with the spiral rule in place of the explore rule."""

    def make(cfg, teacher, *args, **kwargs):
        return (
            ExploreVariant(cfg, **SPIRAL)
            if teacher == "explore"
            else make_teacher(cfg, teacher, *args, **kwargs)
        )

    return make


def train_one(seed: int, episodes: int, out: Path) -> None:
    cfg = (
        EnvConfig()
        .replace(scenario="no_move", place_cell_m=CELL_M, **{"radio.shadowing_model": "spatial"})
        .validate()
    )
    tc = with_changes(
        TrainConfig(),
        {
            "episodes": episodes,
            "seed": seed,
            "aoa_noise_max_deg": 0.0,
            "torch_threads": 1,
            "warm_start.teacher": "explore",
            "warm_start.episodes": 512,
            "warm_start.epochs": 40,
            "warm_start.log_std": -2.5,
        },
    ).validate(cfg)
    real = teachers.make_teacher
    teachers.make_teacher = spiral_teacher_factory(real)
    try:
        train(cfg, tc, out, progress=False)
    finally:
        teachers.make_teacher = real


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="training seeds")
    parser.add_argument("--train-episodes", type=int, default=24000)
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes")
    parser.add_argument(
        "--seed", type=int, default=1, help="evaluation seed (1: validation episodes)"
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = [Path(tmp) / f"no_move_s{seed}.zip" for seed in args.seeds]
        for seed, path in zip(args.seeds, files, strict=True):
            train_one(seed, args.train_episodes, path)
        for motion in ("instant", "px4"):
            overrides = EnvOverrides.from_command_line(
                "no_move", None, ["radio.shadowing_model=spatial", f"uav_motion={motion}"]
            )
            [(spatial, spatial_cfg), *trained] = load_with_env(
                ["policies/spatial/no_move.zip", *map(str, files)], overrides
            )
            base = evaluate_policy(spatial, spatial_cfg, args.episodes, args.seed)
            rule_cfg = trained[0][1]
            candidates = {
                "rule": (ExploreVariant(rule_cfg, **SPIRAL), rule_cfg),
                **{f"PPO seed {s}": t for s, t in zip(args.seeds, trained, strict=True)},
            }
            for name, (policy, cfg) in candidates.items():
                result = evaluate_policy(policy, cfg, args.episodes, args.seed)
                rows.append(
                    {
                        "motion": motion,
                        "policy": name,
                        "mean_rate_mbps": round(result.mean_rate_mbps, 4),
                        "spatial_mbps": round(base.mean_rate_mbps, 4),
                        "vs_spatial": [
                            round(x, 4)
                            for x in paired_ratio_ci(
                                result.episode_rate_mbps, base.episode_rate_mbps
                            )
                        ],
                    }
                )
    if args.json:
        print(json.dumps({"episodes": args.episodes, "seed": args.seed, "rows": rows}, indent=1))
        return 0
    print("| motion | policy | Mbps | vs spatial policy |\n|---|---|---:|---|")
    for r in rows:
        v = r["vs_spatial"]
        print(
            f"| {r['motion']} | {r['policy']} | {r['mean_rate_mbps']:.3f} | {v[0]:.3f} [{v[1]:.3f}, {v[2]:.3f}] |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
