"""The genie (SPEC "The limit, and a memory of place"): its DP is exact, its plan keeps the motion limits,
the env flies exactly the planned path, and the realised throughput is the planned one without fading.

Small worlds (a 120 m area, short episodes) keep these fast; research/genie_check.py runs the full
check against every baseline and shipped policy.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from support.cli import assert_user_error, run_uavlink_in_process

from uavlink.config import EnvConfig, RadioConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.evaluation import evaluate_policy
from uavlink.mobility.fleet import min_separation_m
from uavlink.policies.genie import GeniePolicy, fleet_mean_rate_bps
from uavlink.policies.genie.grid import Grid, MoveBox, best_grid_path, grid_rx_dbm
from uavlink.policies.genie.separation import merged_boxes
from uavlink.policies.registry import make_baseline
from uavlink.radio.cells import mean_channel_rate_bps
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
from uavlink.radio.spatial_shadowing import SpatialShadowField
from uavlink.rollout import chunks
from uavlink.seeding import EVAL


def small(scenario: str = "straight", **changes) -> EnvConfig:
    settings = {
        "area.half_width_m": 60.0,
        "episode_frames": 12,
        "radio.shadowing_model": "spatial",
        "radio.fast_fading": False,
        "fleet_start_radius_m": 30.0,
        **changes,
    }
    return EnvConfig(scenario=scenario).replace(**settings).validate()


def brute_force(
    reward: np.ndarray, grid: Grid, first: np.ndarray, allowed: np.ndarray | None
) -> float:
    best = -np.inf
    for start in zip(*np.nonzero(first), strict=True):
        for moves in itertools.product(range(len(grid.offsets)), repeat=len(reward) - 1):
            cell, total = np.array(start), reward[0][start]
            for t, k in enumerate(moves):
                if allowed is not None and not allowed[t, k, cell[0], cell[1]]:
                    break
                cell = cell + grid.offsets[k]
                if not ((cell >= 0) & (cell < grid.n)).all():
                    break
                total += reward[t + 1][tuple(cell)]
            else:
                best = max(best, total)
    return best


@pytest.mark.parametrize(
    "r_max_m,frames,masked", [(4.0, 4, False), (6.0, 3, False), (6.0, 3, True)]
)
def test_dp_is_exact_against_brute_force(r_max_m: float, frames: int, masked: bool) -> None:
    grid = Grid.over_area(8.0, 4.0, r_max_m)  # 5 x 5 cells; 5 or 9 moves
    rng = np.random.default_rng(int(r_max_m) * 10 + frames + masked)
    for _ in range(3):
        reward = rng.normal(size=(frames, grid.n, grid.n))
        reward[rng.random(reward.shape) < 0.1] = -np.inf  # forbidden cells
        allowed, boxes = None, None
        if masked:  # a random box of forbidden moves per frame, every move outside it allowed
            allowed = np.ones((frames - 1, len(grid.offsets), grid.n, grid.n), dtype=bool)
            boxes = []
            for t in range(frames - 1):
                row, col = rng.integers(0, grid.n - 1, 2)
                h, w = rng.integers(1, grid.n - row + 1), rng.integers(1, grid.n - col + 1)
                box = MoveBox(int(row), int(col), rng.random((len(grid.offsets), h, w)) > 0.3)
                allowed[t, :, row : row + h, col : col + w] = box.allowed
                boxes.append([box])
        first = grid.cells_within(np.array([0.0, 0.0]), r_max_m)
        path, value = best_grid_path(reward, grid, first, boxes)
        assert value == pytest.approx(brute_force(reward, grid, first, allowed))
        assert value == pytest.approx(sum(reward[t][tuple(c)] for t, c in enumerate(path)))
        if allowed is not None:  # every move of the path one the boxes allow
            moves = [
                list(map(tuple, grid.offsets)).index(tuple(b - a))
                for a, b in zip(path[:-1], path[1:], strict=True)
            ]
            assert all(
                allowed[t, k, a[0], a[1]]
                for t, (k, a) in enumerate(zip(moves, path[:-1], strict=True))
            )


def test_merged_boxes_are_disjoint_and_forbid_what_any_window_forbids() -> None:
    """Windows of allowed moves (some overlapping, some not) as the DP's boxes: the boxes do not
    overlap, and a move is allowed from a cell exactly where every window holding the cell allows it
    (every move from a cell outside all windows)."""
    rng, n, k, w = np.random.default_rng(5), 30, 4, 6
    for _ in range(50):
        windows = int(rng.integers(1, 4))
        rows, cols = (
            rng.integers(0, n - w, windows).tolist(),
            rng.integers(0, n - w, windows).tolist(),
        )
        allowed = rng.random((windows, k, w, w)) > 0.2
        want = np.ones((k, n, n), dtype=bool)
        for r, c, one in zip(rows, cols, allowed, strict=True):
            want[:, r : r + w, c : c + w] &= one
        got, covered = np.ones((k, n, n), dtype=bool), np.zeros((n, n), dtype=int)
        for box in merged_boxes(rows, cols, allowed):
            h, v = box.allowed.shape[1:]
            got[:, box.row : box.row + h, box.col : box.col + v] = box.allowed
            covered[box.row : box.row + h, box.col : box.col + v] += 1
            cell = np.array([box.row + h - 1, box.col])
            np.testing.assert_array_equal(box.at(cell), want[:, cell[0], cell[1]])
            assert box.at(np.array([box.row + h, box.col])) is None  # just outside
        assert covered.max() == 1
        np.testing.assert_array_equal(got, want)


def test_grid_offsets_are_the_reachable_moves() -> None:
    grid = Grid.over_area(200.0, 4.0, 12.0)
    assert grid.n == 101 and grid.spacing_m == pytest.approx(4.0)
    assert tuple(grid.offsets[0]) == (0, 0) and len(grid.offsets) == 29  # |(i, j)| <= 3
    assert (np.hypot(*grid.offsets.T) * grid.spacing_m <= 12.0 + 1e-9).all()


def test_grid_powers_are_the_envs() -> None:
    """The planner's float32 path loss and matrix-product field against the env's own functions."""
    radio, grid = RadioConfig(shadowing_model="spatial"), Grid.over_area(60.0, 4.0, 12.0)
    rng = np.random.default_rng(1)
    field = SpatialShadowField.draw(rng, 1, radio)
    ue = rng.uniform(-60, 60, (3, 4, 2))
    rx = grid_rx_dbm(grid, ue, field, radio, 95.0)
    cells = rng.integers(0, grid.n, (20, 2))
    for ix, iy in cells:
        uav = np.broadcast_to(grid.points_m(np.array([ix, iy])), (3, 1, 2))
        want = mean_rx_power_dbm(distance_3d_m(uav, ue, 95.0), radio)[..., 0]
        one = SpatialShadowField(
            *(
                np.broadcast_to(a, (3, *a.shape[1:]))
                for a in (field.ue_wave_per_m, field.uav_wave_per_m, field.phase_rad)
            ),
            field.amplitude_db,
        )
        want = want + one.shadow_db(uav, ue)[..., 0]
        np.testing.assert_allclose(rx[:, :, ix, iy], want, atol=2e-3)


@pytest.mark.parametrize(
    "n_uavs,reuse", [(2, "full"), (3, "full"), (2, "orthogonal"), (2, "listen"), (4, "listen")]
)
def test_fleet_mean_rates_are_the_mean_channel_rates(n_uavs: int, reuse: str) -> None:
    rng, radio = np.random.default_rng(n_uavs), RadioConfig()
    mine, others = rng.uniform(-90, -60, (3, 10, 40)), rng.uniform(-90, -60, (3, 10, n_uavs - 1))
    rx = np.concatenate(
        [mine.transpose(0, 2, 1)[..., None], np.repeat(others[:, None], 40, axis=1)], axis=-1
    )
    want = mean_channel_rate_bps(rx, radio, reuse).mean(axis=-1)  # (T, G)
    got = fleet_mean_rate_bps(
        (10 ** (mine / 10)).astype(np.float32),
        (10 ** (others / 10)).astype(np.float32),
        radio,
        reuse,
    )
    np.testing.assert_allclose(got, want, rtol=1e-5)


def fly(cfg: EnvConfig, episodes: int, seed: int = 0) -> tuple[GeniePolicy, np.ndarray, np.ndarray]:
    """The genie over ``episodes``: its plan, the path the env flew (T + 1, N, D, 2) and the rates."""
    genie = make_baseline("genie", cfg)
    [chunk] = list(chunks(cfg, EVAL, episodes, seed))
    flown, rates = [chunk.env.uav_xy_m.reshape(episodes, cfg.n_uavs, 2).copy()], []
    for frame in chunk.frames(genie):
        flown.append(frame.env.uav_xy_m.reshape(episodes, cfg.n_uavs, 2).copy())
        rates.append(frame.result.mean_rate_mbps)
    return genie, np.array(flown), np.array(rates).mean(axis=0)


@pytest.mark.parametrize(
    "scenario,mapping",
    [("straight", "cartesian-v1"), ("circular", "polar-v1"), ("hotspot", "cartesian-v1")],
)
def test_one_uav_flies_its_plan_within_the_limits(scenario: str, mapping: str) -> None:
    cfg = small(scenario, action_mapping=mapping)
    genie, flown, rates = fly(cfg, 3)
    np.testing.assert_allclose(flown, genie.path_m, atol=1e-6)  # the env flew the planned path
    step = np.linalg.norm(np.diff(genie.path_m, axis=0), axis=-1)
    assert (step <= cfg.r_max_m + 1e-9).all() and (np.abs(genie.path_m) <= 60.0).all()
    np.testing.assert_array_equal(genie.path_m[0], 0.0)  # from the start
    # no fading: realised = planned, to summation order (numpy 2.4 sums the two in orders 2e-9 apart)
    np.testing.assert_allclose(rates, genie.planned_rate_mbps, rtol=1e-8)


@pytest.mark.slow
def test_plan_beats_the_gps_baselines_and_uses_the_field() -> None:
    """On the spatial channel the plan's expected throughput is at least every replayed baseline's,
    and well above the oracle's (which ignores shadowing)."""
    cfg = small("no_move", episode_frames=16)
    genie, _, rates = fly(cfg, 4)
    for name in ("static", "oracle", "kmeans", "aoa"):
        other = evaluate_policy(make_baseline(name, cfg), cfg, 4, 0).episode_rate_mbps
        assert (rates >= other - 1e-9).all(), name
    assert (
        rates.mean() > 1.1 * evaluate_policy(make_baseline("oracle", cfg), cfg, 4, 0).mean_rate_mbps
    )


