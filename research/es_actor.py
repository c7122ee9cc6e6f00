"""Is there a better deterministic policy next to a fleet policy? Evolution strategies on its actor.

PPO from a good copy stays level or falls (research/log/fleet.md, "Advantages against copies
flying the same episodes"): around the copy it finds no direction. PPO climbs the noisy policy's
R_fair; this asks the question of the deterministic policy and the metric the bars read. It
perturbs the actor's last ``--layers`` linear layers (1: the action head, 2 x (hidden + 1)
weights; 4: every layer) with antithetic Gaussian noise, each tensor's noise scaled by its RMS,
and scores each pair on the same seeded episodes at the sizes given, so a pair's difference holds
no episode luck (Salimans et al. 2017, "Evolution strategies as a scalable alternative to
reinforcement learning"; common random numbers). The step follows the pairs' throughput
differences (Adam; ``--objective fair``: their R_fair differences, PPO's reward, to tell the
objective from the rest of the method; ``--action-noise``: the policy scored with PPO's per-frame
action noise, the same noise for both members of a pair, to tell PPO's stochastic objective from
its estimator; ``--per-agent``: each UAV perturbed apart, as PPO's exploration moves them). Each
iteration draws fresh episodes from its own seed, so the step does not fit one set of episodes.
At the end it pairs the result with the start and with the policy's warm-start teacher on
``--check-episodes`` of ``--check-seed``, and prints them as one JSON object (each iteration's
line goes to stderr).

    python research/es_actor.py policies/fleet/straight_180.zip --iterations 40 --sigma 0.01 \\
        --out OUT.zip                                   # the action head alone
    python research/es_actor.py policies/fleet/straight_180.zip --layers 4 --iterations 40 \\
        --sigma 0.02 --out OUT.zip                      # every layer of the actor
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from entry import run_script

TRAIN_SEED_BASE = 500_000  # iteration k flies episodes of seed TRAIN_SEED_BASE + k


def head_parameters(actor: Any, layers: int) -> list[Any]:
    """The actor's last ``layers`` linear layers' weights and biases (1: the action head alone)."""
    import torch

    linears = [m for m in actor.modules() if isinstance(m, torch.nn.Linear)]
    return [p for m in linears[-layers:] for p in m.parameters()]


OBJECTIVES = {"mbps": "episode_rate_mbps", "fair": "episode_fair_rate"}  # EvalResult's arrays


class NoisyActions:
    """``policy`` with PPO's exploration: per-frame Gaussian noise of std exp(``log_std``) added to
    each action, clipped to the box as SB3 clips a sampled action. The noise's generator restarts
    from ``seed`` on each ``restart``, so both members of a pair fly the same noise."""

    def __init__(self, policy: Any, log_std: float) -> None:
        self._policy, self._std = policy, float(np.exp(log_std))
        self._rng = np.random.default_rng(0)

    def restart(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)

    def act(self, obs: np.ndarray, truth: Any = None) -> np.ndarray:
        mean = self._policy.act(obs, truth)
        return np.clip(mean + self._std * self._rng.standard_normal(mean.shape), -1.0, 1.0).astype(
            np.float32
        )

    def __getattr__(self, name: str) -> Any:  # layout, name, manifest: the policy's own
        return getattr(self._policy, name)


class PerAgentWeights:
    """``policy`` whose UAV d flies weights of its own, ``values[d]`` (the env's agent row i is UAV
    i % D), as PPO's exploration moves each UAV apart from the others; ``values`` None: the
    policy's own weights for all."""

    def __init__(self, policy: Any, set_params: Any) -> None:
        self._policy, self._set = policy, set_params
        self.values: list[list[Any]] | None = None
        self.n_uavs = 1

    def act(self, obs: np.ndarray, truth: Any = None) -> np.ndarray:
        if self.values is None:
            return self._policy.act(obs, truth)
        d, out = self.n_uavs, np.empty((obs.shape[0], 2), np.float32)
        for uav in range(d):
            self._set(self.values[uav])
            out[uav::d] = self._policy.act(obs[uav::d])
        return out

    def __getattr__(self, name: str) -> Any:  # layout, name, manifest: the policy's own
        return getattr(self._policy, name)


