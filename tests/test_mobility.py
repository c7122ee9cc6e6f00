"""UE mobility scenarios (SPEC "UE mobility scenarios" and "Scenario geometry")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.mobility import (
    MIXED,
    SCENARIOS,
    MobilityState,
    draw_scenarios,
    init_mobility,
    scenario_index,
    step_mobility,
)

CFG = EnvConfig()
HALF = CFG.area.half_width_m  # 200 m
SPEED = CFG.ue_speed_mps  # 8 m/s
N_ENVS = 256


def start(name: str, n_envs: int = N_ENVS, seed: int = 0, cfg: EnvConfig = CFG) -> MobilityState:
    return init_mobility(np.random.default_rng(seed), draw_scenarios(None, name, n_envs), cfg)


def run(state: MobilityState, frames: int = 128) -> list[np.ndarray]:
    """Positions at every frame, the start included."""
    positions = [state.position_m.copy()]
    for _ in range(frames):
        step_mobility(state, 1.0, HALF)
        positions.append(state.position_m.copy())
    return positions


def linear_state(position, velocity) -> MobilityState:
    """One env of hand-placed linear movers."""
    position = np.asarray(position, float)[None]
    n_ues = position.shape[1]
    return MobilityState(
        position_m=position,
        velocity_mps=np.asarray(velocity, float)[None],
        orbiting=np.zeros(1, bool),
        orbit_angle_rad=np.zeros(1),
        orbit_radius_m=np.ones(1),
        orbit_rate_rad_s=np.zeros(1),
        orbit_offset_m=np.zeros((1, n_ues, 2)),
    )


def speeds(state: MobilityState) -> np.ndarray:
    return np.linalg.norm(state.velocity_mps, axis=-1)


def heading_deg(velocity: np.ndarray) -> np.ndarray:
    return np.degrees(np.arctan2(velocity[..., 1], velocity[..., 0]))


# --- reflection at the walls -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("position", "velocity", "mirrored", "flipped"),
    [
        ((197.0, 10.0), (8.0, 0.0), (195.0, 10.0), (-8.0, 0.0)),  # east wall: 205 -> 195
        ((-197.0, 10.0), (-8.0, 0.0), (-195.0, 10.0), (8.0, 0.0)),  # west wall
        ((10.0, 199.0), (0.0, 8.0), (10.0, 193.0), (0.0, -8.0)),  # north wall: 207 -> 193
        ((10.0, -196.0), (0.0, -8.0), (10.0, -196.0), (0.0, 8.0)),  # south wall: -204 -> -196
    ],
)
def test_reflection_at_each_wall(position, velocity, mirrored, flipped):
    state = linear_state([position], [velocity])
    step_mobility(state, 1.0, HALF)
    np.testing.assert_allclose(state.position_m[0, 0], mirrored, atol=1e-12)
    np.testing.assert_allclose(state.velocity_mps[0, 0], flipped, atol=1e-12)


def test_reflection_flips_only_the_component_that_hit():
    state = linear_state([(196.0, 0.0)], [(6.0, 2.0)])  # hits the east wall going north-east
    step_mobility(state, 1.0, HALF)
    np.testing.assert_allclose(state.position_m[0, 0], (198.0, 2.0), atol=1e-12)
    np.testing.assert_allclose(state.velocity_mps[0, 0], (-6.0, 2.0), atol=1e-12)
    # Into a corner: both components flip.
    corner = linear_state([(198.0, -198.0)], [(4.0, -4.0)])
    step_mobility(corner, 1.0, HALF)
    np.testing.assert_allclose(corner.position_m[0, 0], (198.0, -198.0), atol=1e-12)
    np.testing.assert_allclose(corner.velocity_mps[0, 0], (-4.0, 4.0), atol=1e-12)


def test_no_reflection_away_from_walls():
    state = linear_state([(0.0, 0.0)], [(SPEED, 0.0)])
    step_mobility(state, 1.0, HALF)
    np.testing.assert_allclose(state.position_m[0, 0], (8.0, 0.0))
    np.testing.assert_allclose(state.velocity_mps[0, 0], (8.0, 0.0))


# --- per-scenario definitions ------------------------------------------------------------------


def test_scenario_names_and_index():
    assert SCENARIOS == (
        "no_move",
        "straight",
        "circular",
        "straight_90",
        "straight_180",
        "hotspot",
    )
    assert scenario_index("circular") == 2
    with pytest.raises(ValueError, match="unknown scenario 'zigzag'"):
        scenario_index("zigzag")
    with pytest.raises(ValueError, match="unknown scenario"):
        draw_scenarios(np.random.default_rng(0), "zigzag", 4)


def test_mixed_draws_every_scenario():
    ids = draw_scenarios(np.random.default_rng(0), MIXED, 6000)
    counts = np.bincount(ids, minlength=len(SCENARIOS))
    assert len(counts) == len(SCENARIOS)
    assert np.all(np.abs(counts - 1000) < 120)  # uniform over the six


def test_no_move_is_one_static_cluster_at_the_centre():
    state = start("no_move")
    positions = run(state, 10)
    assert np.all(np.abs(positions[0]) <= CFG.cluster_size_m / 2)
    assert np.all(speeds(state) == 0.0)
    np.testing.assert_array_equal(positions[-1], positions[0])


def test_straight_cluster_moves_together_at_8_mps_in_a_random_direction():
    state = start("straight")
    assert np.all(np.abs(state.position_m) <= CFG.cluster_size_m / 2)  # starts at the centre
    np.testing.assert_allclose(speeds(state), SPEED)
    # All UEs of an env share the velocity; directions are uniform over the envs.
    np.testing.assert_allclose(state.velocity_mps, state.velocity_mps[:, :1].repeat(10, axis=1))
    direction = np.radians(heading_deg(state.velocity_mps[:, 0]))
    assert abs(np.mean(np.exp(1j * direction))) < 0.15  # no preferred direction
    first = state.position_m.copy()
    step_mobility(state, 1.0, HALF)
    np.testing.assert_allclose(np.linalg.norm(state.position_m - first, axis=-1), SPEED)
    # Linear movers keep their speed through reflections for a whole episode.
    run(state, 127)
    np.testing.assert_allclose(speeds(state), SPEED)


@pytest.mark.parametrize(("name", "gap_deg"), [("straight_90", 90.0), ("straight_180", 180.0)])
def test_two_clusters_split_at_the_right_angle(name, gap_deg):
    state = start(name)
    assert np.all(np.abs(state.position_m) <= CFG.cluster_size_m / 2)  # both start at the centre
    np.testing.assert_allclose(speeds(state), SPEED)
    a, b = state.velocity_mps[:, :5], state.velocity_mps[:, 5:]
    np.testing.assert_allclose(a, a[:, :1].repeat(5, axis=1))  # clusters of 5 move together
    np.testing.assert_allclose(b, b[:, :1].repeat(5, axis=1))
    gap = np.abs(((heading_deg(b[:, 0]) - heading_deg(a[:, 0])) + 180.0) % 360.0 - 180.0)
    np.testing.assert_allclose(gap, gap_deg, atol=1e-9)
    base = np.radians(heading_deg(a[:, 0]))
    assert abs(np.mean(np.exp(1j * base))) < 0.15  # random base direction


def test_circular_cluster_starts_at_the_bottom_and_orbits_at_8_mps():
    state = start("circular")
    x, y = state.position_m[..., 0], state.position_m[..., 1]
    assert np.all((x >= 0.0) & (x <= 10.0)) and np.all((y >= -HALF) & (y <= -HALF + 10.0))
    np.testing.assert_allclose(speeds(state), SPEED)
    radius = math.hypot(5.0, 195.0)  # the start square's centre, ~195 m from the origin
    np.testing.assert_allclose(state.orbit_radius_m, radius)
    pairwise0 = np.linalg.norm(state.position_m[:, :, None] - state.position_m[:, None], axis=-1)
    positions = run(state)
    for pos in positions:
        # Rigid translation: the cluster keeps its shape ...
        pairwise = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
        np.testing.assert_allclose(pairwise, pairwise0, atol=1e-9)
        # ... and its centre stays on the ~195 m circle round the origin.
        centre = pos - state.orbit_offset_m
        np.testing.assert_allclose(np.linalg.norm(centre, axis=-1), radius, rtol=1e-12)
        centroid = np.linalg.norm(pos.mean(axis=1), axis=-1)
        assert np.all(np.abs(centroid - radius) <= CFG.cluster_size_m / 2 * math.sqrt(2))
    # 8 m/s along the arc: 128 s later it has turned 8 * 128 / r radians, counter-clockwise.
    step = np.linalg.norm(positions[1] - positions[0], axis=-1)
    np.testing.assert_allclose(step, 2 * radius * math.sin(SPEED / radius / 2), rtol=1e-9)
    turned = np.unwrap([np.arctan2(*(p - state.orbit_offset_m)[0, 0, ::-1]) for p in positions])
    assert turned[-1] - turned[0] == pytest.approx(SPEED * 128 / radius, rel=1e-9)
    assert np.all(np.diff(turned) > 0)  # counter-clockwise


def test_hotspot_cluster_plus_independent_ues():
    state = start("hotspot", n_envs=2000)
    spd = speeds(state)
    assert np.all((spd >= 0.0) & (spd <= SPEED))
    assert spd[:, 5:].mean() == pytest.approx(SPEED / 2, abs=0.2)  # uniform in [0, 8]
    cluster = state.position_m[:, :5]
    spread = cluster.max(axis=1) - cluster.min(axis=1)
    assert np.all(spread <= CFG.cluster_size_m)  # the five in a 10 m square ...
    np.testing.assert_allclose(
        state.velocity_mps[:, :5], state.velocity_mps[:, :1].repeat(5, axis=1)
    )  # ... moving together
    free = state.position_m[:, 5:]
    assert np.all(np.abs(free) <= HALF)
    assert free.std() == pytest.approx(2 * HALF / math.sqrt(12), rel=0.05)  # uniform in the area
    # The independent UEs have their own velocities.
    assert not np.allclose(state.velocity_mps[:, 5], state.velocity_mps[:, 6])
    run(state)
    assert np.all(speeds(state) <= SPEED + 1e-9)


@pytest.mark.parametrize("name", SCENARIOS)
def test_ues_always_inside_the_area(name):
    state = start(name, seed=1)
    positions = np.stack(run(state))
    # The circular cluster's square starts flush with the south wall but its centre is at
    # hypot(5, 195) = 195.06 m, so a corner UE can stand up to 6.4 cm past a wall when the cluster
    # is due east/north/west/south; every other scenario reflects exactly at the wall.
    slack = math.hypot(5.0, 195.0) + CFG.cluster_size_m / 2 - HALF if name == "circular" else 0.0
    assert slack < 0.07
    assert np.abs(positions).max() <= HALF + slack + 1e-9


def test_same_seed_same_trajectories_different_seed_different():
    a = np.stack(run(start("hotspot", 8, seed=3), 20))
    b = np.stack(run(start("hotspot", 8, seed=3), 20))
    c = np.stack(run(start("hotspot", 8, seed=4), 20))
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


def test_mixed_batch_runs_each_env_by_its_own_scenario():
    cfg = EnvConfig(scenario=MIXED)
    ids = np.arange(len(SCENARIOS)).repeat(4)
    state = init_mobility(np.random.default_rng(0), ids, cfg)
    static = ids == scenario_index("no_move")
    assert np.all(speeds(state)[static] == 0.0)
    assert np.all(state.orbiting == (ids == scenario_index("circular")))
    moving = np.isin(ids, [scenario_index(s) for s in ("straight", "straight_90", "straight_180")])
    np.testing.assert_allclose(speeds(state)[moving], SPEED)
