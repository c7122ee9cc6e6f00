"""Train one sweep job with exploration that holds for a whole episode (gSDE) after the warm start.

PPO explores with Gaussian noise drawn afresh every frame. The action is a move of at most r_max
a frame, and the policy steers back to where it wants to be, so white noise jitters a UAV about its
placement and averages out: it never tries a different placement for long enough to be scored on
it, while what separates the teachers' rules is the placement as a whole (research/log/fleet.md,
"Advantages against copies flying the same episodes"). Generalised state-dependent exploration
(gSDE; Raffin, Kober and Stulp, CoRL 2021; SB3's ``use_sde``) draws the noise as a function of the
actor's last hidden layer, eps(s) = phi(s) . W, with W drawn once per rollout (``--sample-freq -1``:
each agent row's W holds for its whole 128-frame episode), so each UAV explores a consistent
change of its placement rule. The action's per-frame law is still Gaussian, so PPO's ratio stands.

After the job's warm start, the callback swaps the policy's diagonal Gaussian for SB3's
``StateDependentNoiseDistribution`` (full std, one log std per hidden unit and action) and scales
its log std so that the per-frame std on the first observations equals ``--log-std``; the actor's
mean network, which ``evaluate`` and ``fly`` use, is the copy's, unchanged. At the end of training
it puts a diagonal Gaussian back (its log std the per-frame one gSDE had on the first
observations), so the saved policy is one the product loads: its mean network is all that
``evaluate``, ``export`` and ``fly`` read.

    python research/sde_ppo.py sweeps/fleet.toml --scenario circular --seed 0 --log-std -1.5 \
        --out runs/trials/circular_sde_seed0.zip
    python research/fleet_bars.py --fleet DIR --scenario circular --episodes 300 --seed 1
"""

from __future__ import annotations

import math
import sys
from typing import Any

from entry import run_script


def gsde_callback(log_std: float, sample_freq: int) -> Any:
    """An SB3 callback that turns the model's exploration into gSDE at the start of training (it must
    come before the critic warm-up's callback, which freezes the log std it finds)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.distributions import (
        DiagGaussianDistribution,
        StateDependentNoiseDistribution,
    )

    def new_optimizer(model: Any) -> None:
        policy = model.policy
        policy.optimizer = policy.optimizer_class(
            policy.parameters(), lr=model.lr_schedule(1.0), **policy.optimizer_kwargs
        )

    class Gsde(BaseCallback):
        def _on_training_start(self) -> None:
            model, policy = self.model, self.model.policy
            with torch.no_grad():
                obs = torch.as_tensor(model._last_obs, dtype=torch.float32)
                features = policy.extract_features(obs)
                pi_features = features[0] if isinstance(features, tuple) else features
                latent_pi = policy.mlp_extractor.forward_actor(pi_features)
                mean_square = float((latent_pi**2).sum(dim=1).mean())
            # per-frame variance = sum_j phi_j^2 sigma^2 with every sigma alike: sigma from the target
            sigma_log = log_std - 0.5 * math.log(mean_square)
            action_dim = policy.action_net.out_features
            dist_kwargs = {"full_std": True, "squash_output": False, "use_expln": False}
            policy.action_dist = StateDependentNoiseDistribution(
                action_dim, learn_features=False, **dist_kwargs
            )
            policy.log_std = torch.nn.Parameter(
                torch.full((latent_pi.shape[1], action_dim), sigma_log)
            )
            policy.use_sde, policy.dist_kwargs, policy.log_std_init = True, dist_kwargs, sigma_log
            new_optimizer(model)
            model.use_sde, model.sde_sample_freq = True, sample_freq
            self.mean_square = mean_square
            print(
                f"gSDE: sum phi^2 = {mean_square:.2f} on the first observations, log std per unit "
                f"{sigma_log:.3f} (per-frame log std {log_std}), noise drawn every "
                f"{'rollout' if sample_freq <= 0 else f'{sample_freq} frames'}",
                file=sys.stderr,
                flush=True,
            )

        def _on_training_end(self) -> None:
            model, policy = self.model, self.model.policy
            # about the per-frame variance on the first observations, per action (phi^2 taken alike)
            with torch.no_grad():
                variance = self.mean_square * torch.exp(2 * policy.log_std).mean(dim=0)
            action_dim = policy.action_net.out_features
            policy.action_dist = DiagGaussianDistribution(action_dim)
            policy.log_std = torch.nn.Parameter(0.5 * torch.log(variance))
            policy.use_sde, policy.dist_kwargs, policy.log_std_init = False, None, 0.0
            model.use_sde, model.sde_sample_freq = False, -1
            new_optimizer(model)

        def _on_step(self) -> bool:
            return True

    return Gsde()


def main(argv: list[str] | None = None) -> int:
    from frozen_std_train import curve_sixths, sweep_job

    args, job = sweep_job(
        __doc__.split("\n\n")[0],
        argv,
        ("--log-std", {"type": float, "default": -2.0, "help": "per-frame log std (default -2)"}),
        (
            "--sample-freq",
            {"type": int, "default": -1, "help": "frames between draws of W; -1: once a rollout"},
        ),
    )

    from uavlink.learn.training import train

    training = train(
        job.env,
        job.train,
        args.out,
        progress=False,
        callbacks=[gsde_callback(args.log_std, args.sample_freq)],
    )
    print(f"{job.name} with gSDE -> {args.out}; learning curve in sixths {curve_sixths(training)}")
    return 0


if __name__ == "__main__":
    run_script(main)
