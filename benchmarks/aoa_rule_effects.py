"""The figures behind docs/design.md's notes on shadowing and the warm start, one run.

1. What the SPEC's memoryless shadowing rewards: over the same seeded episodes, hovering
   (``static``), a 12 m east-west zig-zag (moving all the time) and the ``aoa`` rule (moving only
   while the SINRs sit below the hover level), on ``no_move`` and ``straight_180``.
2. How good the warm start's copy of the rule is before PPO: the actor of a fresh PPO model cloned
   as ``uavlink train --warm-start aoa`` does (``TrainConfig``'s defaults, the shipped sweep's
   training AoA noise), flown deterministically, against the rule itself.
3. Variants of the rule on ``straight_180`` and ``hotspot``, on validation episodes (``--validation-seed``,
   not the evaluation seed of docs/results.md): its speed span (``sinr_span_db``, 10 dB in the
   baseline) and the shadow gate (ours, ``shadow_gate_db``; off in the baseline), in Mbps / R_fair;
   and, as a bound on what any gate could gain, the rule gated on the true mean shadowing of the
   links (hover while it is above a threshold), which no GPS-free policy can read.

    python benchmarks/aoa_rule_effects.py [--episodes 100] [--seed 0] [--validation-seed 1] [--json]
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv, GroundTruth
from uavlink.evaluation import CHUNK, episode_seed, evaluate_policy
from uavlink.policies.baselines import AoaPolicy, make_baseline

SHADOWING_SCENARIOS = ("no_move", "straight_180")
CLONE_SCENARIOS = ("no_move", "straight_180", "hotspot")
VARIANT_SCENARIOS = ("straight_180", "hotspot")
SPANS_DB = (6.0, 8.0, 10.0, 12.0)
GATES_DB = (None, 0.0, 1.0, 2.0, 3.0)
TRUE_SHADOW_THRESHOLDS_DB = (0.0, 1.5, 3.0, 4.5)
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
    from uavlink.imitation import warm_start
    from uavlink.training import TrainConfig, make_model, training_env_config

    tc = TrainConfig(warm_start_teacher="aoa", aoa_noise_max_deg=TRAIN_AOA_NOISE_MAX_DEG)
    model = make_model(cfg, tc, None)
    warm_start(model.policy, training_env_config(cfg, tc), tc.warm_start_teacher, tc.warm_start_episodes,
               tc.seed, log_std=tc.warm_start_log_std)
    return ClonedActor(model)


def rule_variants(episodes: int, seed: int) -> dict[str, dict[str, list[float]]]:
    """{scenario: {"span=S gate=G": [Mbps, R_fair]}} over the same seeded episodes."""
    table: dict[str, dict[str, list[float]]] = {}
    for scenario in VARIANT_SCENARIOS:
        cfg = EnvConfig(scenario=scenario)
        table[scenario] = {}
        for span in SPANS_DB:
            for gate in GATES_DB:
                result = evaluate_policy(AoaPolicy(cfg, sinr_span_db=span, shadow_gate_db=gate), cfg,
                                         episodes=episodes, seed=seed)
                table[scenario][f"span={span:g} gate={'off' if gate is None else f'{gate:g}'}"] = [
                    round(result.mean_rate_mbps, 3), round(result.mean_fair_rate, 3)]
        for threshold in TRUE_SHADOW_THRESHOLDS_DB:
            table[scenario][f"true shadow > {threshold:g} dB"] = true_shadow_gate(cfg, threshold, episodes, seed)
    return table


def true_shadow_gate(cfg: EnvConfig, threshold_db: float, episodes: int, seed: int) -> list[float]:
    """[Mbps, R_fair] of the rule that hovers while the links' true mean shadowing is above
    ``threshold_db``, on the episodes ``evaluate_policy`` would fly (privileged: reads the channel)."""
    rule, rates, fairs = AoaPolicy(cfg), [], []
    for chunk, start in enumerate(range(0, episodes, CHUNK)):
        env = BatchedUavEnv(cfg, n_envs=min(CHUNK, episodes - start), seed=episode_seed(seed, chunk))
        obs = env.reset()
        for _ in range(cfg.episode_frames):
            lucky = env.channel.shadow_db.mean(axis=(1, 2)) > threshold_db
            step = env.step(np.where(lucky[:, None], 0.0, rule.act(obs)))
            obs = step.observation
            rates.append(step.mean_rate_mbps)
            fairs.append(step.fair_rate)
    return [round(float(np.mean(rates)), 3), round(float(np.mean(fairs)), 3)]


def measure(episodes: int, seed: int, validation_seed: int) -> dict[str, Any]:
    def mbps(policy: Any, cfg: EnvConfig) -> float:
        return round(evaluate_policy(policy, cfg, episodes=episodes, seed=seed).mean_rate_mbps, 3)

    shadowing = {}
    for scenario in SHADOWING_SCENARIOS:
        cfg = EnvConfig(scenario=scenario)
        shadowing[scenario] = {"static": mbps(make_baseline("static", cfg), cfg),
                               "zigzag": mbps(ZigZag(), cfg), "aoa": mbps(make_baseline("aoa", cfg), cfg)}
    clone = {}
    for scenario in CLONE_SCENARIOS:
        cfg = EnvConfig(scenario=scenario)
        clone[scenario] = {"clone": mbps(clone_of_the_rule(cfg), cfg), "aoa": mbps(make_baseline("aoa", cfg), cfg)}
    return {"episodes": episodes, "seed": seed, "shadowing_mbps": shadowing, "clone_before_ppo_mbps": clone,
            "validation_seed": validation_seed,
            "rule_variants_mbps_r_fair": rule_variants(episodes, validation_seed)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--validation-seed", type=int, default=1, help="episodes of the rule variants")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    result = measure(args.episodes, args.seed, args.validation_seed)
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
    variants = result["rule_variants_mbps_r_fair"]
    print(f"\nrule variants, validation seed {args.validation_seed}, Mbps / R_fair (baseline: span=10 gate=off)")
    print("| variant | " + " | ".join(variants) + " |\n|---|" + "---:|" * len(variants))
    for name in next(iter(variants.values())):
        print(f"| {name} | " + " | ".join(f"{v[name][0]:.3f} / {v[name][1]:.3f}" for v in variants.values()) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
