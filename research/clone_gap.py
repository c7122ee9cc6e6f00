"""Where a copy loses against its teacher: a sweep job's behaviour clone alone, after each DAgger
round, and (optionally) trained policies, each against the teacher on the same fresh episodes.

A DAgger round (Ross et al. 2011, "A reduction of imitation learning ... to no-regret online
learning"): the copy flies, the teacher labels the frames it meets, and the copy is fitted again on
everything gathered so far; a copy fitted on the teacher's own flying errs most where the teacher
never goes, and its small errors take it there.

The job (a scenario and training seed of a sweep file) gives the env, the teacher and the cloning
recipe, as ``uavlink sweep`` would train it; the copy is SB3's deterministic action, as a policy file
flies. research/log/map-policies.md, "DAgger on hotspot", runs:

    python research/clone_gap.py --sweep sweeps/map.toml --scenario hotspot --rounds 2 --epochs 40 \\
        --policy policies/map/hotspot.zip --episodes 500 --eval-seed 7 [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from entry import run_script


def run(
    sweep: Path,
    scenario: str,
    seed: int,
    rounds: int,
    epochs: int | None,
    clone_episodes: int | None,
    episodes: int,
    eval_seed: int,
    policy_paths: list[Path],
) -> dict[str, Any]:
    import numpy as np
    import torch

    from uavlink.env.observation import ObservationLayout
    from uavlink.errors import UserError
    from uavlink.evaluation import evaluate_policy, paired_ratio_ci
    from uavlink.learn.imitation import clone_actor, student_dataset, teacher_dataset
    from uavlink.learn.teachers import warm_start_teacher
    from uavlink.learn.training import make_model, training_env_config
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.sb3_policy import deterministic_actor
    from uavlink.sweep.sweep_file import load_spec

    jobs = [j for j in load_spec(sweep).jobs() if j.scenario == scenario and j.seed == seed]
    if not jobs:
        raise UserError(f"{sweep} has no job of scenario {scenario!r} and seed {seed}")
    cfg, tc = jobs[0].env, jobs[0].train
    ws = tc.warm_start
    if not ws.teacher:
        raise UserError(f"{sweep}'s {scenario} job copies no teacher")
    epochs = epochs or ws.epochs or 20
    clone_episodes = clone_episodes or ws.episodes

    class Copy:
        """The clone as a policy file flies it: SB3's deterministic action."""

        needs_truth, name = False, "copy"

        def __init__(self) -> None:
            self.net, self.layout = (
                deterministic_actor(model.policy),
                ObservationLayout.for_config(cfg),
            )

        def act(self, obs, truth=None):
            with torch.no_grad():
                return self.net(torch.as_tensor(np.asarray(obs, dtype=np.float32))).numpy()

    torch.set_num_threads(tc.torch_threads)
    start = time.perf_counter()
    model, train_cfg = make_model(cfg, tc, None), training_env_config(cfg, tc)
    teacher, _ = warm_start_teacher(train_cfg, tc)
    reference = evaluate_policy(teacher, cfg, episodes, eval_seed)

    def row(stage: str, flier: Any, **extra: Any) -> dict[str, Any]:
        result = evaluate_policy(flier, cfg, episodes, eval_seed)
        ratio, lo, hi = paired_ratio_ci(result.episode_rate_mbps, reference.episode_rate_mbps)
        return {
            "stage": stage,
            **extra,
            "mbps": round(result.mean_rate_mbps, 4),
            "vs_teacher": round(ratio - 1, 4),
            "ci95": [round(lo - 1, 4), round(hi - 1, 4)],
            "elapsed_s": round(time.perf_counter() - start, 1),
        }

    obs, actions = teacher_dataset(train_cfg, teacher, clone_episodes, tc.seed)
    rows = []
    for round_index in range(rounds + 1):
        if round_index:
            more_obs, more_actions = student_dataset(
                model.policy, train_cfg, teacher, clone_episodes, tc.seed, round_index - 1
            )
            obs, actions = np.concatenate([obs, more_obs]), np.concatenate([actions, more_actions])
        mse = clone_actor(
            model.policy, obs, actions, epochs=epochs, log_std=ws.log_std, seed=tc.seed
        )
        stage = "clone" if round_index == 0 else f"dagger {round_index}"
        rows.append(row(stage, Copy(), samples=len(obs), mse=round(mse, 6)))
    for path in policy_paths:
        [(policy, policy_cfg)] = load_with_env([path], EnvOverrides())
        if policy_cfg.to_dict() != cfg.to_dict():
            raise UserError(f"{path} flies another env than {sweep}'s {scenario} job")
        rows.append(row(f"policy {path}", policy))
    return {
        "benchmark": "clone_gap",
        "sweep": str(sweep),
        "scenario": scenario,
        "seed": seed,
        "epochs": epochs,
        "clone_episodes": clone_episodes,
        "episodes": episodes,
        "eval_seed": eval_seed,
        "teacher_mbps": round(reference.mean_rate_mbps, 4),
        "rows": rows,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sweep", type=Path, required=True, help="the sweep file whose job to copy"
    )
    parser.add_argument("--scenario", required=True)
    parser.add_argument("--seed", type=int, default=0, help="the job's training seed")
    parser.add_argument("--rounds", type=int, default=2, help="DAgger rounds after the first fit")
    parser.add_argument(
        "--epochs", type=int, default=None, help="passes per fit (default: the job's)"
    )
    parser.add_argument(
        "--clone-episodes",
        type=int,
        default=None,
        help="episodes of flying per fit's new data (default: the job's warm_start.episodes)",
    )
    parser.add_argument(
        "--policy",
        type=Path,
        action="append",
        default=[],
        help="also a trained policy of that job's env (repeatable)",
    )
    parser.add_argument("--episodes", type=int, default=500, help="evaluation episodes")
    parser.add_argument("--eval-seed", type=int, default=7)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    args = parser.parse_args(argv)
    if args.episodes < 2 or args.rounds < 0:
        parser.error("--episodes must be >= 2 (a paired interval) and --rounds >= 0")
    from uavlink.errors import UserError

    try:
        report = run(
            args.sweep,
            args.scenario,
            args.seed,
            args.rounds,
            args.epochs,
            args.clone_episodes,
            args.episodes,
            args.eval_seed,
            args.policy,
        )
    except UserError as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(
        f"{args.scenario}, job seed {args.seed}: teacher {report['teacher_mbps']:.4f} Mbps on {args.episodes} "
        f"episodes (seed {args.eval_seed})\n"
    )
    print("| stage | samples | clone MSE | Mbps | vs teacher |\n|---|---:|---:|---:|---|")
    for r in report["rows"]:
        lo, hi = r["ci95"]
        print(
            f"| {r['stage']} | {r.get('samples', '')} | {r.get('mse', '')} | {r['mbps']:.4f} | "
            f"{100 * r['vs_teacher']:+.2f} % [{100 * lo:+.2f}, {100 * hi:+.2f}] |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
