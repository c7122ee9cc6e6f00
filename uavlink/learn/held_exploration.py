"""Exploration held for a whole episode: gSDE after the warm start (``TrainConfig.gsde_log_std``).

PPO's default noise is drawn afresh every frame. A UAV's action is a move of at most r_max a frame
and a copied policy steers back to where it wants to be, so white noise jitters it about its
placement and averages out: it never tries another placement long enough to be scored on it, while
what separates a fleet's placement rules is the placement as a whole. Generalised state-dependent
exploration (gSDE; Raffin, Kober and Stulp, CoRL 2021; SB3's ``use_sde``) draws the noise as a
function of the actor's last hidden layer, eps(s) = phi(s) . W, with W drawn once a rollout, which
with ``n_steps`` = ``episode_frames`` is once per agent row's episode: each UAV explores one
consistent change of its rule. The per-frame law is still Gaussian, so PPO's ratio stands.
Evidence: docs/design/learning.md ("Exploration held for an episode").

The callback swaps the policy's diagonal Gaussian for SB3's ``StateDependentNoiseDistribution``
where training starts (after the warm start, before the critic warm-up freezes the std it finds),
one log std per hidden unit and action, scaled so that the per-frame std on the first observations
is exp(``log_std``). Where training ends it puts a diagonal Gaussian back, its std the per-frame one
gSDE had on those observations: the saved policy is a plain SB3 policy whose mean network is all
that ``evaluate``, ``export`` and ``fly`` read.
"""

from __future__ import annotations

import math
from typing import Any

from uavlink.errors import UserError

__all__ = ["held_exploration_callback"]


def _new_optimizer(model: Any) -> None:
    """The optimizer again over the policy's parameters (the log std parameter is a new one)."""
    policy = model.policy
    policy.optimizer = policy.optimizer_class(
        policy.parameters(), lr=model.lr_schedule(1.0), **policy.optimizer_kwargs
    )


def held_exploration_callback(log_std: float, sample_freq: int = -1) -> Any:
    """An SB3 callback that trains with gSDE at a per-frame std of exp(``log_std``), W drawn every
    ``sample_freq`` frames (-1, the product's: once a rollout; research/sde_ppo.py tries others); it
    must come before the critic warm-up's callback."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.distributions import (
        DiagGaussianDistribution,
        StateDependentNoiseDistribution,
    )

    class HeldExploration(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.mean_square = 1.0  # sum_j phi_j^2 on the first observations

        def _on_training_start(self) -> None:
            model: Any = self.model  # SB3's PPO and ActorCriticPolicy, set here by attribute
            policy: Any = model.policy
            if model.use_sde:  # a second callback: its swap would save a policy nothing loads
                raise UserError(
                    "held exploration (gSDE) is on already: one held-noise callback per run"
                    " (a recipe with gsde_log_std takes no second one)"
                )
            with torch.no_grad():
                obs = torch.as_tensor(model._last_obs, dtype=torch.float32)
                features = policy.extract_features(obs)
                pi_features = features[0] if isinstance(features, tuple) else features
                latent_pi = policy.mlp_extractor.forward_actor(pi_features)
                self.mean_square = float((latent_pi**2).sum(dim=1).mean())
            # per-frame variance = sum_j phi_j^2 sigma^2 with every sigma alike
            sigma_log = log_std - 0.5 * math.log(self.mean_square)
            action_dim = policy.action_net.out_features
            dist_kwargs = {"full_std": True, "squash_output": False, "use_expln": False}
            policy.action_dist = StateDependentNoiseDistribution(
                action_dim, learn_features=False, **dist_kwargs
            )
            policy.log_std = torch.nn.Parameter(
                torch.full((latent_pi.shape[1], action_dim), sigma_log)
            )
            policy.use_sde, policy.dist_kwargs, policy.log_std_init = True, dist_kwargs, sigma_log
            _new_optimizer(model)
            model.use_sde, model.sde_sample_freq = True, sample_freq

        def _on_training_end(self) -> None:
            model: Any = self.model  # SB3's PPO and ActorCriticPolicy, set here by attribute
            policy: Any = model.policy
            with torch.no_grad():  # the per-frame variance on the first observations, per action
                variance = self.mean_square * torch.exp(2 * policy.log_std).mean(dim=0)
            policy.action_dist = DiagGaussianDistribution(policy.action_net.out_features)
            policy.log_std = torch.nn.Parameter(0.5 * torch.log(variance))
            policy.use_sde, policy.dist_kwargs, policy.log_std_init = False, None, 0.0
            model.use_sde, model.sde_sample_freq = False, -1
            _new_optimizer(model)

        def _on_step(self) -> bool:
            return True

    return HeldExploration()
