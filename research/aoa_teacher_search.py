"""Which variant of the aoa rule the warm start copies, per scenario: the choice behind the teachers
of sweeps/table1.toml's ``[scenario_train.*]`` tables.

The grid: the rule's speed span (``sinr_span_db``: full speed that many dB below the hover SINR; 10 dB
in the baseline) x its shadow gate (ours; off in the baseline), which hovers either after a frame
whose mean SINR beats the older frames' by ``shadow_gate_db`` ("jump" gates) or while the links' mean
shadowing, as estimated from the observation by ``uavlink.learn.shadow_estimation`` (fitted on
``--estimator-episodes`` simulated episodes of training seed 0), is above it ("estimate" gates).
Every variant flies the same validation
episodes (``--seed 1``; docs/results.md evaluates on seed 0) as the baseline rule, and is compared
with it episode by episode: the mean paired difference in R_fair (PPO's reward) and in throughput
(Table I's metric), each with a 95 % normal interval.

The pick: the highest R_fair among the variants whose throughput gain over the rule has its 95 %
interval above zero (none: keep the rule). A teacher must be better on the reward PPO then trains
on, and surely not worse on the metric the table reports; on ``hotspot`` the two part ways
(docs/design/learning.md), and a variant whose mean gain is positive but whose interval is wide is no pick.

As a bound on what any gate could gain, the rule gated on the links' true mean shadowing (hover
while it is above a threshold), which no GPS-free policy can read.

With ``--clone EPISODESxEPOCHS ...`` it also fits a fresh PPO actor to the pick as the sweep's warm
start does (no AoA noise, log std -3; imports torch) from that many teacher episodes and epochs, and
flies the copy deterministically on the same validation episodes: how close the copy PPO starts from is.

    python research/aoa_teacher_search.py [--scenarios ...] [--episodes 100] [--seed 1]
                                            [--clone 256x20 1024x80] [--json]
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from entry import run_script

from uavlink.config import SHADOWING_MODELS, EnvConfig
from uavlink.env.core import BatchedUavEnv, GroundTruth
from uavlink.evaluation import EvalResult, evaluate_policy
from uavlink.learn.shadow_estimation import ShadowEstimator, fit_shadow_estimator
from uavlink.learn.teachers import AoaVariant, TrueAoaTeacher
from uavlink.policies.baselines import AoaPolicy
from uavlink.rollout import chunks
from uavlink.seeding import EVAL

SCENARIOS = ("straight_90", "straight_180", "hotspot")
SPANS_DB = (2.0, 3.0, 4.0, 6.0, 8.0, 10.0)
JUMP_GATES_DB = (0.0, 1.0, 2.0, 3.0)
ESTIMATE_GATES_DB = (0.0, 1.0, 2.0, 3.0, 4.0)
ESTIMATOR_EPISODES = 512  # as sweeps/table1.toml's warm_start.shadow_estimator_episodes
TRUE_SHADOW_THRESHOLDS_DB = (0.0, 1.5, 3.0, 4.5)
BASELINE_SPAN_DB = AoaPolicy.sinr_span_db  # the `aoa` column of every table


def paired(diff: np.ndarray) -> list[float]:
    """[mean, 95 % half-width] of per-episode differences."""
    half = 1.96 * diff.std(ddof=1) / np.sqrt(len(diff)) if len(diff) > 1 else 0.0
    return [round(float(diff.mean()), 4), round(float(half), 4)]


def differences_from_rule(variant: EvalResult, rule: EvalResult) -> dict[str, Any]:
    """Mean per-episode differences with normal 95 % intervals, in R_fair and in throughput (%).
    Not ``uavlink.evaluation.compare`` (a ratio of means with a bootstrap interval): the pick needs
    an interval on the R_fair difference too."""
    return {
        "mbps": round(variant.mean_rate_mbps, 3),
        "r_fair": round(variant.mean_fair_rate, 3),
        "d_r_fair": paired(variant.episode_fair_rate - rule.episode_fair_rate),
        "d_mbps_pct": paired(100.0 * (variant.episode_rate_mbps / rule.episode_rate_mbps - 1.0)),
    }


def variant_policy(
    cfg: EnvConfig, variant: dict[str, Any], estimator: ShadowEstimator | None
) -> AoaVariant:
    return AoaVariant(
        cfg,
        sinr_span_db=variant["sinr_span_db"],
        shadow_gate_db=variant["shadow_gate_db"],
        shadow_estimator=estimator if variant["gate_on"] == "estimate" else None,
    )


def search(
    cfg: EnvConfig,
    spans_db: tuple[float, ...],
    jump_gates_db: tuple[float, ...],
    estimate_gates_db: tuple[float, ...],
    estimator_episodes: int,
    episodes: int,
    seed: int,
) -> dict[str, Any]:
    estimator = fit_shadow_estimator(cfg, estimator_episodes, seed=0)
    rule = evaluate_policy(AoaPolicy(cfg), cfg, episodes=episodes, seed=seed)
    gates = [
        ("off", None),
        *(("jump", g) for g in jump_gates_db),
        *(("estimate", g) for g in estimate_gates_db),
    ]
    variants = []
    for span in spans_db:
        for gate_on, gate in gates:
            variant = {"sinr_span_db": span, "gate_on": gate_on, "shadow_gate_db": gate}
            result = evaluate_policy(
                variant_policy(cfg, variant, estimator), cfg, episodes=episodes, seed=seed
            )
            variants.append({**variant, **differences_from_rule(result, rule)})
    gaining = [v for v in variants if v["d_mbps_pct"][0] - v["d_mbps_pct"][1] > 0.0]
    pick = max(gaining, key=lambda v: v["d_r_fair"][0]) if gaining else None
    bound = {
        f"{threshold:g}": true_shadow_gate(cfg, threshold, episodes, seed)
        for threshold in TRUE_SHADOW_THRESHOLDS_DB
    }
    return {
        "rule": {"mbps": round(rule.mean_rate_mbps, 3), "r_fair": round(rule.mean_fair_rate, 3)},
        "shadow_estimator_r2": round(estimator.r2, 4),
        "variants": variants,
        "pick": pick,
        "true_shadow_gate_mbps_r_fair": bound,
    }


class TrueShadowGate:
    """The rule, hovering while the links' true mean shadowing in ``env`` is above ``threshold_db``
    (privileged: reads the channel)."""

    name = "true-shadow-gate"
    layout = None
    needs_truth = False

    def __init__(self, rule: AoaPolicy, env: BatchedUavEnv, threshold_db: float) -> None:
        self.rule, self.env, self.threshold_db = rule, env, threshold_db

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        lucky = self.env.channel.shadow_db.mean(axis=(1, 2)) > self.threshold_db
        return np.where(lucky[:, None], 0.0, self.rule.act(obs))


def true_shadow_gate(cfg: EnvConfig, threshold_db: float, episodes: int, seed: int) -> list[float]:
    """[Mbps, R_fair] of the rule that hovers while the links' true mean shadowing is above
    ``threshold_db``, on the episodes ``evaluate_policy`` would fly (each frame of each episode weighs
    the same)."""
    rule, rates, fairs = AoaPolicy(cfg), [], []
    for chunk in chunks(cfg, EVAL, episodes, seed):
        for frame in chunk.frames(TrueShadowGate(rule, chunk.env, threshold_db)):
            rates.append(frame.result.mean_rate_mbps)
            fairs.append(frame.result.fair_rate)
    return [
        round(float(np.mean(np.concatenate(rates))), 3),
        round(float(np.mean(np.concatenate(fairs))), 3),
    ]


def clone_of(
    cfg: EnvConfig,
    pick: dict[str, Any],
    estimator_episodes: int,
    teacher_episodes: int,
    epochs: int,
    episodes: int,
    seed: int,
) -> dict[str, Any]:
    """The pick copied into a fresh PPO actor (``uavlink.learn.imitation.warm_start``), flown on the
    validation episodes: Mbps, R_fair and the cloning's final mean squared error."""
    # aoa_rule_effects is a sibling script: research/ is on the path when this one runs
    from aoa_rule_effects import ClonedActor

    from uavlink.config import TrainConfig, WarmStartConfig
    from uavlink.learn.imitation import warm_start
    from uavlink.learn.training import make_model

    model = make_model(cfg, TrainConfig(warm_start=WarmStartConfig(teacher="aoa")), None)
    estimator = (
        fit_shadow_estimator(cfg, estimator_episodes, seed=0)
        if pick["gate_on"] == "estimate"
        else None
    )
    report = warm_start(
        model.policy,
        [(cfg, TrueAoaTeacher(variant_policy(cfg, pick, estimator)))],
        teacher_episodes,
        0,
        epochs=epochs,
        log_std=-3.0,
    )
    result = evaluate_policy(ClonedActor(model), cfg, episodes=episodes, seed=seed)
    return {
        "teacher_episodes": teacher_episodes,
        "epochs": epochs,
        "mse": round(report.final_mse, 5),
        "mbps": round(result.mean_rate_mbps, 3),
        "r_fair": round(result.mean_fair_rate, 3),
    }


