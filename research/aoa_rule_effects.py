"""The figures behind docs/design/radio.md's and learning.md's notes on shadowing and the warm start, one run.

1. What the SPEC's memoryless shadowing rewards: over the same seeded episodes, hovering
   (``static``), a 12 m east-west zig-zag (moving all the time) and the ``aoa`` rule (moving only
   while the SINRs sit below the hover level), on ``no_move`` and ``straight_180``.
2. How good the warm start's copy of the rule is before PPO: the actor of a fresh PPO model cloned
   as ``uavlink train --warm-start aoa`` does (``TrainConfig``'s defaults, the shipped sweep's
   training AoA noise), flown deterministically, against the rule itself.

The variants of the rule that the warm start copies on some scenarios: research/aoa_teacher_search.py.

    python research/aoa_rule_effects.py [--episodes 100] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from entry import run_script

from uavlink.config import EnvConfig
from uavlink.env.core import GroundTruth
from uavlink.evaluation import evaluate_policy
from uavlink.policies.registry import make_baseline

SHADOWING_SCENARIOS = ("no_move", "straight_180")
CLONE_SCENARIOS = ("no_move", "straight_180", "hotspot")
TRAIN_AOA_NOISE_MAX_DEG = 100.0  # as sweeps/table1.toml


class ZigZag:
    """Full 12 m moves east and west in turn: always moving, so every frame re-draws shadowing."""

    name = "zigzag"
    layout = None
    needs_truth = False

    def __init__(self) -> None:
        self.frame = 0

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        self.frame += 1
        action = np.zeros((obs.shape[0], 2), np.float32)
        action[:, 0] = 1.0 if self.frame % 2 else -1.0
        return action


class ClonedActor:
    """The cloned PPO actor, deterministic, behind the Policy interface."""

    name = "clone"
    layout = None
    needs_truth = False

    def __init__(self, model: Any) -> None:
        self.model = model

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        return self.model.predict(obs, deterministic=True)[0]


def clone_of_the_rule(cfg: EnvConfig) -> ClonedActor:
    from uavlink.config import TrainConfig, WarmStartConfig
    from uavlink.learn.imitation import warm_start
    from uavlink.learn.training import make_model, training_env_config

    tc = TrainConfig(
        warm_start=WarmStartConfig(teacher="aoa"), aoa_noise_max_deg=TRAIN_AOA_NOISE_MAX_DEG
    )
    model = make_model(cfg, tc, None)
    warm_start(
        model.policy,
        [(training_env_config(cfg, tc), tc.warm_start.teacher)],
        tc.warm_start.episodes,
        tc.seed,
        log_std=tc.warm_start.log_std,
    )
    return ClonedActor(model)


def measure(episodes: int, seed: int) -> dict[str, Any]:
    def mbps(policy: Any, cfg: EnvConfig) -> float:
        return round(evaluate_policy(policy, cfg, episodes=episodes, seed=seed).mean_rate_mbps, 3)

    shadowing = {}
    for scenario in SHADOWING_SCENARIOS:
        cfg = EnvConfig(scenario=scenario)
        shadowing[scenario] = {
            "static": mbps(make_baseline("static", cfg), cfg),
            "zigzag": mbps(ZigZag(), cfg),
            "aoa": mbps(make_baseline("aoa", cfg), cfg),
        }
    clone = {}
    for scenario in CLONE_SCENARIOS:
        cfg = EnvConfig(scenario=scenario)
        clone[scenario] = {
            "clone": mbps(clone_of_the_rule(cfg), cfg),
            "aoa": mbps(make_baseline("aoa", cfg), cfg),
        }
    return {
        "episodes": episodes,
        "seed": seed,
        "shadowing_mbps": shadowing,
        "clone_before_ppo_mbps": clone,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    result = measure(args.episodes, args.seed)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"{args.episodes} episodes, seed {args.seed}, Mbps")
    print("| scenario | static | zig-zag | aoa |\n|---|---:|---:|---:|")
    for scenario, row in result["shadowing_mbps"].items():
        print(f"| {scenario} | {row['static']:.3f} | {row['zigzag']:.3f} | {row['aoa']:.3f} |")
    print("\n| scenario | clone of aoa, before PPO | aoa |\n|---|---:|---:|")
    for scenario, row in result["clone_before_ppo_mbps"].items():
        print(f"| {scenario} | {row['clone']:.3f} | {row['aoa']:.3f} |")
    return 0


if __name__ == "__main__":
    run_script(main)
