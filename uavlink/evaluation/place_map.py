"""The picture of a memory of place: what a map policy remembered, over the field it flew in.

One episode of a policy with a memory of place (layout v3; ``uavlink.env.place_memory``) on the
spatial channel, episode 0 of ``uavlink evaluate --episodes 1 --seed S``. Left, the truth at the
episode's last frame: the mean UE throughput a UAV would get at each spot (path loss and the
episode's shadowing field, no fast fading, as the env computes them, on the genie's grid), the team
where it is then, and the UAV's path. Right, the memory as the policy left it: the value sensed
in each cell it visited, on the same scale (its bits/s/Hz times the per-UE bandwidth B / U, so Mbps
as the round robin gives them; sensed with fast fading, at the frame of the visit), and the cell it
ranks best. Where the two agree, the map is worth returning to; where the team has
moved since, the memory is stale (the ranking discounts age).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavlink.config import EnvConfig
from uavlink.config.env import SHADOWING_SPATIAL
from uavlink.policies.base import Policy
from uavlink.policies.genie.grid import Grid, grid_rx_dbm, one_uav_rate_mbps
from uavlink.policies.genie.policy import GENIE_GRID_M, env_field
from uavlink.radio.spatial_shadowing import SpatialShadowField
from uavlink.rollout import chunks
from uavlink.seeding import EVAL


@dataclass(frozen=True)
class PlaceMapEpisode:
    """What the picture shows, for one episode (east, north in metres; throughputs in Mbps)."""

    scenario: str
    seed: int
    mean_rate_mbps: float  # the episode's mean UE throughput, as evaluate reports it
    uav_path_m: np.ndarray  # (T + 1, 2) from the start
    ue_xy_m: np.ndarray  # (U, 2) at the last frame
    field_x_m: np.ndarray  # (n,) grid coordinates of both axes
    field_mbps: np.ndarray  # (n, n) [ix, iy], the truth at the last frame
    cell_m: float
    memory_mbps: np.ndarray  # (n_side, n_side) [ix, iy], NaN where never sensed
    best_m: np.ndarray  # (2,) centre of the cell the memory ranks best
    half_width_m: float
    shadow_field: SpatialShadowField | None  # the episode's (None without shadowing)


def fly_place_map(policy: Policy, cfg: EnvConfig, seed: int) -> PlaceMapEpisode:
    """Fly episode 0 of ``seed`` and read the memory and the truth at its end."""
    if cfg.place_cell_m <= 0 or cfg.n_uavs != 1 or cfg.radio.shadowing_model != SHADOWING_SPATIAL:
        raise ValueError(
            "a place map needs one UAV with a memory of place (place_cell_m > 0) on the "
            "spatial channel (radio.shadowing_model = spatial)"
        )
    chunk = next(chunks(cfg, EVAL, 1, seed))
    env = chunk.env
    path, rates = [env.uav_xy_m[0].copy()], []
    for frame in chunk.frames(policy):
        path.append(env.uav_xy_m[0].copy())
        rates.append(frame.result.mean_rate_mbps[0])
    truth = env.ground_truth()
    per_ue_mbps = cfg.radio.bandwidth_hz / cfg.n_ues * 1e-6
    grid = Grid.over_area(cfg.area.half_width_m, GENIE_GRID_M, cfg.r_max_m)
    field = env_field(truth.shadow_field, 0, 1)
    rx_dbm = grid_rx_dbm(
        grid, truth.ue_xy_m[:1], field, cfg.radio, cfg.area.uav_altitude_m
    )  # (1, U, n, n)
    memory = env.place_memory
    assert memory is not None  # place_cell_m > 0, checked above
    side = memory.n_side
    sensed = np.isfinite(memory.score[0]).reshape(side, side)
    remembered = np.where(sensed, per_ue_mbps * memory.value[0].reshape(side, side), np.nan)
    return PlaceMapEpisode(
        cfg.scenario,
        seed,
        float(np.mean(rates)),
        np.array(path),
        truth.ue_xy_m[0],
        grid.x_m,
        one_uav_rate_mbps(rx_dbm, cfg.radio)[0],
        memory.cell_m,
        remembered,
        memory.centre_m(memory.best[:1])[0],
        cfg.area.half_width_m,
        field,
    )


def draw_place_map(episode: PlaceMapEpisode, path: Path, title: str = "") -> None:
    """The two panels side by side, one colour scale (Mbps), as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    half = episode.half_width_m
    finite = episode.memory_mbps[np.isfinite(episode.memory_mbps)]
    vmin = float(min(episode.field_mbps.min(), finite.min(initial=np.inf)))
    vmax = float(max(episode.field_mbps.max(), finite.max(initial=-np.inf)))
    fig, axes = plt.subplots(
        1, 2, figsize=(11, 5.0), sharex=True, sharey=True, layout="constrained"
    )
    step = episode.field_x_m[1] - episode.field_x_m[0]
    field_extent = (episode.field_x_m[0] - step / 2, episode.field_x_m[-1] + step / 2) * 2
    image = axes[0].imshow(
        episode.field_mbps.T,
        origin="lower",
        extent=field_extent,
        vmin=vmin,
        vmax=vmax,
        cmap="viridis",
    )
    axes[1].set_facecolor("#dddddd")  # never sensed
    axes[1].imshow(
        episode.memory_mbps.T,
        origin="lower",
        extent=(-half, half, -half, half),
        vmin=vmin,
        vmax=vmax,
        cmap="viridis",
    )
    for ax in axes:
        ax.plot(*episode.uav_path_m.T, color="white", lw=1.0, alpha=0.9)
        ax.plot(
            *episode.uav_path_m[-1], "o", color="white", mec="black", ms=7, label="UAV (last frame)"
        )
        ax.plot(
            *episode.best_m, "*", color="#ff4040", mec="black", ms=14, label="best remembered cell"
        )
        ax.set_xlim(-half, half)
        ax.set_ylim(-half, half)
        ax.set_xlabel("east (m)")
        ax.set_aspect("equal")
    axes[0].plot(
        *episode.ue_xy_m.T, "^", color="#ffb000", mec="black", ms=6, label="UEs (last frame)"
    )
    axes[0].set_ylabel("north (m)")
    axes[0].set_title("truth at the last frame, from each spot", fontsize=10)
    axes[1].set_title(f"the memory: sensed where visited ({episode.cell_m:g} m cells)", fontsize=10)
    axes[0].legend(loc="lower left", fontsize=7, framealpha=0.8)
    fig.colorbar(image, ax=axes, shrink=0.8, label="mean UE throughput (Mbps)")
    fig.suptitle(
        title or f"{episode.scenario}, seed {episode.seed}: {episode.mean_rate_mbps:.2f} Mbps flown"
    )
    fig.savefig(path, dpi=90)
    plt.close(fig)
