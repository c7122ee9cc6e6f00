"""The radio world the SITL's payload flies in is the evaluation's episode 0 for its seed."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import SCENARIOS, EnvConfig
from uavlink.env.radio_world import RadioWorld, episode_scenario
from uavlink.evaluation import evaluate_policy
from uavlink.policies.baselines import StaticPolicy
from uavlink.rollout import chunks
from uavlink.seeding import EVAL


@pytest.mark.parametrize("scenario,seed", [("circular", 3), ("hotspot", 0), ("mixed", 4)])
def test_hovering_in_the_radio_world_scores_the_one_episode_evaluation(
    scenario: str, seed: int
) -> None:
    cfg = EnvConfig().replace(scenario=scenario).validate()
    world = RadioWorld(cfg, seed)
    first = world.readings()
    assert world.frame == 0 and first.sinr_db.shape == first.aoa_deg.shape == (cfg.n_ues,)
    scores = [world.advance([0.0, 0.0]) for _ in range(cfg.episode_frames)]
    assert world.frame == cfg.episode_frames
    assert all(s.rate_bps.shape == (cfg.n_ues,) for s in scores)
    assert scores[-1].mean_rate_mbps == pytest.approx(float(np.mean(scores[-1].rate_bps)) * 1e-6)
    evaluated = evaluate_policy(StaticPolicy(cfg), cfg, episodes=1, seed=seed)
    # the same UEs and channel draws: equal up to the order of the mean's summation
    rel = 1e-12
    assert np.mean([s.mean_rate_mbps for s in scores]) == pytest.approx(
        evaluated.episode_rate_mbps[0], rel=rel
    )
    assert np.mean([s.fair_rate for s in scores]) == pytest.approx(
        evaluated.episode_fair_rate[0], rel=rel
    )


def test_mixed_draws_each_seeds_scenario_as_the_evaluation_episode_does() -> None:
    """A vehicle with --scenario mixed flies, per seed, the scenario `uavlink evaluate --episodes 1
    --seed S` draws for that episode (so a mixed policy's flight is comparable with it)."""
    cfg = EnvConfig().replace(scenario="mixed").validate()
    drawn = [episode_scenario(cfg, seed) for seed in range(12)]
    evaluated = [
        SCENARIOS[int(next(chunks(cfg, EVAL, 1, seed)).env.scenario_ids[0])] for seed in range(12)
    ]
    assert drawn == evaluated == [RadioWorld(cfg, seed).scenario for seed in range(12)]
    assert len(set(drawn)) > 2  # drawn per seed, not one for all
    assert episode_scenario(cfg.replace(scenario="hotspot"), 3) == "hotspot"


def test_positions_are_clipped_to_the_area_and_shaped_per_uav() -> None:
    cfg = EnvConfig().replace(scenario="straight").validate()
    a, b = RadioWorld(cfg, 1), RadioWorld(cfg, 1)
    far = 10 * cfg.area.half_width_m
    sa = a.advance([[far, -far]])
    sb = b.advance([cfg.area.half_width_m, -cfg.area.half_width_m])
    np.testing.assert_array_equal(sa.rate_bps, sb.rate_bps)
    np.testing.assert_array_equal(a.readings().sinr_db, b.readings().sinr_db)
    with pytest.raises(ValueError):
        a.advance([[0.0, 0.0], [1.0, 1.0]])  # one UAV today
