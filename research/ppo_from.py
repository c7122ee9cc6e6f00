"""PPO from a given policy: where does its climb from a fleet copy stop, and what moves it?

Evolution strategies climb from hotspot's kmeans copy about 3 % at D = 2 and 3, scored on the
deterministic policy or on PPO's noisy one alike; PPO from such a copy climbs about 1 % and stays
(research/log/fleet.md, "What ES has that PPO lacks"). This trains one job of a sweep file with its
settings unchanged but the warm start, replaced by ``--start-from FILE`` (the actor's weights as
they are, the exploration std reset to the warm start's), and one knob at a time:

- ``--anneal``: the learning rate falling linearly to zero over the run (SB3's ``lr_schedule``).
  With a constant rate, noisy steps hold the weights in a cloud where the drift and the noise
  balance, below the top of a narrow ridge; a falling rate shrinks the cloud.
- ``--gsde FRAMES``: gSDE exploration (``uavlink/learn/held_exploration.py``'s callback; -1: W
  drawn once a rollout), noise held for many frames as ES holds its perturbation for a whole
  episode.

It then pairs the policy with the start and with kmeans on ``--check-episodes`` of
``--check-seed`` and prints one JSON object.

    python research/ppo_from.py research/sweeps/fleet_kmeans_paired.toml --scenario hotspot \
        --seed 0 --start-from COPY.zip --episodes 24000 --anneal --out OUT.zip
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

from entry import run_script
from frozen_std_train import curve_sixths, sweep_job


def annealed_lr_callback() -> Any:
    """An SB3 callback that makes the learning rate fall linearly from the one set to zero over
    the run (``progress_remaining`` 1 -> 0): SB3 reads ``lr_schedule`` at every update."""
    from stable_baselines3.common.callbacks import BaseCallback

    class AnnealedLr(BaseCallback):
        def _on_training_start(self) -> None:
            start = float(self.model.learning_rate)
            self.model.lr_schedule = lambda progress_remaining: start * progress_remaining

        def _on_step(self) -> bool:
            return True

    return AnnealedLr()


def main(argv: list[str] | None = None) -> int:
    args, job = sweep_job(
        __doc__.split("\n\n")[0],
        argv,
        ("--start-from", {"type": Path, "required": True, "help": "the policy PPO starts from"}),
        ("--episodes", {"type": int, "help": "the training budget (default: the job's)"}),
        ("--anneal", {"action": "store_true", "help": "learning rate falling linearly to 0"}),
        (
            "--gsde",
            {
                "type": int,
                "metavar": "FRAMES",
                "help": "gSDE, W drawn every FRAMES (-1: a rollout)",
            },
        ),
        ("--log-std", {"type": float, "default": -2.0, "help": "gSDE's per-frame log std"}),
        ("--check-episodes", {"type": int, "default": 300}),
        ("--check-seed", {"type": int, "default": 1}),
    )
    from uavlink.errors import UserError
    from uavlink.evaluation import evaluate_policy, paired_ratio_ci
    from uavlink.learn.training import train
    from uavlink.policies.registry import baseline_env, make_baseline
    from uavlink.policies.sb3_policy import SB3Policy

    if not args.start_from.is_file():
        raise UserError(f"--start-from {args.start_from}: no such file")
    warm = dataclasses.replace(
        job.train.warm_start, teacher="", dagger_rounds=0, policy=str(args.start_from)
    )
    tc = dataclasses.replace(
        job.train, warm_start=warm, episodes=args.episodes or job.train.episodes
    )
    callbacks = [annealed_lr_callback()] if args.anneal else []
    if args.gsde is not None:
        from uavlink.learn.held_exploration import held_exploration_callback

        callbacks.append(held_exploration_callback(args.log_std, args.gsde))
    training = train(job.env, tc.validate(job.env), args.out, progress=False, callbacks=callbacks)

    result, start = SB3Policy(args.out), SB3Policy(args.start_from)
    rows: dict[str, Any] = {"curve_sixths_mbps": curve_sixths(training)}
    for d in (2, 3, 4):
        cfg = job.env.replace(n_uavs=d).validate()
        new = evaluate_policy(result, cfg, args.check_episodes, args.check_seed)
        old = evaluate_policy(start, cfg, args.check_episodes, args.check_seed)
        kmeans = evaluate_policy(
            make_baseline("kmeans", cfg), baseline_env("kmeans", cfg), args.check_episodes,
            args.check_seed,
        )  # fmt: skip
        pair = {
            "vs_start": paired_ratio_ci(new.episode_rate_mbps, old.episode_rate_mbps),
            "vs_kmeans": paired_ratio_ci(new.episode_rate_mbps, kmeans.episode_rate_mbps),
        }
        rows[f"D{d}"] = {k: [round(x, 4) for x in v] for k, v in pair.items()}
        rows[f"D{d}"]["mbps"] = round(new.mean_rate_mbps, 4)
    print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    run_script(main)