def fitness(
    policy: Any, envs: list[Any], episodes: int, seed: int, objective: str = "mbps"
) -> np.ndarray:
    """Per fleet size, each of ``episodes`` seeded episodes' mean UE rate (Mbps; ``objective``
    "fair": its R_fair, what PPO's reward normalises), stacked."""
    from uavlink.evaluation import evaluate_policy

    field = OBJECTIVES[objective]
    if isinstance(policy, NoisyActions):
        policy.restart(seed)
    scores = []
    for cfg in envs:
        if isinstance(policy, PerAgentWeights):
            policy.n_uavs = cfg.n_uavs
        scores.append(getattr(evaluate_policy(policy, cfg, episodes, seed), field))
    return np.concatenate(scores)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy", type=Path, help="an any-size fleet policy zip")
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--layers", type=int, default=1, help="last linear layers perturbed")
    parser.add_argument("--iterations", type=int, default=40)
    parser.add_argument("--pairs", type=int, default=16)
    parser.add_argument(
        "--episodes", type=int, default=64, help="per size and pair, each iteration"
    )
    parser.add_argument("--sigma", type=float, default=0.02, help="noise std, x each tensor's RMS")
    parser.add_argument(
        "--learning-rate", type=float, default=0.01, help="Adam, x each tensor's RMS"
    )
    parser.add_argument(
        "--objective",
        choices=tuple(OBJECTIVES),
        default="mbps",
        help="what a pair is scored on: throughput (the bars') or R_fair (PPO's reward)",
    )
    parser.add_argument(
        "--action-noise",
        type=float,
        metavar="LOG_STD",
        help="score the policy with PPO's per-frame action noise of this log std (paired within a "
        "pair), not the deterministic policy; the check still flies it deterministically",
    )
    parser.add_argument(
        "--per-agent",
        action="store_true",
        help="each UAV of a pair's member flies noise of its own (as PPO's exploration), not the "
        "same perturbed weights for the whole fleet; the step sums the UAVs' noise",
    )
    parser.add_argument("--check-episodes", type=int, default=300)
    parser.add_argument("--check-seed", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0, help="the noise's generator")
    parser.add_argument("--out", type=Path, required=True, help="the policy zip written")
    args = parser.parse_args(argv)
    if not args.policy.is_file():
        parser.error(f"no such file: {args.policy}")
    if args.per_agent and args.action_noise is not None:
        parser.error("--per-agent and --action-noise are separate questions: give one")

    import torch

    from uavlink.evaluation import evaluate_policy, paired_ratio_ci
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.sb3_policy import SB3Policy

    torch.set_num_threads(1)
    [(_, built)] = load_with_env([args.policy], EnvOverrides())
    envs = [built.replace(n_uavs=d).validate() for d in args.sizes]
    policy = SB3Policy(args.policy)
    params = head_parameters(policy.actor, args.layers)
    theta = [p.detach().clone() for p in params]  # the start, then each step's weights
    scale = [float(x.pow(2).mean().sqrt()) for x in theta]
    m = [torch.zeros_like(p) for p in theta]
    v = [torch.zeros_like(p) for p in theta]
    rng = torch.Generator().manual_seed(args.seed)

    def set_params(values: list[Any]) -> None:
        with torch.no_grad():
            for p, x in zip(params, values, strict=True):
                p.copy_(x)

    scored: Any = policy
    if args.action_noise is not None:
        scored = NoisyActions(policy, args.action_noise)
    elif args.per_agent:
        scored = PerAgentWeights(policy, set_params)
    uavs = max(args.sizes) if args.per_agent else 1  # noise draws a member's fleet flies
    for k in range(args.iterations):
        t0, seed = time.perf_counter(), TRAIN_SEED_BASE + k
        noise, diffs = [], []
        for _ in range(args.pairs):
            eps = [
                [torch.randn(p.shape, generator=rng, dtype=p.dtype) for p in theta]
                for _ in range(uavs)
            ]
            scores = []
            for sign in (1.0, -1.0):
                values = [
                    [
                        x + sign * args.sigma * s * e
                        for x, s, e in zip(theta, scale, one, strict=True)
                    ]
                    for one in eps
                ]
                if isinstance(scored, PerAgentWeights):
                    scored.values = values
                else:
                    set_params(values[0])
                scores.append(fitness(scored, envs, args.episodes, seed, args.objective).mean())
            noise.append([sum(tensors) for tensors in zip(*eps, strict=True)])  # the UAVs' sum
            diffs.append(scores[0] - scores[1])
        if isinstance(scored, PerAgentWeights):
            scored.values = None
        set_params(theta)
        centre = fitness(scored, envs, args.episodes, seed, args.objective).mean()
        d = np.asarray(diffs)
        weights = d / (
            d.std() + 1e-12
        )  # the step's length does not depend on the differences' scale
        for i, (x, s) in enumerate(zip(theta, scale, strict=True)):
            grad = sum(float(w) * eps[i] for w, eps in zip(weights, noise, strict=True)) / (
                2 * args.pairs
            )
            m[i] = 0.9 * m[i] + 0.1 * grad
            v[i] = 0.999 * v[i] + 0.001 * grad**2
            mh, vh = m[i] / (1 - 0.9 ** (k + 1)), v[i] / (1 - 0.999 ** (k + 1))
            theta[i] = x + args.learning_rate * s * mh / (vh.sqrt() + 1e-8)
        print(
            f"iteration {k + 1}/{args.iterations}: centre {centre:.4f} ({args.objective}), pair differences "
            f"mean {d.mean():+.4f} std {d.std():.4f}, {time.perf_counter() - t0:.0f} s",
            file=sys.stderr,
            flush=True,
        )
    set_params(theta)

    # Write the result as a policy zip: the start's zip with the head's new weights.
    from stable_baselines3.common.save_util import load_from_zip_file, save_to_zip_file

    data, state, _ = load_from_zip_file(args.policy, device="cpu")
    linears = _actor_linears(state)[-args.layers :]
    names = [f"{n}.{w}" for n in linears for w in ("weight", "bias")]
    for name, x in zip(names, theta, strict=True):
        state["policy"][name] = x.to(state["policy"][name].dtype)
    tmp = args.out.with_suffix(".partial.zip")
    save_to_zip_file(tmp, data=data, params=state)
    _copy_manifest(args.policy, tmp)
    shutil.move(tmp, args.out)

    result, initial = SB3Policy(args.out), SB3Policy(args.policy)  # the written file, the start
    rows: dict[str, Any] = {}
    for cfg in [built.replace(n_uavs=d).validate() for d in (2, 3, 4)]:
        new = evaluate_policy(result, cfg, args.check_episodes, args.check_seed)
        old = evaluate_policy(initial, cfg, args.check_episodes, args.check_seed)
        row = {
            "mbps": round(new.mean_rate_mbps, 4),
            "vs_start": [
                round(x, 4) for x in paired_ratio_ci(new.episode_rate_mbps, old.episode_rate_mbps)
            ],
            "fair_vs_start": round(new.mean_fair_rate - old.mean_fair_rate, 4),
        }
        if cfg.n_uavs == 2:
            teacher, name = policy_teacher(result, cfg)
            t = evaluate_policy(teacher, cfg, args.check_episodes, args.check_seed)
            row["teacher"] = name
            row["vs_teacher"] = [
                round(x, 4) for x in paired_ratio_ci(new.episode_rate_mbps, t.episode_rate_mbps)
            ]
            row["start_vs_teacher"] = [
                round(x, 4) for x in paired_ratio_ci(old.episode_rate_mbps, t.episode_rate_mbps)
            ]
        rows[f"D{cfg.n_uavs}"] = row
    print(json.dumps(rows))
    return 0


def _actor_linears(state: dict[str, Any]) -> list[str]:
    """The actor's linear layers by their state-dict names, in order (policy_net's, action_net)."""
    names = [k[: -len(".weight")] for k in state["policy"] if k.endswith(".weight")]
    return [n for n in names if n.startswith("mlp_extractor.policy_net") or n == "action_net"]


def _copy_manifest(src: Path, dst: Path) -> None:
    """Copy the uavlink manifest entry of ``src`` into the zip ``dst``."""
    import zipfile

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "a") as zout:
        zout.writestr("uavlink_manifest.json", zin.read("uavlink_manifest.json"))


if __name__ == "__main__":
    run_script(main)
