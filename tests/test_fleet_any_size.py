"""A fleet of any size (layout v6, ``EnvConfig.fleet_slots``; v7 with a memory of place): one observation for 2 to K + 1 UAVs,
the bearing fix, the contract that lets one policy fly every size its slots allow, and training on
several sizes at once."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from uavlink.config import EnvConfig, TrainConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.field_model import FieldModel
from uavlink.env.observation import (
    ANY_FLEET_KRIGING_LAYOUT_VERSION,
    ANY_FLEET_LAYOUT_VERSION,
    ANY_FLEET_PLACE_LAYOUT_VERSION,
    ANY_FLEET_POOLED_LAYOUT_VERSION,
    PLACE_FIELDS,
    ObservationLayout,
)
from uavlink.env.observation.fleet_view import slot_quantities
from uavlink.env.place_memory import sensed_value_bits
from uavlink.errors import ConfigError, UserError
from uavlink.policies.contract import EnvOverrides, apply_overrides
from uavlink.radio.aoa import bearing_fix_xy_m, true_aoa_deg

SPATIAL = {"radio.shadowing_model": "spatial"}


def _cfg(n_uavs: int, **changes: object) -> EnvConfig:
    return EnvConfig().replace(n_uavs=n_uavs, fleet_slots=3, **SPATIAL, **changes).validate()


def test_one_layout_for_two_three_and_four_uavs() -> None:
    layouts = {ObservationLayout.for_config(_cfg(d)) for d in (2, 3, 4)}
    assert len(layouts) == 1
    (layout,) = layouts
    assert layout.version == ANY_FLEET_LAYOUT_VERSION and layout.uav_slots == 3
    assert "n_uavs" not in layout.to_dict() and layout.to_dict()["uav_slots"] == 3
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    names = layout.feature_names()
    assert len(names) == len(set(names)) == layout.size
    assert "t-0:slot_present_2" in names and "t-0:ue_fix_dx_9" in names
    # the per-size layout of before is untouched: it still grows with D
    v2 = [ObservationLayout.for_config(EnvConfig(n_uavs=d).validate()) for d in (2, 3)]
    assert v2[0].version == v2[1].version == 2 and v2[0].size < v2[1].size


@pytest.mark.parametrize("n_uavs", [2, 3, 4])
def test_the_env_gives_every_size_the_same_observation_within_bounds(n_uavs: int) -> None:
    env = BatchedUavEnv(_cfg(n_uavs, scenario="straight_90"), n_envs=3, seed=1)
    obs = env.reset()
    low, high = env.layout.bounds()
    rng = np.random.default_rng(0)
    for _ in range(20):
        obs = env.step(rng.uniform(-1, 1, (env.n_rows, 2))).observation
        assert obs.shape == (3 * n_uavs, env.layout.size)
        assert np.all(obs >= low - 1e-6) and np.all(obs <= high + 1e-6)
    frame = env.layout.newest_frame(obs)
    assert frame["slot_present"].sum(axis=1).tolist() == [n_uavs - 1] * (3 * n_uavs)
    # every UE is served by exactly one UAV of its env
    served = frame["served_here"].reshape(3, n_uavs, -1).sum(axis=1)
    assert np.all(served == 1)


def test_slots_list_the_others_nearest_first_and_servers_relative_to_me() -> None:
    uav = np.array([[[0.0, 0.0], [50.0, 0.0], [0.0, -30.0]]])  # (1, 3, 2)
    serving = np.array([[2, 0, 1]])
    aoa = true_aoa_deg(uav[:, :, None, :], np.array([[[10.0, 10.0], [-40.0, 5.0], [60.0, 60.0]]]))
    q = slot_quantities(uav, serving, aoa, uav_slots=3, half_width_m=200.0)
    # UAV 0 sees UAV 2 (30 m) before UAV 1 (50 m), and an empty third slot
    np.testing.assert_allclose(q["slot_offset_m"][0], [[0.0, -30.0], [50.0, 0.0], [0.0, 0.0]])
    assert q["slot_present"][0].tolist() == [True, True, False]
    assert q["served_here"][1].tolist() == [False, False, True]
    np.testing.assert_allclose(q["server_offset_m"][1, 0], [-50.0, -30.0])  # UE 0's server, UAV 2
    # with exact bearings the fix is the UE, seen from each UAV
    np.testing.assert_allclose(q["ue_fix_offset_m"][2, 2], [60.0, 90.0], atol=1e-3)
    with pytest.raises(ValueError, match="slots"):
        slot_quantities(uav, serving, aoa, uav_slots=1, half_width_m=200.0)


def test_the_bearing_fix_finds_the_ue_and_stays_finite_in_line() -> None:
    rng = np.random.default_rng(3)
    uav = rng.uniform(-150, 150, (50, 3, 2))
    ue = rng.uniform(-150, 150, (50, 10, 2))
    aoa = true_aoa_deg(uav[:, :, None, :], ue[:, None, :, :])
    miss_m = np.linalg.norm(bearing_fix_xy_m(uav, aoa) - ue, axis=-1)
    assert (
        np.quantile(miss_m, 0.99) < 0.01 and miss_m.max() < 1.0
    )  # the ridge's pull, nearly in line
    # a UE on the line through both UAVs: every point of it fits; the fix stays on the line
    uav2 = np.array([[[-100.0, 0.0], [100.0, 0.0]]])
    fix = bearing_fix_xy_m(uav2, true_aoa_deg(uav2[:, :, None, :], np.array([[[[20.0, 0.0]]]])))
    assert np.all(np.isfinite(fix)) and abs(fix[0, 0, 1]) < 1e-6


def test_config_refuses_sizes_the_slots_cannot_fly() -> None:
    with pytest.raises(ConfigError, match="fleets of 2 to 4 UAVs, not n_uavs=5"):
        EnvConfig(n_uavs=5, fleet_slots=3).validate()
    with pytest.raises(ConfigError, match="not n_uavs=1"):
        EnvConfig(fleet_slots=3).validate()
    with pytest.raises(ConfigError, match="fleet_sizes_up_to=4 needs"):
        TrainConfig(fleet_sizes_up_to=4).validate(EnvConfig(n_uavs=2, fleet_slots=2).validate())
    assert TrainConfig(fleet_sizes_up_to=4).fleet_sizes == (2, 3, 4)


def test_a_policy_built_for_any_size_flies_every_size_its_slots_allow() -> None:
    built = _cfg(3)
    for size in (2, 4):
        cfg = apply_overrides(built, EnvOverrides(settings={"n_uavs": size}), built_for="p.zip")
        assert cfg.n_uavs == size
    with pytest.raises(UserError, match="fleets of 2 to 4"):
        apply_overrides(built, EnvOverrides(settings={"n_uavs": 5}), built_for="p.zip")
    with pytest.raises(UserError, match="built for fleet_slots=3"):
        apply_overrides(built, EnvOverrides(settings={"fleet_slots": 2}), built_for="p.zip")
    # a per-size policy (layout v2) still flies its own size only
    v2 = EnvConfig(n_uavs=2).validate()
    with pytest.raises(UserError, match="built for n_uavs=2"):
        apply_overrides(v2, EnvOverrides(settings={"n_uavs": 3}), built_for="p.zip")


@pytest.mark.parametrize("n_uavs", [2, 4])
def test_the_pettingzoo_face_serves_any_size(n_uavs: int) -> None:
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test

    from uavlink.fleet import parallel_env

    env = parallel_env("hotspot", n_uavs, fleet_slots=3, episode_frames=8)
    assert env.observation_space("uav_0").shape == (ObservationLayout.for_config(_cfg(2)).size,)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parallel_api_test(env, num_cycles=12)


def test_several_sizes_train_side_by_side() -> None:
    pytest.importorskip("stable_baselines3")
    from uavlink.env.vec_env import FleetSizesVecEnv

    venv = FleetSizesVecEnv.for_sizes(_cfg(3, episode_frames=4), (2, 3, 4), n_envs=2, seed=5)
    assert venv.num_envs == 2 * (2 + 3 + 4)
    obs = venv.reset()
    for _ in range(4):
        obs, reward, done, infos = venv.step(np.zeros((venv.num_envs, 2), np.float32))
        assert obs.shape == (18, venv.observation_space.shape[0]) and reward.shape == (18,)
    assert done.all() and all("terminal_observation" in info for info in infos)
    # each size flies its own episodes (its own chunk of the seed), reproducibly
    again = FleetSizesVecEnv.for_sizes(_cfg(3, episode_frames=4), (2, 3, 4), n_envs=2, seed=5)
    first = again.reset()
    np.testing.assert_array_equal(
        first,
        FleetSizesVecEnv.for_sizes(_cfg(3, episode_frames=4), (2, 3, 4), n_envs=2, seed=5).reset(),
    )
    parts = [part.core.ground_truth().ue_xy_m for part in again.parts]
    assert not np.allclose(parts[0], parts[1])


def test_the_bearings_teacher_heads_for_its_cells_centroid_without_gps() -> None:
    from uavlink.learn.teachers import make_teacher

    cfg = _cfg(3, scenario="straight_90")
    env = BatchedUavEnv(cfg, n_envs=4, seed=2)
    obs = env.reset()
    teacher = make_teacher(cfg, "bearings")
    assert teacher.needs_truth is False
    move = env.actions.to_displacement_m(teacher.act(obs))
    truth, serving = env.ground_truth(), env.readings.serving
    for row in range(env.n_rows):
        n, d = divmod(row, 3)
        mine = serving[n] == d
        if not mine.any():
            assert np.allclose(move[row], 0.0)  # an empty cell holds
            continue
        offset = truth.ue_xy_m[n, mine].mean(axis=0) - truth.uav_xy_m[row]
        cos = move[row] @ offset / (np.linalg.norm(move[row]) * np.linalg.norm(offset))
        assert cos > 0.999
    with pytest.raises(ConfigError, match="fleet_slots > 0"):
        make_teacher(EnvConfig(n_uavs=2).validate(), "bearings")


def test_the_lead_teachers_roles_read_the_same_from_either_fleet_layout() -> None:
    from uavlink.learn.teachers import make_teacher
    from uavlink.rollout import rollout
    from uavlink.seeding import EVAL

    flown = []
    for slots in (0, 3):
        cfg = EnvConfig().replace(
            scenario="no_move", n_uavs=2, fleet_slots=slots, episode_frames=24, **SPATIAL
        )
        teacher = make_teacher(cfg.validate(), "lead", leader_policy="policies/spatial/no_move.zip")
        frames = rollout(teacher, cfg.validate(), EVAL, 4, 0)
        flown.append(np.stack([frame.action for frame in frames]))
    np.testing.assert_array_equal(flown[0], flown[1])


def test_a_memory_of_place_makes_layout_v7_for_every_size_with_each_uavs_own_memory() -> None:
    """v6 plus the memory of place (``place_cell_m`` > 0): one layout for 2-4 UAVs, and each UAV's
    place fields are the ones the fleet of a given size (v4) keeps for it on the same episodes."""
    layouts = {ObservationLayout.for_config(_cfg(d, place_cell_m=12.0)) for d in (2, 3, 4)}
    assert len(layouts) == 1
    (layout,) = layouts
    v6 = ObservationLayout.for_config(_cfg(2))
    assert layout.version == ANY_FLEET_PLACE_LAYOUT_VERSION and layout.uav_slots == 3
    assert layout.frame_size == v6.frame_size + sum(f.width(layout) for f in PLACE_FIELDS)
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    assert "t-0:place_best_dx" in layout.feature_names()
    assert "t-3:slot_present_2" in layout.feature_names()
    v7 = BatchedUavEnv(_cfg(3, place_cell_m=12.0, scenario="no_move"), n_envs=2, seed=4)
    v4_cfg = EnvConfig().replace(n_uavs=3, place_cell_m=12.0, scenario="no_move", **SPATIAL)
    v4 = BatchedUavEnv(v4_cfg.validate(), n_envs=2, seed=4)
    assert v4.layout.version == 4
    obs7, obs4 = v7.reset(), v4.reset()
    rng = np.random.default_rng(2)
    for _ in range(12):
        action = rng.uniform(-1, 1, (v7.n_rows, 2))
        obs7, obs4 = v7.step(action).observation, v4.step(action).observation
    for field in PLACE_FIELDS:
        np.testing.assert_array_equal(
            v7.layout.history(obs7, field.quantity), v4.layout.history(obs4, field.quantity)
        )
    assert np.all(v7.layout.newest_frame(obs7)["place_frames"] == 13)  # the reset and 12 steps


def test_a_model_of_the_field_makes_layout_v8_for_every_size_with_each_uavs_own_model() -> None:
    """v7 plus the model of the sensed field (``place_model = "kriging"``): one layout for 2-4
    UAVs, v7's fields unchanged, and each UAV's pick the one its own model (fed its own position and
    what it senses, as one UAV's v5 is) makes."""
    kriging = {"place_cell_m": 12.0, "place_model": "kriging", "scenario": "no_move"}
    layouts = {ObservationLayout.for_config(_cfg(d, **kriging)) for d in (2, 3, 4)}
    assert len(layouts) == 1
    (layout,) = layouts
    assert layout.version == ANY_FLEET_KRIGING_LAYOUT_VERSION
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    assert "t-0:place_pick_dx" in layout.feature_names()
    v8 = BatchedUavEnv(_cfg(3, **kriging), n_envs=2, seed=4)
    v7 = BatchedUavEnv(_cfg(3, place_cell_m=12.0, scenario="no_move"), n_envs=2, seed=4)
    model = FieldModel(v8.n_rows, layout.episode_frames, layout.r_max_m, layout.half_width_m)

    def own_model() -> dict[str, np.ndarray]:
        sinr_db = v8.readings.heard_sinr_db.reshape(v8.n_rows, -1)
        return model.update(v8.uav_xy_m, sensed_value_bits(sinr_db))

    obs8, obs7 = v8.reset(), v7.reset()
    model.reset()
    picked = own_model()
    rng = np.random.default_rng(2)
    for _ in range(12):
        action = rng.uniform(-1, 1, (v8.n_rows, 2))
        obs8, obs7 = v8.step(action).observation, v7.step(action).observation
        picked = own_model()
    for field in v7.layout.fields:
        np.testing.assert_array_equal(
            v8.layout.history(obs8, field.quantity), v7.layout.history(obs7, field.quantity)
        )
    np.testing.assert_allclose(
        v8.layout.newest_frame(obs8)["place_pick_offset_m"],
        picked["place_pick_offset_m"],
        atol=1e-3,
    )


def test_a_pooled_model_of_the_field_makes_layout_v9_one_model_per_fleet_fed_by_every_uav() -> None:
    """``place_model = "pooled"``: v8's fields (the same size), one model per env into which every
    UAV of the env puts what it senses where it is, each frame in fleet order, and each UAV's pick
    made from that one posterior where it is."""
    pooled = {"place_cell_m": 12.0, "place_model": "pooled", "scenario": "no_move"}
    layouts = {ObservationLayout.for_config(_cfg(d, **pooled)) for d in (2, 3, 4)}
    assert len(layouts) == 1
    (layout,) = layouts
    v8 = ObservationLayout.for_config(_cfg(3, **(pooled | {"place_model": "kriging"})))
    assert layout.version == ANY_FLEET_POOLED_LAYOUT_VERSION and layout.size == v8.size
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    assert "place_model=pooled" in layout.describe()
    env = BatchedUavEnv(_cfg(3, **pooled), n_envs=2, seed=4)
    model = FieldModel(2, layout.episode_frames, layout.r_max_m, layout.half_width_m, sensors=3)

    def fleet_model() -> dict[str, np.ndarray]:
        value = sensed_value_bits(env.readings.heard_sinr_db.reshape(env.n_rows, -1)).reshape(2, 3)
        xy = env.uav_xy_m.reshape(2, 3, 2)
        for uav in range(3):
            model.observe(xy[:, uav], value[:, uav])
        return {"mean": model.mean.copy(), "var": model.var.copy()}

    obs = env.reset()
    model.reset()
    rng = np.random.default_rng(2)
    for _ in range(6):
        posterior = fleet_model()
        obs = env.step(rng.uniform(-1, 1, (env.n_rows, 2))).observation
    posterior = fleet_model()
    np.testing.assert_allclose(env._builder.field.mean, posterior["mean"], atol=1e-9)
    frame = env.layout.newest_frame(obs)
    pick_m = env.uav_xy_m + frame["place_pick_offset_m"]  # (6, 2): each UAV's own pick
    spot = np.linalg.norm(model.spots_m[None] - pick_m[:, None], axis=2).argmin(axis=1)
    std = np.sqrt(np.repeat(posterior["var"], 3, axis=0))  # each UAV's row of its fleet's model
    np.testing.assert_allclose(
        std[np.arange(6), spot], frame["place_pick_std_bits"].ravel(), atol=2e-3
    )
