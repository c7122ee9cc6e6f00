"""Behaviour-cloning warm start (ours, not the paper's): fit PPO's actor to a rule before PPO runs.

PPO from scratch finds the moves that follow the team, but not the subtler habit of the ``aoa`` rule:
keep moving while the SINRs sit below the hover level (shadowed) and stop when they do not, which
under the SPEC's shadowing model is worth up to 4 % on ``no_move`` (docs/design/radio.md). Starting PPO
from a copy of the rule lets it keep that habit and improve on the rest. The teacher
(``uavlink.learn.teachers``; the aoa rule reads the true AoAs where the student sees noisy ones) flies its
own seeded rollouts of the training env on the ``TEACHER`` stream; the student's actor (MLP +
action head) is fitted to the teacher's actions by mean squared error, and its exploration std is
reset. The critic knows nothing yet, and PPO's first updates with its random advantages would undo
the copy, so the actor stays frozen for the first few rollouts while the critic learns the cloned
policy's values (``critic_warmup_callback``). Imports torch.

A copy fitted on the teacher's own flying errs most where the teacher never goes, and the copy's
small errors take it there (Ross et al. 2011, "A reduction of imitation learning ... to no-regret
online learning"). ``dagger_rounds`` adds DAgger's remedy: the copy flies, the teacher labels the
frames it meets, and the copy is fitted again on everything gathered so far.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.learn.teachers import make_teacher
from uavlink.policies.base import Policy
from uavlink.rollout import Actor, rollout
from uavlink.seeding import DAGGER, TEACHER

# Passes over the cloning data unless TrainConfig.warm_start.epochs says otherwise.
CLONE_EPOCHS = 20


@dataclass(frozen=True)
class CloneReport:
    teacher: str
    samples: int
    epochs: int
    final_mse: float
    dagger_rounds: int = 0

    def to_dict(self) -> dict[str, Any]:
        rounds = {"dagger_rounds": self.dagger_rounds} if self.dagger_rounds else {}
        return {
            "teacher": self.teacher,
            "samples": self.samples,
            "epochs": self.epochs,
            "final_mse": round(self.final_mse, 6),
            **rounds,
        }


def teacher_dataset(
    cfg: EnvConfig, teacher: str | Actor, episodes: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """(observations, actions) float32 from ``episodes`` seeded episodes flown by ``teacher`` (a rule's
    name, or a teacher from ``uavlink.learn.teachers.make_teacher``)."""
    policy = make_teacher(cfg, teacher) if isinstance(teacher, str) else teacher
    observations, actions = [], []
    for frame in rollout(policy, cfg, TEACHER, episodes, seed):
        observations.append(frame.observation)
        actions.append(frame.action)
    return np.concatenate(observations).astype(np.float32), np.concatenate(actions).astype(
        np.float32
    )


class _LabelledFlight:
    """The copy flies (SB3's deterministic action, as its policy file would) while the teacher says
    what it would do in each frame: DAgger's data. Asks for ground truth when the teacher needs it."""

    name = "dagger"

    def __init__(self, sb3_policy: Any, teacher: Actor, cfg: EnvConfig) -> None:
        from uavlink.policies.sb3_policy import deterministic_actor

        self.actor = deterministic_actor(sb3_policy)
        self.teacher = teacher
        self.needs_truth = bool(teacher.needs_truth)
        self.layout = ObservationLayout.for_config(cfg)
        self.labels: list[np.ndarray] = []

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        import torch

        self.labels.append(self.teacher.act(obs, truth))
        with torch.no_grad():
            return self.actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()


def student_dataset(
    sb3_policy: Any, cfg: EnvConfig, teacher: Actor, episodes: int, seed: int, round_index: int
) -> tuple[np.ndarray, np.ndarray]:
    """(observations, the teacher's actions) float32 from ``episodes`` seeded episodes flown by the
    copy in ``sb3_policy``: DAgger round ``round_index``, on its own sibling of the DAGGER stream."""
    flight = _LabelledFlight(sb3_policy, teacher, cfg)
    stream = DAGGER.sibling(f"dagger-round-{round_index}", round_index)
    observations = [frame.observation for frame in rollout(flight, cfg, stream, episodes, seed)]
    return np.concatenate(observations).astype(np.float32), np.concatenate(flight.labels).astype(
        np.float32
    )


def actor_mean_parameters(sb3_policy: Any) -> list:
    """The parameters of the actor's mean (its MLP and action head; not the log std, not the critic)."""
    return [*sb3_policy.mlp_extractor.policy_net.parameters(), *sb3_policy.action_net.parameters()]


def clone_actor(
    sb3_policy: Any,
    observations: np.ndarray,
    actions: np.ndarray,
    epochs: int = CLONE_EPOCHS,
    batch_size: int = 1024,
    learning_rate: float = 1e-3,
    log_std: float = -1.0,
    seed: int = 0,
) -> float:
    """Fit the SB3 policy's actor mean to ``actions`` (MSE, Adam) and set its log std; returns the
    final epoch's mean squared error."""
    import torch

    generator = torch.Generator().manual_seed(seed)
    obs_t, act_t = torch.as_tensor(observations), torch.as_tensor(actions)
    optimizer = torch.optim.Adam(actor_mean_parameters(sb3_policy), lr=learning_rate)
    loss_sum = 0.0
    for _ in range(epochs):
        loss_sum, order = 0.0, torch.randperm(len(obs_t), generator=generator)
        for start in range(0, len(order), batch_size):
            idx = order[start : start + batch_size]
            latent = sb3_policy.mlp_extractor.forward_actor(obs_t[idx])
            loss = torch.nn.functional.mse_loss(sb3_policy.action_net(latent), act_t[idx])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            loss_sum += float(loss.detach()) * len(idx)
    with torch.no_grad():
        sb3_policy.log_std.fill_(log_std)
    return loss_sum / len(obs_t)


def warm_start(
    sb3_policy: Any,
    flights: Sequence[tuple[EnvConfig, str | Policy]],
    episodes: int,
    seed: int,
    epochs: int = CLONE_EPOCHS,
    log_std: float = -1.0,
    dagger_rounds: int = 0,
) -> CloneReport:
    """Clone the teachers of ``flights`` (each an env and its teacher: a rule's name, or a policy
    from ``make_teacher``; one per fleet size trained on) into the policy's actor from ``episodes``
    of each one's own flying; then ``dagger_rounds`` times, ``episodes`` of the copy's flying in
    each env, labelled by that env's teacher, are added and the copy is fitted again on all of it."""
    policies = [
        make_teacher(cfg, teacher) if isinstance(teacher, str) else teacher
        for cfg, teacher in flights
    ]
    data = [
        teacher_dataset(cfg, policy, episodes, seed)
        for (cfg, _), policy in zip(flights, policies, strict=True)
    ]
    observations = np.concatenate([obs for obs, _ in data])
    actions = np.concatenate([act for _, act in data])
    mse = clone_actor(sb3_policy, observations, actions, epochs=epochs, log_std=log_std, seed=seed)
    for round_index in range(dagger_rounds):
        data = [
            student_dataset(sb3_policy, cfg, policy, episodes, seed, round_index)
            for (cfg, _), policy in zip(flights, policies, strict=True)
        ]
        observations = np.concatenate([observations, *(obs for obs, _ in data)])
        actions = np.concatenate([actions, *(act for _, act in data)])
        mse = clone_actor(
            sb3_policy, observations, actions, epochs=epochs, log_std=log_std, seed=seed
        )
    return CloneReport(policies[0].name, len(observations), epochs, mse, dagger_rounds)


def critic_warmup_callback(rollouts: int):
    """An SB3 callback that freezes the actor (MLP, action head, log std) for the first ``rollouts``
    rollouts, so PPO's first updates fit only the critic."""
    from stable_baselines3.common.callbacks import BaseCallback

    class CriticWarmup(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.rollouts_done = 0

        def _set_frozen(self, frozen: bool) -> None:
            for param in [*actor_mean_parameters(self.model.policy), self.model.policy.log_std]:
                param.requires_grad_(not frozen)

        def _on_training_start(self) -> None:
            # frozen until rollout rollouts + 1 has ended (a run continued from a snapshot may
            # start past that)
            self._set_frozen(rollouts > 0 and self.rollouts_done <= rollouts)

        def _on_rollout_end(self) -> None:
            self.rollouts_done += 1
            if self.rollouts_done == rollouts + 1:  # the updates after this rollout move the actor
                self._set_frozen(False)

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:
            self._set_frozen(False)

    return CriticWarmup()
