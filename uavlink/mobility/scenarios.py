"""The six UE mobility scenarios of the paper (SPEC "UE mobility scenarios"), batched over envs.

A cluster is a ``cluster_size_m`` square (10 m) whose UEs are uniform inside it and share one
velocity. Linear movers reflect off the area boundary; the circular cluster translates rigidly along
a circle round the origin, counter-clockwise, so it keeps its shape. ``mixed`` draws a scenario per
environment at every reset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import MIXED, SCENARIOS, EnvConfig


@dataclass
class MobilityState:
    """UE kinematics for N envs and U UEs (metres, m/s, env frame)."""

    position_m: np.ndarray  # (N, U, 2)
    velocity_mps: np.ndarray  # (N, U, 2)
    orbiting: np.ndarray  # (N,) bool: env's UEs follow the circular orbit
    orbit_angle_rad: np.ndarray  # (N,) angle of the cluster centre from east
    orbit_radius_m: np.ndarray  # (N,)
    orbit_rate_rad_s: np.ndarray  # (N,) counter-clockwise
    orbit_offset_m: np.ndarray  # (N, U, 2) UE offsets from the cluster centre


def scenario_index(name: str) -> int:
    if name not in SCENARIOS:
        raise ValueError(
            f"unknown scenario {name!r}; choose from {', '.join(SCENARIOS)} or {MIXED}"
        )
    return SCENARIOS.index(name)


def draw_scenarios(rng: np.random.Generator, name: str, n_envs: int) -> np.ndarray:
    """Scenario index per env: all ``name``, or uniformly drawn per env for ``mixed``."""
    if name == MIXED:
        return rng.integers(0, len(SCENARIOS), size=n_envs)
    return np.full(n_envs, scenario_index(name))


def init_mobility(
    rng: np.random.Generator, scenario_ids: np.ndarray, cfg: EnvConfig
) -> MobilityState:
    """Initial UE positions and velocities for each env's scenario (indices into ``SCENARIOS``)."""
    n_envs, n_ues = len(scenario_ids), cfg.n_ues
    state = MobilityState(
        position_m=np.zeros((n_envs, n_ues, 2)),
        velocity_mps=np.zeros((n_envs, n_ues, 2)),
        orbiting=np.zeros(n_envs, dtype=bool),
        orbit_angle_rad=np.zeros(n_envs),
        orbit_radius_m=np.ones(n_envs),
        orbit_rate_rad_s=np.zeros(n_envs),
        orbit_offset_m=np.zeros((n_envs, n_ues, 2)),
    )
    for index, name in enumerate(SCENARIOS):
        envs = np.flatnonzero(scenario_ids == index)
        if len(envs):
            _INIT[name](rng, state, envs, cfg)
    return state


def step_mobility(state: MobilityState, dt_s: float, half_width_m: float) -> None:
    """Advance every UE by ``dt_s`` seconds in place; linear movers reflect off the walls."""
    pos, vel = state.position_m, state.velocity_mps
    pos += vel * dt_s
    for _ in range(2):  # a second pass only matters for a step longer than the area
        over, under = pos > half_width_m, pos < -half_width_m
        np.copyto(pos, 2.0 * half_width_m - pos, where=over)
        np.copyto(pos, -2.0 * half_width_m - pos, where=under)
        np.negative(vel, out=vel, where=over | under)
    if state.orbiting.any():
        o = state.orbiting
        state.orbit_angle_rad[o] += state.orbit_rate_rad_s[o] * dt_s
        _place_on_orbit(state, np.flatnonzero(o))


def _uniform_square(rng: np.random.Generator, n: int, count: int, half_m: float) -> np.ndarray:
    return rng.uniform(-half_m, half_m, size=(n, count, 2))


def _heading(angle_rad: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(angle_rad), np.sin(angle_rad)], axis=-1)


def _init_no_move(rng, state, envs, cfg):
    state.position_m[envs] = _uniform_square(rng, len(envs), cfg.n_ues, cfg.cluster_size_m / 2)


def _init_straight(rng, state, envs, cfg):
    _init_no_move(rng, state, envs, cfg)
    direction = rng.uniform(-np.pi, np.pi, size=len(envs))
    state.velocity_mps[envs] = cfg.ue_speed_mps * _heading(direction)[:, None, :]


def _init_two_clusters(gap_rad: float):
    def init(rng, state, envs, cfg):
        _init_no_move(rng, state, envs, cfg)
        base = rng.uniform(-np.pi, np.pi, size=len(envs))
        split = cfg.n_ues // 2
        state.velocity_mps[envs, :split] = cfg.ue_speed_mps * _heading(base)[:, None, :]
        state.velocity_mps[envs, split:] = cfg.ue_speed_mps * _heading(base + gap_rad)[:, None, :]

    return init


def _init_circular(rng, state, envs, cfg):
    hw, size = cfg.area.half_width_m, cfg.cluster_size_m
    # Cluster square at x in [0, size], y in [-hw, -hw + size]: the paper's start, x in [0, 10],
    # y in [-200, -190]; its centre then circles the origin.
    centre = np.array([size / 2, -hw + size / 2])
    state.orbit_offset_m[envs] = _uniform_square(rng, len(envs), cfg.n_ues, size / 2)
    radius = float(np.hypot(*centre))
    state.orbiting[envs] = True
    state.orbit_radius_m[envs] = radius
    state.orbit_angle_rad[envs] = np.arctan2(centre[1], centre[0])
    state.orbit_rate_rad_s[envs] = cfg.ue_speed_mps / radius
    _place_on_orbit(state, envs)


def _place_on_orbit(state: MobilityState, envs: np.ndarray) -> None:
    angle, radius = state.orbit_angle_rad[envs], state.orbit_radius_m[envs]
    centre = radius[:, None] * _heading(angle)
    state.position_m[envs] = centre[:, None, :] + state.orbit_offset_m[envs]
    tangent = _heading(angle + np.pi / 2) * (radius * state.orbit_rate_rad_s[envs])[:, None]
    state.velocity_mps[envs] = tangent[:, None, :]


def _init_hotspot(rng, state, envs, cfg):
    n, hw, half = len(envs), cfg.area.half_width_m, cfg.cluster_size_m / 2
    split = cfg.n_ues // 2
    centre = rng.uniform(-hw + half, hw - half, size=(n, 1, 2))
    state.position_m[envs, :split] = centre + _uniform_square(rng, n, split, half)
    state.position_m[envs, split:] = rng.uniform(-hw, hw, size=(n, cfg.n_ues - split, 2))
    # One velocity for the cluster, one per independent UE; speeds uniform in [0, ue_speed].
    direction = rng.uniform(-np.pi, np.pi, size=(n, 1 + cfg.n_ues - split))
    speed = rng.uniform(0.0, cfg.ue_speed_mps, size=(n, 1 + cfg.n_ues - split))
    velocity = speed[..., None] * _heading(direction)
    state.velocity_mps[envs, :split] = velocity[:, :1]
    state.velocity_mps[envs, split:] = velocity[:, 1:]


_INIT = {
    "no_move": _init_no_move,
    "straight": _init_straight,
    "circular": _init_circular,
    "straight_90": _init_two_clusters(np.pi / 2),
    "straight_180": _init_two_clusters(np.pi),
    "hotspot": _init_hotspot,
}
