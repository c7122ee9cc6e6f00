"""Can PPO improve on the ``aoa`` rule when it starts as the rule? Residual PPO, one run.

The actor's output is added to the rule's action (residual reinforcement learning: Johannink et
al. 2019, Silver et al. 2018), so before any update the deterministic policy is the rule itself
(SB3 initialises the action head near zero) and PPO only has to find a correction. Trained with
``TrainConfig``'s defaults except where flagged (bigger rollouts and a small exploration std keep
the updates from drifting off the rule; both were the best of the variants tried), on the
scenarios where the shipped policies stay below the rule. Prints throughput (Mbps) and R_fair,
the reward PPO maximises, over the same seeded evaluation episodes for the rule, the residual
policy before training and after it.

    python research/residual_ppo.py [--scenarios straight_90 straight_180 hotspot]
        [--train-episodes 4000] [--n-envs 256] [--batch-size 4096] [--log-std -3]
        [--learning-rate 3e-4] [--gamma 0.99] [--gae-lambda 0.95] [--episodes 100] [--seed 0] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np
from entry import run_script
from stable_baselines3.common.vec_env import VecEnvWrapper, VecNormalize

from uavlink.config import EnvConfig, TrainConfig
from uavlink.env.core import GroundTruth
from uavlink.env.vec_env import UavVecEnv
from uavlink.evaluation import evaluate_policy
from uavlink.policies.baselines import AoaPolicy


def compose(rule_action: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """The rule's cartesian action plus the residual, cut back to the unit disc (a full move)."""
    action = rule_action + np.clip(residual, -1.0, 1.0)
    return (action / np.maximum(1.0, np.hypot(action[:, 0], action[:, 1]))[:, None]).astype(
        np.float32
    )


class RuleResidualVecEnv(VecEnvWrapper):
    """Steps the wrapped env with rule(last observation) + the agent's action."""

    def __init__(self, venv: Any, rule: AoaPolicy) -> None:
        super().__init__(venv)
        self.rule = rule
        self._obs: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        self._obs = self.venv.reset()
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(compose(self.rule.act(self._obs), actions))

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        self._obs = obs  # after an episode's end, the next one's first observation (SB3 auto-reset)
        return obs, rewards, dones, infos


class ResidualPolicy:
    """The trained residual on top of the rule, deterministic, behind the Policy interface."""

    name = "residual"
    layout = None
    needs_truth = False

    def __init__(self, model: Any, rule: AoaPolicy) -> None:
        self.model, self.rule = model, rule

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        return compose(self.rule.act(obs), self.model.predict(obs, deterministic=True)[0])


def measure(
    scenarios: list[str],
    train_episodes: int,
    episodes: int,
    seed: int,
    n_envs: int,
    batch_size: int,
    log_std: float,
    **train_overrides: float,
) -> dict[str, Any]:
    import torch
    from stable_baselines3.common.logger import Logger

    from uavlink.learn.training import make_model

    def score(policy: Any, cfg: EnvConfig) -> dict[str, float]:
        result = evaluate_policy(policy, cfg, episodes=episodes, seed=seed)
        return {"mbps": round(result.mean_rate_mbps, 3), "r_fair": round(result.mean_fair_rate, 3)}

    rows = {}
    for scenario in scenarios:
        cfg = EnvConfig(scenario=scenario)
        # 128 steps x 10 epochs: the PPO loop of the figures in docs/ (TrainConfig's defaults then)
        tc = TrainConfig(
            episodes=train_episodes,
            seed=seed,
            n_envs=n_envs,
            batch_size=batch_size,
            **{"n_steps": 128, "n_epochs": 10, **train_overrides},
        )
        rule = AoaPolicy(cfg)
        model = make_model(cfg, tc, None)
        model.set_env(
            VecNormalize(
                RuleResidualVecEnv(UavVecEnv(cfg, n_envs=tc.n_envs, seed=tc.seed), rule),
                norm_obs=False,
                norm_reward=tc.normalize_reward,
                gamma=tc.gamma,
            )
        )
        model.set_logger(Logger(folder=None, output_formats=[]))
        with torch.no_grad():
            model.policy.log_std.fill_(log_std)
        row = {"aoa": score(rule, cfg), "residual_before": score(ResidualPolicy(model, rule), cfg)}
        start = time.perf_counter()
        model.learn(total_timesteps=tc.total_timesteps(cfg))
        row["train_wall_s"] = round(time.perf_counter() - start, 1)
        row["residual_after"] = score(ResidualPolicy(model, rule), cfg)
        rows[scenario] = row
    return {
        "train_episodes": train_episodes,
        "n_envs": n_envs,
        "batch_size": batch_size,
        "log_std_init": log_std,
        **train_overrides,
        "episodes": episodes,
        "seed": seed,
        "scenarios": rows,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenarios", nargs="+", default=["straight_90", "straight_180", "hotspot"]
    )
    parser.add_argument("--train-episodes", type=int, default=4000, help="PPO budget per scenario")
    parser.add_argument("--n-envs", type=int, default=256, help="envs per rollout (default 256)")
    parser.add_argument("--batch-size", type=int, default=4096, help="minibatch (default 4096)")
    parser.add_argument("--log-std", type=float, default=-3.0, help="initial exploration log std")
    defaults = TrainConfig()
    parser.add_argument("--learning-rate", type=float, default=defaults.learning_rate)
    parser.add_argument("--gamma", type=float, default=defaults.gamma)
    parser.add_argument("--gae-lambda", type=float, default=defaults.gae_lambda)
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args(argv)
    result = measure(
        args.scenarios,
        args.train_episodes,
        args.episodes,
        args.seed,
        args.n_envs,
        args.batch_size,
        args.log_std,
        learning_rate=args.learning_rate,
        gamma=args.gamma,
        gae_lambda=args.gae_lambda,
    )
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(
        f"residual PPO on the aoa rule: {args.train_episodes} training episodes, evaluation "
        f"{args.episodes} episodes seed {args.seed}; Mbps / R_fair"
    )
    print(
        "| scenario | aoa | residual, before PPO | residual, after PPO | training |\n|---|---:|---:|---:|---:|"
    )
    for scenario, row in result["scenarios"].items():
        cells = [
            f"{row[k]['mbps']:.3f} / {row[k]['r_fair']:.3f}"
            for k in ("aoa", "residual_before", "residual_after")
        ]
        print(f"| {scenario} | {' | '.join(cells)} | {row['train_wall_s']:.0f} s |")
    return 0


if __name__ == "__main__":
    run_script(main)