def test_ar1_plans_on_the_mean_channel() -> None:
    cfg = small("circular", **{"radio.shadowing_model": "ar1"})
    env = BatchedUavEnv(cfg, 2, seed=0)
    env.reset()
    assert env.ground_truth().shadow_field is None
    genie, flown, _ = fly(cfg, 2)
    np.testing.assert_allclose(flown, genie.path_m, atol=1e-6)


@pytest.mark.slow
def test_fleet_flies_its_plan_apart() -> None:
    cfg = small("straight_180", n_uavs=2)
    genie, flown, rates = fly(cfg, 2)
    np.testing.assert_allclose(
        flown, genie.path_m, atol=1e-6
    )  # the separation filter never cut a move
    assert (min_separation_m(flown.reshape(-1, 2, 2)) >= cfg.uav_separation_m).all()
    assert (np.linalg.norm(np.diff(genie.path_m, axis=0), axis=-1) <= cfg.r_max_m + 1e-9).all()
    np.testing.assert_allclose(rates, genie.planned_rate_mbps, rtol=1e-9)
    for name in ("static", "oracle", "kmeans"):
        assert (
            rates >= evaluate_policy(make_baseline(name, cfg), cfg, 2, 0).episode_rate_mbps - 1e-9
        ).all()


def test_one_genie_plans_each_batch_of_an_evaluation_afresh() -> None:
    """An evaluation flies batch after batch with one policy, and every episode starts at the centre,
    where the last batch's plan began: the genie flies each batch on its own plan (it flew the first
    batch's plan again, level with static over 1,000 no_move episodes)."""
    cfg = small("no_move")
    genie = make_baseline("genie", cfg)
    flown = []
    for seed in (0, 1):  # two batches, as evaluate_policy's chunks
        [chunk] = list(chunks(cfg, EVAL, 2, seed))
        flown.append(
            np.mean([frame.result.mean_rate_mbps for frame in chunk.frames(genie)], axis=0)
        )
    _, _, fresh = fly(cfg, 2, seed=1)  # a genie that met only the second batch
    np.testing.assert_allclose(flown[1], fresh, rtol=1e-9)
    assert not np.allclose(flown[0], flown[1])


def test_episodes_planned_side_by_side_are_the_ones_planned_in_turn() -> None:
    """Threads plan a batch's episodes (numpy releases the GIL); the plans are the serial ones."""
    cfg = small("circular", n_uavs=2, episode_frames=8)
    [chunk] = list(chunks(cfg, EVAL, 5, 0))
    truth = chunk.env.ground_truth()
    plans = []
    for workers in (1, 2):
        genie = make_baseline("genie", cfg)
        genie.workers = workers
        genie.plan(truth)
        plans.append((genie.path_m, genie.planned_rate_mbps))
    np.testing.assert_array_equal(plans[0][0], plans[1][0])
    np.testing.assert_array_equal(plans[0][1], plans[1][1])


@pytest.mark.slow
def test_fly_and_export_refuse_the_genie() -> None:
    assert_user_error(run_uavlink_in_process("export", "genie"), "genie", "nothing to export")
    assert_user_error(run_uavlink_in_process("fly", "--policy", "genie"), "genie", "cannot fly")
