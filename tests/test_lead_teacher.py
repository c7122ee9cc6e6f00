"""The fleet's lead teacher (uavlink/learn/lead_teacher.py): roles read from the observation, the leader's
single-UAV view, and what it is for: one UAV serving, the other silent, beating the fleet aoa rule."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from uavlink.config import EnvConfig, TrainConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import FIELDS, ObservationLayout
from uavlink.errors import UserError
from uavlink.evaluation import evaluate_policy
from uavlink.learn.lead_teacher import (
    LeadTeacher,
    leader_index,
    make_lead_teacher,
    single_layout,
    single_view,
)
from uavlink.learn.teachers import make_teacher
from uavlink.policies.baselines import AoaPolicy
from uavlink.policies.registry import make_baseline

FLEET = (
    EnvConfig()
    .replace(scenario="no_move", n_uavs=2, **{"radio.shadowing_model": "spatial"})
    .validate()
)
SINGLE_POLICY = Path(__file__).resolve().parents[1] / "policies" / "spatial" / "no_move.zip"
MAP_POLICY = SINGLE_POLICY.parents[1] / "map" / "no_move.zip"


def _fleet_obs(steps: int = 5) -> tuple[LeadTeacher, np.ndarray]:
    teacher = make_lead_teacher(FLEET)
    env = BatchedUavEnv(FLEET, n_envs=32, seed=3)
    obs = env.reset()
    for _ in range(steps):
        obs = env.step(teacher.act(obs)).observation
    return teacher, obs


def test_single_view_is_the_v1_fields_of_every_frame() -> None:
    teacher, obs = _fleet_obs()
    fleet, single = teacher.layout, single_layout(teacher.layout)
    view = single_view(fleet, obs)
    assert single == ObservationLayout.for_config(FLEET.replace(n_uavs=1)) and view.shape == (
        len(obs),
        single.size,
    )
    for field in FIELDS:
        np.testing.assert_array_equal(
            single.history(view, field.quantity), fleet.history(obs, field.quantity)
        )


def test_every_uav_of_an_env_picks_the_same_leader_the_one_serving_most() -> None:
    teacher, obs = _fleet_obs()
    index, _ = leader_index(teacher.layout, obs)
    lead = (index == 0).reshape(-1, 2)
    assert (lead.sum(axis=1) == 1).all()  # one leader per env, as both UAVs see it
    other = np.where(index == 0, 1, 0)  # D = 2: the other UAV, as the row numbers it
    served = (teacher.layout.history(obs, "served_by")[..., None] == np.arange(2)).sum(axis=(1, 2))
    rows = np.arange(len(obs))
    assert (served[rows, index] >= served[rows, other]).all()


def test_leader_flies_its_single_policy_the_other_heads_for_a_far_corner() -> None:
    teacher, obs = _fleet_obs()
    lead = leader_index(teacher.layout, obs)[0] == 0
    action = teacher.act(obs)
    frame = teacher.layout.newest_frame(obs)
    near = (frame["aoa_std_deg"] >= teacher.close_spread_deg) | (
        frame["sinr_db"].mean(axis=1) >= teacher.hover_sinr_db + teacher.far_sinr_margin_db
    )
    assert (lead & near).any()
    np.testing.assert_allclose(
        action[lead & near],
        teacher.leader.act(single_view(teacher.layout, obs[lead & near])),
        rtol=1e-6,
    )
    far = lead & ~near  # a leader still far from the UEs closes in at full speed
    assert far.any()
    np.testing.assert_allclose(
        np.linalg.norm(teacher.mapping.to_displacement_m(action[far]), axis=1),
        teacher.mapping.r_max_m,
        rtol=1e-5,
    )
    xy = teacher.layout.newest_frame(obs)["uav_xy_m"]
    step = teacher.mapping.to_displacement_m(action[~lead])
    leader_xy = xy.reshape(-1, 2, 2)[lead.reshape(-1, 2)]  # the away row's env's leader, env order
    assert (
        np.linalg.norm(xy[~lead] + step - leader_xy, axis=1)
        > np.linalg.norm(xy[~lead] - leader_xy, axis=1)
    ).all()


@pytest.mark.slow
def test_one_uav_serves_and_the_fleet_beats_its_aoa_rule() -> None:
    """The point of the teacher: with one group the away cell empties and the fleet outdoes the
    fleet aoa rule (whose two active cells interfere)."""
    teacher = make_lead_teacher(FLEET, str(SINGLE_POLICY))
    ours = evaluate_policy(teacher, FLEET, episodes=32, seed=1)
    rule = evaluate_policy(make_baseline("aoa", FLEET), FLEET, episodes=32, seed=1)
    assert ours.mean_rate_mbps > 1.05 * rule.mean_rate_mbps


def test_make_teacher_and_config_name_the_lead_teacher() -> None:
    assert isinstance(make_teacher(FLEET, "lead"), LeadTeacher)
    assert isinstance(make_teacher(FLEET, "lead").leader, AoaPolicy)
    assert make_teacher(FLEET, "lead", leader_policy=str(SINGLE_POLICY)).leader.name == "no_move"
    with pytest.raises(UserError, match="fleet"):
        make_teacher(FLEET.replace(n_uavs=1), "lead")
    with pytest.raises(UserError, match="leader_policy needs train.warm_start.teacher lead"):
        make_teacher(FLEET, "solo", leader_policy=str(SINGLE_POLICY))
    with pytest.raises(UserError, match="leader_policy"):
        TrainConfig.from_dict(
            {"warm_start": {"teacher": "aoa", "leader_policy": "x.zip"}}
        ).validate()
    with pytest.raises(
        UserError, match="layout mismatch"
    ):  # a fleet policy cannot lead: v2, not v1
        LeadTeacher(FLEET, make_baseline("aoa", FLEET))


@pytest.mark.slow
def test_in_a_fleet_with_a_memory_of_place_a_v1_leader_flies_as_before_and_a_v3_leader_reads_it() -> (
    None
):
    """Layout v7 (v6 + the memory of place): a v1 leader gets the v1 fields alone and flies the same
    episodes as in v6, to the bit; a rule that reads the memory (``explore``, v3) gets it."""
    v6 = FLEET.replace(fleet_slots=3).validate()
    v7 = v6.replace(place_cell_m=12.0).validate()
    before = evaluate_policy(make_lead_teacher(v6, str(SINGLE_POLICY)), v6, 2, 5)
    after_teacher = make_lead_teacher(v7, str(SINGLE_POLICY))
    assert after_teacher.single.version == 1
    after = evaluate_policy(after_teacher, v7, 2, 5)
    np.testing.assert_array_equal(before.episode_rate_mbps, after.episode_rate_mbps)
    explore = make_lead_teacher(v7, "explore")
    assert explore.single == ObservationLayout.for_config(v7.replace(n_uavs=1, fleet_slots=0))
    assert explore.single.version == 3
    env = BatchedUavEnv(v7, n_envs=2, seed=5)
    obs = env.reset()
    for _ in range(3):
        obs = env.step(explore.act(obs)).observation
    view = single_view(explore.layout, obs)
    np.testing.assert_array_equal(
        explore.single.history(view, "place_best_offset_m"),
        explore.layout.history(obs, "place_best_offset_m"),
    )


def test_in_a_fleet_with_a_model_of_the_field_a_v5_leader_reads_its_own_and_is_never_dashed() -> (
    None
):
    """Layout v8 (v7 + each UAV's model of the field): a leader that reads a model (no_move's map
    policy, v5) gets its own, and flies its own moves from the start, 100 m off the UEs, where a
    leader without a model is dashed towards them."""
    v8 = FLEET.replace(fleet_slots=3, place_cell_m=12.0, place_model="kriging").validate()
    teacher = make_lead_teacher(v8, str(MAP_POLICY))
    assert teacher.single == ObservationLayout.for_config(v8.replace(n_uavs=1, fleet_slots=0))
    assert teacher.single.version == 5 and not teacher.dash
    assert make_lead_teacher(v8.replace(place_model="cells").validate(), str(SINGLE_POLICY)).dash
    obs = BatchedUavEnv(v8, n_envs=4, seed=5).reset()
    view = single_view(teacher.layout, obs)
    np.testing.assert_array_equal(
        teacher.single.history(view, "place_pick_offset_m"),
        teacher.layout.history(obs, "place_pick_offset_m"),
    )
    lead = leader_index(teacher.layout, obs)[0] == 0
    assert lead.any()
    np.testing.assert_array_equal(teacher.act(obs)[lead], teacher.leader.act(view)[lead])


def test_in_a_listening_fleet_the_uavs_that_do_not_serve_hold_and_the_leader_reads_the_pool() -> (
    None
):
    """``fleet_reuse = "listen"`` with one pooled model (v9): the leader (the serving UAV) flies the
    map policy on a v5 view of the fleet's model; the others take no UE wherever they are, so they
    hold rather than fly to the far corners."""
    v9 = FLEET.replace(
        fleet_slots=3, place_cell_m=12.0, place_model="pooled", fleet_reuse="listen"
    ).validate()
    teacher = make_lead_teacher(v9, str(MAP_POLICY))
    assert teacher.single.version == 5 and not teacher.dash
    env = BatchedUavEnv(v9, n_envs=8, seed=5)
    obs = env.reset()
    for _ in range(3):
        obs = env.step(teacher.act(obs)).observation
    lead = leader_index(teacher.layout, obs)[0] == 0
    assert lead.sum() == 8  # one leader per fleet: the serving UAV
    np.testing.assert_array_equal(
        env.readings.serving.max(axis=1), env.readings.serving.min(axis=1)
    )
    np.testing.assert_array_equal(teacher.act(obs)[~lead], 0.0)
    np.testing.assert_array_equal(
        teacher.act(obs)[lead], teacher.leader.act(single_view(teacher.layout, obs))[lead]
    )
