"""Named random streams: the seed tree each kind of seeded rollout draws its episodes from.

Chunk i of a rollout on stream S with seed s runs ``S.chunk_envs`` envs seeded with
``SeedSequence([s, *S.tag, i])``. Each stream's tag and chunk size are declared here once: two
kinds of rollout never share episodes by accident, and changing one never moves another's figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Stream:
    name: str
    tag: tuple[int, ...]
    chunk_envs: int

    def seed(self, seed: int, chunk: int = 0) -> np.random.SeedSequence:
        return np.random.SeedSequence([seed, *self.tag, chunk])


# Evaluation (uavlink evaluate, reports, sweeps) and the SITL's radio payload (episode 0 of seed S).
EVAL = Stream("eval", (), 128)
# A rule's flying that the warm start clones (uavlink/imitation.py).
TEACHER = Stream("teacher", (0xB0,), 64)
# The shadowing estimator's fitting data, and its held-out check (uavlink/shadow_estimation.py).
SHADOW = Stream("shadow", (0x5AD, 0), 64)
SHADOW_HELD_OUT = Stream("shadow-held-out", (0x5AD, 1), 64)
