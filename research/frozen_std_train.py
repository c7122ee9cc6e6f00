"""Train one sweep job with PPO's exploration std held where the warm start left it.

PPO updates the Gaussian policy's log std with the rest of the actor, while ``evaluate`` and
``fly`` use the mean action alone. Does PPO move the mean action further past its teacher when the
std cannot change? This runs a job of a sweep file (its env and train settings, unchanged) with
``log_std`` taken out of the optimizer after the warm start, and saves the policy as ``uavlink
train`` would (research/log/fleet.md, "Holding the exploration std": it does not).

    python research/frozen_std_train.py sweeps/fleet.toml --scenario straight_180 --seed 0 \
        --out runs/trials/s180_frozen_std_seed0.zip
    python research/fleet_bars.py --fleet DIR --scenario straight_180 --episodes 1000 --seed 7
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from entry import run_script


def frozen_std_callback() -> Any:
    """An SB3 callback that takes the policy's ``log_std`` out of the optimizer for the training:
    gradients still reach it, no step moves it (the critic warm-up may toggle its
    ``requires_grad``; the optimizer does not hold it either way). It is put back at the end, so the
    saved optimizer state loads as any other."""
    from stable_baselines3.common.callbacks import BaseCallback

    class FrozenStd(BaseCallback):
        def _on_training_start(self) -> None:
            policy = self.model.policy
            self.removed = []
            for group in policy.optimizer.param_groups:
                ids = [i for i, p in enumerate(group["params"]) if p is policy.log_std]
                self.removed.append(ids)
                group["params"] = [p for p in group["params"] if p is not policy.log_std]

        def _on_training_end(self) -> None:
            policy = self.model.policy
            for group, ids in zip(policy.optimizer.param_groups, self.removed, strict=True):
                for i in ids:
                    group["params"].insert(i, policy.log_std)

        def _on_step(self) -> bool:
            return True

    return FrozenStd()


def sweep_job(
    description: str, argv: list[str] | None, *extra: tuple[str, dict], out_unless: str = ""
) -> tuple:
    """The command line of a script that trains one job of a sweep file (``sweep --scenario X
    --seed S --out OUT.zip [--torch-threads N]``, and ``extra`` options as (flag, keywords); OUT
    not needed where the extra option ``out_unless`` names is given): its parsed arguments and
    that job, torch's threads set and OUT's folder made; a one-line refusal (exit 2) when the file
    has no such job."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("sweep", help="sweep file whose job is trained, e.g. sweeps/fleet.toml")
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", type=Path, required=not out_unless, help="policy zip to write")
    ap.add_argument("--torch-threads", type=int, default=1)
    for flag, keywords in extra:
        ap.add_argument(flag, **keywords)
    args = ap.parse_args(argv)
    if args.out is None and not getattr(args, out_unless):
        ap.error("the following arguments are required: --out")

    import torch

    from uavlink.sweep.sweep_file import load_spec

    jobs = [
        j
        for j in load_spec(args.sweep).jobs()
        if (j.scenario, j.seed) == (args.scenario, args.seed)
    ]
    if len(jobs) != 1:
        ap.exit(2, f"{args.sweep}: {len(jobs)} jobs for {args.scenario} seed {args.seed}\n")
    torch.set_num_threads(args.torch_threads)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
    return args, jobs[0]


def curve_sixths(training: dict) -> list[float]:
    """A training section's learning curve (mean UE rate of the rollouts) averaged in sixths."""
    import numpy as np

    curve = [rate for _, rate in training["learning_curve"]]
    return [round(float(part.mean()), 2) for part in np.array_split(curve, min(6, len(curve)))]


def main(argv: list[str] | None = None) -> int:
    args, job = sweep_job(__doc__.split("\n\n")[0], argv)

    from uavlink.learn.training import train

    training = train(
        job.env, job.train, args.out, progress=False, callbacks=[frozen_std_callback()]
    )
    curve = training["learning_curve"]
    print(f"{job.name} with the std frozen -> {args.out}; learning curve {curve}")
    return 0


if __name__ == "__main__":
    run_script(main)