def clone_arg(text: str) -> tuple[int, int]:
    episodes, _, epochs = text.partition("x")
    return int(episodes), int(epochs)


def variant_name(v: dict[str, Any]) -> str:
    gate = "off" if v["gate_on"] == "off" else f"{v['shadow_gate_db']:g} dB on the {v['gate_on']}"
    return f"span {v['sinr_span_db']:g} dB, gate {gate}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--seed", type=int, default=1, help="validation episodes (docs/results.md uses 0)"
    )
    parser.add_argument("--spans-db", nargs="+", type=float, default=list(SPANS_DB))
    parser.add_argument("--jump-gates-db", nargs="*", type=float, default=list(JUMP_GATES_DB))
    parser.add_argument(
        "--estimate-gates-db", nargs="*", type=float, default=list(ESTIMATE_GATES_DB)
    )
    parser.add_argument("--estimator-episodes", type=int, default=ESTIMATOR_EPISODES)
    parser.add_argument(
        "--shadowing-model",
        choices=SHADOWING_MODELS,
        default="ar1",
        help="the channel's shadowing (radio.shadowing_model; default ar1, the paper's)",
    )
    parser.add_argument(
        "--top", type=int, default=5, help="variants listed per scenario, by R_fair"
    )
    parser.add_argument(
        "--clone",
        nargs="*",
        type=clone_arg,
        default=[],
        metavar="EPISODESxEPOCHS",
        help="also copy the pick into a PPO actor this way and fly the copy",
    )
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    configs = {
        s: EnvConfig(scenario=s)
        .replace(**{"radio.shadowing_model": args.shadowing_model})
        .validate()
        for s in args.scenarios
    }
    result = {
        "episodes": args.episodes,
        "seed": args.seed,
        "shadowing_model": args.shadowing_model,
        "scenarios": {
            s: search(
                configs[s],
                tuple(args.spans_db),
                tuple(args.jump_gates_db),
                tuple(args.estimate_gates_db),
                args.estimator_episodes,
                args.episodes,
                args.seed,
            )
            for s in args.scenarios
        },
    }
    for scenario, row in result["scenarios"].items():
        if row["pick"] is not None and args.clone:
            row["clones_of_pick"] = [
                clone_of(
                    configs[scenario],
                    row["pick"],
                    args.estimator_episodes,
                    teacher_episodes,
                    epochs,
                    args.episodes,
                    args.seed,
                )
                for teacher_episodes, epochs in args.clone
            ]
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(
        f"{args.episodes} validation episodes, seed {args.seed}; differences vs the rule "
        f"(span {BASELINE_SPAN_DB:g} dB, gate off), paired, 95 %"
    )
    for scenario, row in result["scenarios"].items():
        print(
            f"\n{scenario}: rule {row['rule']['mbps']:.3f} Mbps, R_fair {row['rule']['r_fair']:.3f}; "
            f"shadow estimator R² {row['shadow_estimator_r2']:.2f} on held-out episodes"
        )
        print("| variant | Mbps | R_fair | d R_fair | d Mbps % |\n|---|---:|---:|---:|---:|")
        best = sorted(row["variants"], key=lambda v: v["d_r_fair"][0], reverse=True)[: args.top]
        for v in best if row["pick"] in best or row["pick"] is None else [*best, row["pick"]]:
            print(
                f"| {variant_name(v)} | {v['mbps']:.3f} | {v['r_fair']:.3f} | {v['d_r_fair'][0]:+.3f} ± "
                f"{v['d_r_fair'][1]:.3f} | {v['d_mbps_pct'][0]:+.2f} ± {v['d_mbps_pct'][1]:.2f} |"
            )
        print(
            "pick: "
            + (
                "none gains throughput surely: the rule"
                if row["pick"] is None
                else variant_name(row["pick"])
            )
        )
        for c in row.get("clones_of_pick", []):
            print(
                f"copy of the pick, {c['teacher_episodes']} episodes x {c['epochs']} epochs: "
                f"{c['mbps']:.3f} Mbps, R_fair {c['r_fair']:.3f} (mse {c['mse']:.5f})"
            )
        print(
            "true-shadow gate (privileged bound), Mbps / R_fair: "
            + ", ".join(
                f"> {t} dB {m:.3f} / {f:.3f}"
                for t, (m, f) in row["true_shadow_gate_mbps_r_fair"].items()
            )
        )
    return 0


if __name__ == "__main__":
    run_script(main)
