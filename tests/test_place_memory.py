"""The memory of place (uavlink/env/place_memory.py), its layout v3 / v4, and the explore rule."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support.cli import ROOT, cli_json

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import ObservationLayout
from uavlink.env.observation_builder import ObservationBuilder
from uavlink.env.place_memory import (
    HYSTERESIS_BITS,
    STALE_BITS_PER_FRAME,
    PlaceMemory,
    sensed_value_bits,
)
from uavlink.errors import UserError
from uavlink.evaluation import evaluate_policy
from uavlink.policies.explore import ExplorePolicy
from uavlink.policies.registry import baseline_env, make_baseline

SPATIAL = EnvConfig(scenario="no_move").replace(**{"radio.shadowing_model": "spatial"})
PLACE = SPATIAL.replace(place_cell_m=12.0)
SHIPPED = (".zip", ".onnx", ".json")  # a shipped policy's files: the zip runs as its ONNX twin


def test_best_cell_is_ranked_first_up_to_the_hysteresis_over_a_random_walk() -> None:
    rng = np.random.default_rng(0)
    memory = PlaceMemory(20.0, 100.0, n_rows=5)
    xy = np.zeros((5, 2))
    seen: list[dict] = [{} for _ in range(5)]  # cell -> (value, frame)
    for t in range(60):
        xy = np.clip(xy + rng.uniform(-25, 25, (5, 2)), -100, 100)
        sinr = rng.normal(10, 8, (5, 3))
        q = memory.update(xy, sinr)
        now = sensed_value_bits(sinr)
        for row in range(5):
            i, j = np.minimum(((xy[row] + 100) // 20).astype(int), 9)
            seen[row][(i, j)] = (now[row], t)
            centre = q["place_best_offset_m"][row] + xy[row]
            cell = tuple(((centre + 100) // 20).astype(int))
            value, frame = seen[row][cell]  # a cell sensed, reported as sensed
            assert q["place_best_gain_bits"][row] == pytest.approx(value - now[row])
            assert q["place_best_age_frames"][row] == t - frame
            # ranked first, up to the hysteresis
            top = max(v + STALE_BITS_PER_FRAME * f for v, f in seen[row].values())
            assert value + STALE_BITS_PER_FRAME * frame >= top - HYSTERESIS_BITS - 1e-9
        assert (q["place_frames"] == t + 1).all()


def test_neighbours_report_what_was_sensed_next_door_and_reset_forgets() -> None:
    memory = PlaceMemory(10.0, 50.0, n_rows=1)
    memory.update(np.array([[15.0, 5.0]]), np.array([[20.0]]))  # the cell east of (5, 5)
    q = memory.update(np.array([[5.0, 5.0]]), np.array([[0.0]]))
    assert q["place_neighbour_known"].tolist() == [[1.0, 0.0, 0.0, 0.0]]
    assert q["place_neighbour_gain_bits"][0, 0] == pytest.approx(np.log2(101.0) - 1.0)
    assert q["place_best_offset_m"].tolist() == [[10.0, 0.0]]
    memory.reset()
    q = memory.update(np.array([[5.0, 5.0]]), np.array([[0.0]]))
    assert q["place_neighbour_known"].sum() == 0 and q["place_best_gain_bits"][0] == 0.0
    assert q["place_frames"][0] == 1


def test_a_spot_revisited_reads_what_it_read_before_on_the_spatial_channel() -> None:
    """No UE moves on no_move and the shadowing is a map: back at the start, the value remembered
    there is what the UAV senses again (up to the fast fading)."""
    env = BatchedUavEnv(PLACE, n_envs=8, seed=3)
    env.reset()
    east, west = np.tile([1.0, 0.0], (8, 1)), np.tile([-1.0, 0.0], (8, 1))
    for action in (east, east, west, west):
        obs = env.step(action).observation
    frame = env.layout.newest_frame(obs)
    assert np.allclose(frame["uav_xy_m"], 0.0, atol=1e-4)
    # the best spot is one of the three visited, and the start cell was just overwritten with now
    assert set(np.round(np.abs(frame["place_best_offset_m"][:, 0]) / 12).astype(int)) <= {0, 1, 2}


def test_layout_v3_and_v4_and_old_records_unchanged() -> None:
    old = ObservationLayout.for_config(SPATIAL)
    assert old.version == 1 and "place_cell_m" not in old.to_dict() and old.size == 4 * 15
    v3 = ObservationLayout.for_config(PLACE)
    assert v3.version == 3 and v3.frame_size == old.frame_size + 13
    assert ObservationLayout.from_dict(json.loads(json.dumps(v3.to_dict()))) == v3
    assert ObservationLayout.for_config(PLACE.replace(n_uavs=2)).version == 4
    assert any(name.endswith("place_best_gain") for name in v3.feature_names())
    low, high = v3.bounds()
    obs = BatchedUavEnv(PLACE, n_envs=4, seed=0).reset()
    assert obs.shape == (4, v3.size) and (obs >= low).all() and (obs <= high).all()
    with pytest.raises(UserError, match="layout mismatch"):
        old.check_matches(v3)


def test_env_and_builder_fed_the_same_readings_agree() -> None:
    """The flight loop builds the observation with ObservationBuilder from position and radio
    reports; fed the env's readings it reproduces the env's observations, memory included."""
    env = BatchedUavEnv(PLACE, n_envs=1, seed=1)
    builder = ObservationBuilder(env.layout, 1)
    obs = env.reset()
    mine = builder.reset(**env._sensed())
    assert np.array_equal(obs, mine)
    rng = np.random.default_rng(0)
    for _ in range(30):
        obs = env.step(rng.uniform(-1, 1, (1, 2))).observation
        assert np.array_equal(obs, builder.push(**env._sensed()))


def test_explore_is_a_baseline_with_its_own_memory_env() -> None:
    assert baseline_env("explore", SPATIAL).place_cell_m == 12.0
    assert baseline_env("explore", PLACE.replace(place_cell_m=8.0)).place_cell_m == 8.0
    assert baseline_env("aoa", SPATIAL) == SPATIAL
    with pytest.raises(UserError, match="memory of place"):
        ExplorePolicy(SPATIAL)
    policy = make_baseline("explore", SPATIAL)
    assert policy.layout == ObservationLayout.for_config(PLACE) and not policy.needs_truth


def test_explore_searches_a_cross_then_returns_to_the_best_spot() -> None:
    policy = make_baseline("explore", SPATIAL)
    env = BatchedUavEnv(PLACE, n_envs=6, seed=2)
    obs = env.reset()
    path = []
    for _ in range(60):
        obs = env.step(policy.act(obs)).observation
        path.append(env.uav_xy_m.copy())
    path = np.array(path)
    xs = path[..., 0]
    assert np.allclose(path[3], [48.0, 0.0], atol=1e-3) and np.allclose(
        path[11], [-48.0, 0.0], atol=1e-3
    )
    assert np.allclose(path[19], [0.0, 48.0], atol=1e-3) and np.allclose(
        path[27], [0.0, -48.0], atol=1e-3
    )
    assert np.allclose(path[31], 0.0, atol=1e-3)
    assert np.allclose(path[:16, :, 1], 0.0, atol=1e-3) and np.allclose(
        path[16:32, :, 0], 0.0, atol=1e-3
    )
    # after the search most hover at the best spot they sensed (the no_move team stays put; a spot
    # that reads less on return than remembered sends the UAV on to the next best)
    hovering = np.isclose(xs[-1], xs[-2], atol=1e-3)
    assert hovering.sum() >= 4
    frame = env.layout.newest_frame(obs)
    assert (np.abs(frame["place_best_offset_m"][hovering]) <= 6.0 + 1e-6).all()


@pytest.mark.slow
def test_explore_beats_hovering_on_no_move_and_flies_a_fleet() -> None:
    explore = evaluate_policy(make_baseline("explore", SPATIAL), PLACE, 8, 0).mean_rate_mbps
    static = evaluate_policy(make_baseline("static", SPATIAL), SPATIAL, 8, 0).mean_rate_mbps
    assert explore > 1.05 * static
    fleet = SPATIAL.replace(n_uavs=2, scenario="straight_180")
    policy = make_baseline("explore", fleet)
    assert policy.layout.version == 4
    result = evaluate_policy(policy, baseline_env("explore", fleet), 2, 0, record_trajectory=True)
    # each UAV searches its own cross: both fly its 48 m arms from their starts
    reach_m = np.abs(result.trajectory.uav_xy_m - result.trajectory.uav_xy_m[0]).max(axis=(0, 2))
    assert reach_m.shape == (2,) and (reach_m >= 40.0).all(), reach_m


def test_evaluate_explore_from_the_command_line() -> None:
    out = cli_json(
        "evaluate",
        "--policy",
        "explore",
        "--scenario",
        "no_move",
        "--set",
        "radio.shadowing_model=spatial",
        "--episodes",
        "2",
        "--json",
    )
    assert out["policy"] == "explore" and out["episodes"] == 2


def test_shipped_policies_keep_their_layouts() -> None:
    for manifest in sorted(Path(ROOT, "policies").glob("**/*.json")):
        data = json.loads(manifest.read_text())
        if "observation_layout" in data and "env_config" in data:
            layout = ObservationLayout.from_dict(data["observation_layout"])
            cfg = EnvConfig.from_dict(data["env_config"])
            assert ObservationLayout.for_config(cfg) == layout, manifest
            if cfg.place_cell_m == 0:  # v1, v2 or the any-size fleet's v6: no memory of place
                assert (
                    layout.version in (1, 2, 6) and "place_cell_m" not in data["observation_layout"]
                )


def test_map_report_refuses_without_spatial_and_skips_untrained_scenarios(tmp_path: Path) -> None:
    from support.cli import run_uavlink_in_process

    from uavlink.evaluation.report_map import map_table
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides

    proc = run_uavlink_in_process(
        "evaluate",
        "--scenario",
        "all",
        "--policy",
        str(ROOT / "policies"),
        "--out",
        str(tmp_path / "out"),
        "--map",
        str(tmp_path),
    )
    assert proc.returncode == 2 and "--map" in proc.stderr and "--spatial" in proc.stderr
    assert not (tmp_path / "out").exists()
    header, body = map_table(
        tmp_path, ROOT / "policies" / "spatial", 1, 0, EnvOverrides(), policy_teacher
    )
    assert body == [] and header[:3] == ["scenario", "map PPO", "spatial PPO"]


@pytest.mark.slow
def test_map_report_rows_put_each_map_policy_beside_explore_and_the_genie(tmp_path: Path) -> None:
    """One row per scenario a shipped map policy flies (and mixed's), with the genie's column and the shares of it (the genie is
    the limit: its episode is at least the map policy's and the spatial policy's)."""
    from uavlink.evaluation.report_map import map_table
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides

    header, body = map_table(  # one episode a scenario: the genie's plan is most of the cost
        ROOT / "policies" / "map",
        ROOT / "policies" / "spatial",
        1,
        0,
        EnvOverrides(),
        policy_teacher,
    )
    from uavlink.config import MIXED, SCENARIO_NAMES

    shipped = {p.stem for p in (ROOT / "policies" / "map").glob("*.zip")}
    # a scenario without its own map policy is flown by the mixed one, if shipped
    assert [row[0] for row in body] == [
        s for s in SCENARIO_NAMES if s in shipped or MIXED in shipped
    ]
    col = {name: i for i, name in enumerate(header)}
    # each map policy beside the teacher it copied, knobs and all (not only the rule's name)
    teachers = {row[0]: row[col["map vs its teacher"]] for row in body}
    assert teachers["no_move"].startswith("kriging: ") and teachers["straight_90"].startswith(
        "aoa (span 3, gate 2): "
    )
    for row in body:
        mbps = {
            name: float(row[col[name]].split(" ± ")[0])
            for name in ("map PPO", "spatial PPO", "genie")
        }
        assert mbps["genie"] >= max(mbps["map PPO"], mbps["spatial PPO"]), row
        for share in ("map / genie", "spatial / genie"):
            assert 0 < float(row[col[share]].split(" %")[0]) <= 100, row
    # without the genie: the same cells for the rest (the same episodes), and no genie column (on two
    # of the policies: the rows do not depend on each other)
    import shutil

    for name in [f"{stem}{suffix}" for stem in ("no_move", "circular") for suffix in SHIPPED]:
        shutil.copy(ROOT / "policies" / "map" / name, tmp_path)
    header_lean, body_lean = map_table(
        tmp_path,
        ROOT / "policies" / "spatial",
        1,
        0,
        EnvOverrides(),
        policy_teacher,
        with_genie=False,
    )
    assert "genie" not in " ".join(header_lean) and [row[0] for row in body_lean] == [
        "no_move",
        "circular",
    ]
    lean = {name: i for i, name in enumerate(header_lean)}
    for row_lean in body_lean:
        row = next(r for r in body if r[0] == row_lean[0])
        assert all(row[col[name]] == row_lean[lean[name]] for name in header_lean), (row, row_lean)


@pytest.mark.slow
def test_place_map_holds_the_cells_flown_over_the_fields_truth(tmp_path: Path) -> None:
    """uavlink.evaluation.place_map on circular's map policy, episode 0 of seed 0: the episode is
    evaluate's, the memory holds exactly the cells the UAV was in (its best among them), and the
    truth at a spot is the env's mean-channel rate for a UAV there (the radio code, not the genie's
    float32 grid)."""
    from uavlink.evaluation.place_map import draw_place_map, fly_place_map
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.radio import distance_3d_m, mean_rx_power_dbm
    from uavlink.radio.cells import mean_channel_rate_bps

    [(policy, cfg)] = load_with_env(
        [str(ROOT / "policies" / "map" / "circular.zip")],
        EnvOverrides.from_command_line("circular", None, []),
    )
    episode = fly_place_map(policy, cfg, 0)
    assert episode.mean_rate_mbps == evaluate_policy(policy, cfg, 1, 0).mean_rate_mbps
    assert len(episode.uav_path_m) == cfg.episode_frames + 1
    half, cell = episode.half_width_m, episode.cell_m
    side = episode.memory_mbps.shape[0]
    visited = {
        tuple(np.clip(np.floor((xy + half) / cell), 0, side - 1).astype(int))
        for xy in episode.uav_path_m
    }
    assert {tuple(ij) for ij in np.argwhere(np.isfinite(episode.memory_mbps))} == visited
    assert tuple(np.floor((episode.best_m + half) / cell).astype(int)) in visited
    for ix, iy in np.random.default_rng(0).integers(0, len(episode.field_x_m), size=(3, 2)):
        uav, ue = (
            np.array([[[episode.field_x_m[ix], episode.field_x_m[iy]]]]),
            episode.ue_xy_m[None],
        )
        rx_dbm = mean_rx_power_dbm(distance_3d_m(uav, ue, cfg.area.uav_altitude_m), cfg.radio)
        rx_dbm = rx_dbm + episode.shadow_field.shadow_db(uav, ue)
        assert episode.field_mbps[ix, iy] == pytest.approx(
            mean_channel_rate_bps(rx_dbm, cfg.radio).mean() * 1e-6, rel=2e-3
        )
    draw_place_map(episode, tmp_path / "map.png")
    assert (tmp_path / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_map_sections_draw_a_place_map_per_scenario_with_a_map_policy(tmp_path: Path) -> None:
    """The report's map part with one map policy (no_move): its row, its picture linked as the
    Markdown sees the output folder, and the sensitivity table's six
    channels for it (circular has no map policy here, so no rows)."""
    import shutil

    from uavlink.evaluation.report_map import map_sections
    from uavlink.evaluation.tables import ReportRun
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides

    folder = tmp_path / "map"
    folder.mkdir()
    for suffix in SHIPPED:
        shutil.copy(ROOT / "policies" / "map" / f"no_move{suffix}", folder)
    out = tmp_path / "out"
    out.mkdir()
    run = ReportRun(1, 0, EnvOverrides(), out, out.parent / "results.md")  # links out as "out/..."
    markdown = "\n".join(
        map_sections(run, folder, ROOT / "policies" / "spatial", [], policy_teacher)
    )
    assert [row.split(",")[0] for row in (out / "map.csv").read_text().splitlines()[1:]] == [
        "no_move"
    ]
    assert (out / "place_map_no_move.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "](out/place_map_no_move.png)" in markdown  # linked from the Markdown's folder
    channels = [
        line.split(" | ")[1:3]
        for line in markdown.splitlines()
        if line.startswith("| no_move | ") and line.count(" | ") == 7
    ]
    assert channels == [[s, d] for s in ("4", "8") for d in ("25", "50", "100")]
