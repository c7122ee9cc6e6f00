"""The one seeded rollout loop: a policy flies N episodes of a config on a named random stream.

Episodes run in chunks of ``stream.chunk_envs`` envs stepped together (``uavlink.seeding``); chunk i
is seeded from the stream alone, so what a consumer sees depends only on (policy, config, stream,
episodes, seed). Consumers (evaluation, the warm start's teacher data, the shadowing estimator's
data, export verification, benchmarks) read the frames: ``rollout`` for a policy fixed over all
chunks, ``chunks`` where a consumer builds its policy per chunk (from the chunk's env or draws) or
reads the env right after reset.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv, GroundTruth, StepResult
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.seeding import Stream


class Actor(Protocol):
    """What a rollout flies: ``uavlink.policies.base.Policy``, or a teacher that reads ground truth."""

    @property
    def needs_truth(self) -> bool: ...  # read-only: a class attribute satisfies it

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray: ...


@dataclass(frozen=True)
class Frame:
    """One step of a chunk: the policy saw ``observation`` and chose ``action``; ``env`` is after the step."""

    chunk: int
    index: int  # frame of the episode, from 0
    observation: np.ndarray  # (n, obs) float32, what the policy acted on
    action: np.ndarray  # (n, 2), as the policy returned it
    result: StepResult
    env: BatchedUavEnv


class Chunk:
    """Chunk ``index`` of a rollout: ``env`` just reset, ``observation`` its first observations."""

    def __init__(self, index: int, env: BatchedUavEnv) -> None:
        self.index = index
        self.env = env
        self.observation = env.reset()

    def frames(self, policy: Actor) -> Iterator[Frame]:
        """Fly the chunk's episodes with ``policy``, yielding each frame after its step; a consumer
        may stop early (export verification does)."""
        layout: ObservationLayout | None = getattr(policy, "layout", None)
        if layout is not None:
            layout.check_matches(
                self.env.layout, what=f"policy {getattr(policy, 'name', policy)!r}"
            )
        obs = self.observation
        for index in range(self.env.cfg.episode_frames):
            truth = self.env.ground_truth() if policy.needs_truth else None
            action = policy.act(obs, truth)
            result = self.env.step(action)
            yield Frame(self.index, index, obs, action, result, self.env)
            obs = result.observation


def chunks(cfg: EnvConfig, stream: Stream, episodes: int, seed: int) -> Iterator[Chunk]:
    """The chunks of ``episodes`` episodes on ``stream`` with ``seed``, each reset and ready to fly."""
    if int(episodes) != episodes or episodes < 1:
        raise UserError(f"episodes must be a positive integer, got {episodes}")
    for index, start in enumerate(range(0, int(episodes), stream.chunk_envs)):
        n_envs = min(stream.chunk_envs, int(episodes) - start)
        yield Chunk(index, BatchedUavEnv(cfg, n_envs=n_envs, seed=stream.seed(seed, index)))


def rollout(
    policy: Actor, cfg: EnvConfig, stream: Stream, episodes: int, seed: int
) -> Iterator[Frame]:
    """Every frame of ``episodes`` seeded episodes flown by ``policy``, chunk after chunk."""
    for chunk in chunks(cfg, stream, episodes, seed):
        yield from chunk.frames(policy)
