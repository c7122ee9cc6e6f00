"""Named random streams: the seed tree each kind of seeded rollout draws its episodes from.

Chunk i of a rollout on stream S with seed s runs up to ``S.chunk_envs`` envs seeded with
``SeedSequence([s, *S.tag, i, *S.suffix])``. Each stream's tag and chunk size are declared here
once: two kinds of rollout never share episodes by accident, and changing one never moves another's
figures. ``uavlink.rollout`` runs the episodes; a consumer's own random draws (the shadowing data's
hovers) come from a sibling stream (``Stream.sibling``), one generator per chunk.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass(frozen=True)
class Stream:
    name: str
    tag: tuple[int, ...]
    chunk_envs: int
    suffix: tuple[int, ...] = ()  # words after the chunk index (a sibling's draws)

    def seed(self, seed: int, chunk: int = 0) -> np.random.SeedSequence:
        return np.random.SeedSequence([seed, *self.tag, chunk, *self.suffix])

    def generator(self, seed: int, chunk: int = 0) -> np.random.Generator:
        return np.random.default_rng(self.seed(seed, chunk))

    def sibling(self, name: str, word: int) -> Stream:
        """A stream beside this one's chunk seeds, for a consumer's own draws in the same chunks."""
        return replace(self, name=name, suffix=(*self.suffix, word))


# Evaluation (uavlink evaluate, reports, sweeps) and the SITL's radio payload (episode 0 of seed S).
EVAL = Stream("eval", (), 128)
# A rule's flying that the warm start clones (uavlink/learn/imitation.py).
TEACHER = Stream("teacher", (0xB0,), 64)
# The episodes training keeps its best weights on (uavlink/learn/selection.py;
# TrainConfig.validation_episodes), apart from every evaluation seed's, so a policy chosen on them is
# scored on episodes it never met.
VALIDATION = Stream("validation", (0x5E1,), 128)
# A copy's flying that its teacher labels, one sibling per DAgger round (research/clone_gap.py).
DAGGER = Stream("dagger", (0xDA,), 64)
# The shadowing estimator's fitting data, and its held-out check (uavlink/learn/shadow_estimation.py);
# the data's rule hovers at random, drawn per chunk from the *_HOVERS siblings.
SHADOW = Stream("shadow", (0x5AD, 0), 64)
SHADOW_HELD_OUT = Stream("shadow-held-out", (0x5AD, 1), 64)
SHADOW_HOVERS = SHADOW.sibling("shadow-hovers", 1)
SHADOW_HELD_OUT_HOVERS = SHADOW_HELD_OUT.sibling("shadow-held-out-hovers", 1)
# The observations export verification checks the ONNX graph on (uavlink/export.py): one chunk of
# up to 1024 envs stepped together, so any prefix holds every env's first frames. Its seeds were
# SeedSequence([s, 0xE0]) before this stream had a chunk index; a trailing 0 word in an entropy of
# at most four words draws the same state, so chunk 0 is those same episodes.
EXPORT = Stream("export", (0xE0,), 1024)
# Each fleet size's envs when several train together (uavlink.env.vec_env.FleetSizesVecEnv): chunk k
# is the k-th size's batch, so the sizes fly different episodes.
FLEET_SIZES = Stream("fleet-sizes", (0xF5,), 1 << 16)
