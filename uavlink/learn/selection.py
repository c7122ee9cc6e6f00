"""Keep the best weights on validation episodes (ours; SB3's ``EvalCallback`` with a
``best_model_save_path`` does the same for its own environments).

Why: PPO started from a rule's copy at a small learning rate, where the rule is already about as
good as the scenario allows, walks at random around the copy (research/log/memory-of-place.md,
"Where the team moves"; research/log/map-policies.md, "DAgger on hotspot"): its last weights are a
draw, above or below where it started. With ``TrainConfig.validation_episodes`` > 0 the
deterministic policy (what ``evaluate`` and ``fly`` fly,
``uavlink.policies.sb3_policy.ActorPolicy``) flies that many episodes of the policy's env on the
``VALIDATION`` stream before the first update (the warm start's weights), after each update and at
the end, and training ships the weights that flew best (all but the exploration std, which held
exploration reshapes: ``uavlink/learn/held_exploration.py``). The stream's episodes are apart from
every evaluation seed's, so a policy chosen on them is scored on episodes it never met. Imports torch.
"""

from __future__ import annotations

import copy
from typing import Any

from uavlink.config import EnvConfig
from uavlink.env.observation import ObservationLayout
from uavlink.rollout import Actor, rollout
from uavlink.seeding import VALIDATION


def validation_rate_mbps(policy: Actor, cfg: EnvConfig, episodes: int, seed: int) -> float:
    """Mean UE throughput (Mbit/s) of ``policy`` over ``episodes`` episodes of ``cfg`` on the
    ``VALIDATION`` stream: the figure ``evaluate`` reports, on other episodes."""
    total, count = 0.0, 0
    for frame in rollout(policy, cfg, VALIDATION, episodes, seed):
        total += float(frame.result.mean_rate_mbps.sum())
        count += frame.result.mean_rate_mbps.size
    return total / count


def _without_std(state: dict[str, Any]) -> dict[str, Any]:
    """A copy of a policy's weights but its exploration std: with held exploration the std is
    gSDE's while training and a diagonal Gaussian's at the end (another shape), and what a policy
    flies is its mean network alone."""
    return {k: copy.deepcopy(v) for k, v in state.items() if k != "log_std"}


def keep_best_callback(cfg: EnvConfig, episodes: int, seed: int):
    """An SB3 callback that scores the policy on validation episodes before each rollout (the
    weights of the update before) and at the end, and leaves the model holding the best weights
    scored (the earliest among equals). ``curve`` lists (agent steps, Mbit/s); ``kept`` the best's."""
    from stable_baselines3.common.callbacks import BaseCallback

    from uavlink.policies.sb3_policy import ActorPolicy

    layout = ObservationLayout.for_config(cfg)

    class KeepBest(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.curve: list[tuple[int, float]] = []
            self.kept: tuple[int, float] | None = None
            self._best_state: dict[str, Any] | None = None

        def _score(self) -> None:
            policy = ActorPolicy(self.model.policy, layout, "training")
            point = (
                int(self.num_timesteps),
                round(validation_rate_mbps(policy, cfg, episodes, seed), 6),
            )
            self.curve.append(point)
            if self.kept is None or point[1] > self.kept[1]:
                self.kept, self._best_state = point, _without_std(self.model.policy.state_dict())

        def _on_rollout_start(self) -> None:
            self._score()

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:
            self._score()
            assert self._best_state is not None  # _score() keeps the first point it scores
            self.model.policy.load_state_dict(
                {**self.model.policy.state_dict(), **self._best_state}
            )

        def report(self) -> dict[str, Any]:
            """The manifest's ``training.validation``."""
            assert self.kept is not None  # asked after training, which scored at least once
            return {
                "episodes": episodes,
                "stream": VALIDATION.name,
                "seed": seed,
                "kept_steps": self.kept[0],
                "kept_mbps": self.kept[1],
                "curve": [list(point) for point in self.curve],
            }

    return KeepBest()
