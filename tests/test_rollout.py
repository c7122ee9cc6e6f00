"""The one rollout loop (uavlink/rollout.py) and the named random streams it draws from
(uavlink/seeding.py)."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.policies.baselines import StaticPolicy
from uavlink.rollout import chunks, rollout
from uavlink.seeding import EVAL, EXPORT, SHADOW, SHADOW_HOVERS, TEACHER, Stream

CFG = EnvConfig(scenario="hotspot", episode_frames=6)


class Recorder:
    """Hovers and remembers whether it was handed ground truth."""

    name = "recorder"
    layout = None

    def __init__(self, needs_truth: bool) -> None:
        self.needs_truth = needs_truth
        self.truths: list = []

    def act(self, obs, truth=None):
        self.truths.append(truth)
        return np.zeros((obs.shape[0], 2), np.float32)


def test_chunks_follow_the_streams_size_and_seeds() -> None:
    stream = Stream("test", (7,), 4)
    sizes = [chunk.env.n_envs for chunk in chunks(CFG, stream, 10, seed=3)]
    assert sizes == [4, 4, 2]
    (last,) = [c for c in chunks(CFG, stream, 10, seed=3) if c.index == 2]
    expected = BatchedUavEnv(CFG, n_envs=2, seed=np.random.SeedSequence([3, 7, 2])).reset()
    np.testing.assert_array_equal(last.observation, expected)


def test_frames_carry_what_the_policy_saw_and_did() -> None:
    frames = list(rollout(StaticPolicy(CFG), CFG, TEACHER, 3, seed=0))
    assert [f.index for f in frames] == list(range(CFG.episode_frames))
    first = next(chunks(CFG, TEACHER, 3, seed=0)).observation
    np.testing.assert_array_equal(frames[0].observation, first)
    for before, after in zip(frames, frames[1:], strict=False):
        np.testing.assert_array_equal(after.observation, before.result.observation)
    assert frames[-1].result.truncated.all() and frames[0].action.shape == (3, 2)
    assert frames[-1].env.frame == CFG.episode_frames  # the env after the step


def test_ground_truth_only_for_a_policy_that_needs_it() -> None:
    blind, seeing = Recorder(False), Recorder(True)
    list(rollout(blind, CFG, EVAL, 2, seed=0))
    list(rollout(seeing, CFG, EVAL, 2, seed=0))
    assert all(t is None for t in blind.truths)
    assert all(t is not None and t.ue_xy_m.shape == (2, CFG.n_ues, 2) for t in seeing.truths)


def test_a_policy_for_another_layout_and_a_bad_count_are_refused() -> None:
    policy = StaticPolicy(CFG)
    policy.layout = ObservationLayout(memory=2)
    with pytest.raises(ValueError, match="observation layout mismatch"):
        next(rollout(policy, CFG, EVAL, 1, seed=0))
    with pytest.raises(UserError, match="episodes must be a positive integer"):
        next(rollout(StaticPolicy(CFG), CFG, EVAL, 0, seed=0))


def test_streams_keep_the_seeds_of_the_loops_they_replaced() -> None:
    """Same seeds, same figures: evaluation's chunks were SeedSequence([seed, chunk]), export's one
    batch SeedSequence([seed, 0xE0]), the shadowing data's hovers default_rng([seed, 0x5AD, 0, chunk, 1])."""

    def state(seq: np.random.SeedSequence) -> list[int]:
        return seq.generate_state(4).tolist()

    assert state(EVAL.seed(5, 2)) == state(np.random.SeedSequence([5, 2]))
    assert state(EXPORT.seed(5, 0)) == state(np.random.SeedSequence([5, 0xE0]))
    assert state(SHADOW_HOVERS.seed(5, 3)) == state(np.random.SeedSequence([5, 0x5AD, 0, 3, 1]))
    assert SHADOW_HOVERS.chunk_envs == SHADOW.chunk_envs
    assert (
        len(
            {
                s.seed(5, 0).entropy
                if isinstance(s.seed(5, 0).entropy, int)
                else tuple(s.seed(5, 0).entropy)
                for s in (EVAL, TEACHER, SHADOW, SHADOW_HOVERS, EXPORT)
            }
        )
        == 5
    )
