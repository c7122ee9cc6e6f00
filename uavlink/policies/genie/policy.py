"""``genie``, the full-knowledge yardstick (SPEC "The limit, and a memory of place"): evaluation only.

It knows the episode's whole future, the UEs' trajectories (their motion is deterministic from the
mobility state) and the spatial shadowing field, and flies the path that maximises the episode's
mean expected UE throughput (per-UE Shannon rate at the mean-fading SINR: ``mean_channel_rate_bps``)
under the motion limits (|move| <= r_max per frame, inside the area, from the start position).

One UAV: dynamic programming over a grid of positions (``uavlink.policies.genie.grid``), exact over
grid paths. A fleet: the same per UAV given the others' paths (interference, association), UAV after
UAV, from the best of the GPS baselines' paths (static, oracle, kmeans, replayed exactly: they read
nothing random), until no UAV's re-plan gains more than ``tolerance``. Separation: a UAV's plan
keeps every move clear of the env's separation filter (``uavlink.mobility.fleet.separate``: UAVs
before it at their new positions, after it at their current ones), so the realised path is the
planned one. On AR(1) (or without shadowing) it plans on the mean channel: a reference, not a bound.
It plans when an episode starts (or whenever it meets a state its plan did not expect) and then
steers to the plan's next point through the env's action mapping; ``fly`` and ``export`` refuse it.
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from uavlink.config import EnvConfig, RadioConfig
from uavlink.config.env import MOTION_INSTANT, REUSE_LISTEN, REUSE_ORTHOGONAL
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.mobility import MobilityState, step_mobility
from uavlink.mobility.fleet import apply_moves
from uavlink.policies.base import RulePolicy
from uavlink.policies.genie.grid import (
    Grid,
    MoveBox,
    best_grid_path,
    grid_rx_dbm,
    one_uav_rate_mbps,
)
from uavlink.policies.genie.separation import merged_boxes, segment_clear
from uavlink.radio.cells import mean_channel_rate_bps
from uavlink.radio.noise import noise_power_dbm
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
from uavlink.radio.spatial_shadowing import SpatialShadowField

# Planned moves keep this much more than the minimum: the filter never cuts.
SEPARATION_SLACK_M = 1e-6
REFERENCES = ("static", "oracle", "kmeans")  # the baselines whose paths a fleet plan starts from
GENIE_GRID_M = 4.0  # the grid the genie plans on (its default); the place map draws the truth on it


def future_ues(
    mobility: MobilityState, frames: int, frame_s: float, half_width_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """UE positions and velocities (frames + 1, N, U, 2) from now (entry 0) to the episode's end,
    stepping a copy of the state as the env does."""
    state = MobilityState(**{k: np.array(v, copy=True) for k, v in vars(mobility).items()})
    pos, vel = [state.position_m.copy()], [state.velocity_mps.copy()]
    for _ in range(frames):
        step_mobility(state, frame_s, half_width_m)
        pos.append(state.position_m.copy())
        vel.append(state.velocity_mps.copy())
    return np.array(pos), np.array(vel)


def env_field(field: SpatialShadowField | None, env: int, frames: int) -> SpatialShadowField | None:
    """Env ``env``'s field with its arrays repeated over ``frames`` leading rows (no copy), so that
    ``shadow_db`` reads a path's frames as its batch."""
    if field is None:
        return None

    def rows(a: np.ndarray) -> np.ndarray:  # noqa: E306
        return np.broadcast_to(a[env : env + 1], (frames, *a.shape[1:]))

    return dataclasses.replace(
        field,
        ue_wave_per_m=rows(field.ue_wave_per_m),
        uav_wave_per_m=rows(field.uav_wave_per_m),
        phase_rad=rows(field.phase_rad),
    )


def fleet_mean_rate_bps(
    mine_mw: np.ndarray, others_mw: np.ndarray, radio: RadioConfig, fleet_reuse: str
) -> np.ndarray:
    """The UEs' mean ``mean_channel_rate_bps`` (T, G) with one UAV at each of G places and the others
    fixed: received powers mW, (T, U, G) from the moving UAV, (T, U, D - 1) from the others. The same
    cells, shares and interference (exact ties of power aside, which go to the moving UAV here and
    to the lower index there), written per place: a fleet plan's hot path; a listening fleet's one
    cell as ``listening_server`` picks it.

    Every UE of a cell has the cell's size, so the mean over UEs is, per cell, the sum of its UEs'
    log2(1 + SINR) over its size: cell sums are matrix products of UE-to-cell indicators (float32
    throughout), not (T, U, G) arrays of sizes."""
    n_ues, n_others = others_mw.shape[-2:]
    noise_mw = np.float32(10.0 ** (noise_power_dbm(radio.bandwidth_hz, radio) / 10.0))
    their = others_mw.argmax(axis=-1)  # (T, U) the strongest other UAV of each UE
    signal_theirs = np.take_along_axis(others_mw, their[..., None], axis=-1)  # (T, U, 1)
    mine = mine_mw > signal_theirs  # (T, U, G) served by the moving UAV
    mine_f = mine.astype(np.float32)
    n_mine = mine_f.sum(axis=1)  # (T, G)
    member = (their[:, None, :] == np.arange(n_others)[None, :, None]).astype(
        np.float32
    )  # (T, D-1, U)
    n_their = (
        member.sum(axis=-1)[..., None] - member @ mine_f
    )  # (T, D-1, G): each other cell's UEs left
    if fleet_reuse == REUSE_LISTEN:  # one cell, as uavlink.radio.cells.listening_server picks it
        power_mine, power_theirs = mine_mw.sum(axis=1), others_mw.sum(axis=1)  # (T, G), (T, D-1)
        total = power_mine + power_theirs.sum(axis=1, keepdims=True)
        key_theirs = n_their + 0.5 * power_theirs[..., None] / total[:, None]  # (T, D-1, G)
        best_other = key_theirs.argmax(axis=1)  # (T, G)
        served = np.where(
            (n_mine + 0.5 * power_mine / total >= key_theirs.max(axis=1))[:, None, :],
            mine_mw,
            np.take_along_axis(others_mw, best_other[:, None, :], axis=-1),
        )  # (T, U, G)
        bits = np.log2(served / noise_mw + np.float32(1.0))
        return np.float32(radio.bandwidth_hz) / n_ues * bits.sum(axis=1) / n_ues
    if fleet_reuse == REUSE_ORTHOGONAL:
        share = np.float32(radio.orthogonal_share(n_others + 1))
        sinr = np.where(mine, mine_mw, signal_theirs) / (share * noise_mw)
        bandwidth = share * np.float32(radio.bandwidth_hz)
    else:  # every active other cell's power, less the UE's own for a UE of another cell
        from_others = sum(
            others_mw[:, :, j, None] * (n_their[:, None, j] > 0) for j in range(n_others)
        )
        interference = np.where(
            mine, from_others, from_others - signal_theirs + (n_mine > 0)[:, None, :] * mine_mw
        )
        sinr = np.where(mine, mine_mw, signal_theirs) / (interference + noise_mw)
        bandwidth = np.float32(radio.bandwidth_hz)
    bits = np.log2(sinr + np.float32(1.0), out=sinr)  # (T, U, G) per UE, before its cell's share
    in_mine = (bits * mine_f).sum(axis=1)  # (T, G)
    in_theirs = member @ (bits - bits * mine_f)  # (T, D-1, G)
    with np.errstate(divide="ignore", invalid="ignore"):  # an empty cell holds no UE: 0 / 0 -> 0
        per_cell = np.where(n_mine > 0, in_mine / n_mine, 0.0) + np.where(
            n_their > 0, in_theirs / n_their, 0.0
        ).sum(axis=1)
    return bandwidth / n_ues * per_cell


class EpisodePlanner:
    """One episode's plan: UEs (T + 1, U, 2) from now, the field (or None), the UAVs' start (D, 2)."""

    def __init__(
        self,
        cfg: EnvConfig,
        grid: Grid,
        ue_xy_m: np.ndarray,
        field: SpatialShadowField | None,
        start_m: np.ndarray,
    ) -> None:
        self.cfg, self.grid, self.ue_xy_m, self.start_m = cfg, grid, ue_xy_m, start_m
        self.frames = len(ue_xy_m) - 1
        self.field = env_field(field, 0, self.frames) if field is not None else None
        self.rx_grid = grid_rx_dbm(grid, ue_xy_m[1:], field, cfg.radio, cfg.area.uav_altitude_m)
        # (T, U, n n) float32, mW: a fleet's rewards (_reward) read it in every UAV's plan
        self.rx_grid_mw = (
            np.exp(
                self.rx_grid.reshape(*self.rx_grid.shape[:2], -1) * np.float32(np.log(10.0) / 10.0)
            )
            if len(start_m) > 1
            else None
        )
        self.separation_m = cfg.uav_separation_m + SEPARATION_SLACK_M
        # (n, n, 2): the grid's points, where the separation checks look
        self._points_m = np.stack(np.meshgrid(grid.x_m, grid.x_m, indexing="ij"), axis=-1)

    def rx_dbm(self, path_m: np.ndarray) -> np.ndarray:
        """Mean received power (T, U, D) for a path (T + 1, D, 2), as the env computes it."""
        uav, ue = path_m[1:], self.ue_xy_m[1:]
        rx = mean_rx_power_dbm(distance_3d_m(uav, ue, self.cfg.area.uav_altitude_m), self.cfg.radio)
        return rx + self.field.shadow_db(uav, ue) if self.field is not None else rx

    def rate_mbps(self, path_m: np.ndarray) -> float:
        """The episode's mean expected UE throughput on ``path_m`` (T + 1, D, 2), Mbps."""
        return (
            float(
                mean_channel_rate_bps(
                    self.rx_dbm(path_m), self.cfg.radio, self.cfg.fleet_reuse
                ).mean()
            )
            * 1e-6
        )

    def plan(
        self, references: list[np.ndarray], tolerance: float, max_rounds: int
    ) -> tuple[np.ndarray, float]:
        """From the best of ``references`` (paths (T + 1, D, 2)), re-plan UAV after UAV given the others
        until a round gains no UAV more than ``tolerance`` (relative); the best path and its rate."""
        values = [self.rate_mbps(p) for p in references]
        path, value = references[int(np.argmax(values))].copy(), max(values)
        n_uavs = path.shape[1]
        changes = np.zeros(n_uavs, dtype=int)  # how often each UAV's path changed
        seen: dict[int, np.ndarray] = {}  # the others' changes when a UAV was last planned
        for _ in range(max_rounds if n_uavs > 1 else 1):
            gained = False
            for d in range(n_uavs):
                if d in seen and (seen[d] == changes).all():
                    continue  # nothing moved since its last plan: the DP would return the same path
                seen[d] = changes.copy()
                own = self.plan_uav(d, path)
                if own is None:
                    continue
                candidate = path.copy()
                candidate[:, d] = own
                new = self.rate_mbps(candidate)
                if new > value:
                    gained |= new > value * (1.0 + tolerance)
                    path, value = candidate, new
                    changes[d] += 1
                    seen[d] = changes.copy()
            if not gained:
                break
        return path, value

    def plan_uav(self, d: int, path_m: np.ndarray) -> np.ndarray | None:
        """UAV ``d``'s best grid path (T + 1, 2) from its start, the others flying ``path_m``."""
        grid, n_uavs = self.grid, path_m.shape[1]
        reward = self._reward(d, path_m)
        first = grid.cells_within(path_m[0, d], grid.r_max_m)
        if n_uavs > 1:
            reward[~self._cells_clear(d, path_m)] = -np.inf
            first &= self._first_moves_clear(self._blockers(d, path_m, 0), path_m[0, d])
        cells, _ = best_grid_path(
            reward, grid, first, self._moves_clear(d, path_m) if n_uavs > 1 else None
        )
        if cells is None:
            return None
        return np.concatenate([path_m[:1, d], grid.points_m(cells)])

    def _reward(self, d: int, path_m: np.ndarray, block: int = 2) -> np.ndarray:
        """Mean UE rate (T, n, n), Mbps, with UAV ``d`` at each cell and the others on ``path_m``."""
        radio, n = self.cfg.radio, self.grid.n
        n_uavs = path_m.shape[1]
        if n_uavs == 1:
            return one_uav_rate_mbps(self.rx_grid, radio)
        assert self.rx_grid_mw is not None  # a fleet's planner (__init__)
        others = [j for j in range(n_uavs) if j != d]
        others_mw = (10.0 ** (self.rx_dbm(path_m)[..., others] / 10.0)).astype(
            np.float32
        )  # (T, U, D-1)
        reward = np.empty((self.frames, n, n))
        for t0 in range(0, self.frames, block):  # a block of frames at a time: arrays in cache
            rate = fleet_mean_rate_bps(
                self.rx_grid_mw[t0 : t0 + block],
                others_mw[t0 : t0 + block],
                radio,
                self.cfg.fleet_reuse,
            )
            reward[t0 : t0 + block] = rate.reshape(-1, n, n) * 1e-6
        return reward

    def _windows(self, centre_m: np.ndarray, reach_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The squares of w x w grid cells holding every cell within ``reach_m`` of each centre
        (..., 2), moved inside the grid where they would cross an edge: their row and column
        indices (..., w) each."""
        grid = self.grid
        w = min(grid.n, 2 * int(np.ceil(reach_m / grid.spacing_m)) + 3)
        origin = np.clip(
            np.rint((centre_m + grid.x_m[-1]) / grid.spacing_m).astype(int) - w // 2, 0, grid.n - w
        )
        return origin[..., 0, None] + np.arange(w), origin[..., 1, None] + np.arange(w)

    def _cells_clear(self, d: int, path_m: np.ndarray) -> np.ndarray:
        """(T, n, n): cells where UAV d may be at frame t + 1 without cutting another's move: clear of
        a later UAV's move into that frame and of an earlier UAV's move out of it. Only cells within
        the separation plus the move's length of its start can come close: each move is checked on
        that window of cells, every frame at once."""
        clear = np.ones((self.frames, self.grid.n, self.grid.n), dtype=bool)
        for j in range(path_m.shape[1]):
            if j > d:  # its move into frame t + 1
                a, b = path_m[:-1, j], path_m[1:, j]
            elif j < d:  # its move out of frame t + 1
                a, b = path_m[1:-1, j], path_m[2:, j]
            else:
                continue
            reach_m = self.separation_m + float(np.hypot(*(b - a).T).max(initial=0.0))
            rows, cols = self._windows(a, reach_m)  # (F, w) each
            frames = np.arange(len(a))[:, None, None]
            cells = (frames, rows[:, :, None], cols[:, None, :])  # (F, w, w) indices
            clear[cells] &= segment_clear(
                a[:, None, None], b[:, None, None], self._points_m[cells[1:]], self.separation_m
            )
        return clear

    @staticmethod
    def _blockers(d: int, path_m: np.ndarray, t: int) -> np.ndarray:
        """Where the others stand while UAV d moves from frame t to t + 1, as the separation filter
        sees them: UAVs before d at frame t + 1, after d at frame t."""
        return np.array(
            [path_m[t + 1, j] if j < d else path_m[t, j] for j in range(path_m.shape[1]) if j != d]
        )

    def _first_moves_clear(self, blockers: np.ndarray, source_m: np.ndarray) -> np.ndarray:
        """(n, n): grid cells a straight move from ``source_m`` reaches clear of every blocker."""
        clear = np.ones(self._points_m.shape[:2], dtype=bool)
        for c in blockers:
            clear &= segment_clear(source_m, self._points_m, c, self.separation_m)
        return clear

    def _moves_clear(self, d: int, path_m: np.ndarray, block: int = 4) -> list[list[MoveBox]]:
        """Per frame t + 1 (T - 1 lists of disjoint boxes), the grid moves of UAV d to frame t + 2
        that stay clear of every other UAV as the filter sees it. Only sources within the separation
        plus r_max of another UAV can come close: each is checked on that window of cells (``block``
        frames at a time, in cache); overlapping windows merge into the box that spans them."""
        grid = self.grid
        step = (grid.offsets * grid.spacing_m)[:, None, None]  # (K, 1, 1, 2)
        blockers = np.stack(
            [self._blockers(d, path_m, t + 1) for t in range(self.frames - 1)]
        )  # (T - 1, D - 1, 2)
        rows, cols = self._windows(blockers, self.separation_m + grid.r_max_m)  # (T-1, D-1, w)
        boxes = []
        for t0 in range(0, self.frames - 1, block):
            span = slice(t0, t0 + block)
            source = self._points_m[rows[span, :, :, None], cols[span, :, None, :]]
            clear = segment_clear(
                source[:, :, None],
                source[:, :, None] + step,
                blockers[span, :, None, None, None],
                self.separation_m,
            )  # (block, D - 1, K, w, w)
            boxes += [
                merged_boxes(r.tolist(), c.tolist(), far)
                for r, c, far in zip(rows[span, :, 0], cols[span, :, 0], clear, strict=True)
            ]
        return boxes


def _plan_episode(task: tuple) -> tuple[np.ndarray, float]:
    """One episode's plan and its rate, from ``GeniePolicy.plan``'s task (a top-level function: a
    worker process calls it)."""
    cfg, grid, ue, field, start, references, tolerance, max_rounds = task
    return EpisodePlanner(cfg, grid, ue, field, start).plan(references, tolerance, max_rounds)


class GeniePolicy(RulePolicy):
    """The genie as a policy: needs ground truth (``GroundTruth.mobility``, ``shadow_field``)."""

    name = "genie"
    layout = None
    needs_truth = True
    privilege = "knows the episode's future (the UEs' paths and the shadowing field), is for evaluation only"

    def __init__(
        self,
        cfg: EnvConfig,
        references: list,
        grid_m: float = GENIE_GRID_M,
        tolerance: float = 1e-3,
        max_rounds: int = 4,
        workers: int | None = None,
    ) -> None:
        """``references``: the baselines of ``REFERENCES`` for ``cfg`` (a fleet's plan starts from the
        best of their paths); ``uavlink.policies.registry.make_baseline("genie", cfg)`` passes them.
        ``workers``: threads that plan a batch's episodes side by side (default: one per CPU)."""
        self.cfg = cfg.validate()
        if cfg.uav_motion != MOTION_INSTANT:
            raise ValueError(
                "the genie plans instant moves: plan it in the env with uav_motion='instant' "
                "(uavlink.policies.registry.baseline_env)"
            )
        self.workers = max(1, workers or os.cpu_count() or 1)
        self.mapping = ActionMapping.for_config(cfg)
        self.grid = Grid.over_area(cfg.area.half_width_m, grid_m, cfg.r_max_m)
        self.tolerance, self.max_rounds = tolerance, max_rounds
        self.references = references
        # (T + 1, N, D, 2) the plan, entry 0 at frame ``planned_at``.
        self.path_m: np.ndarray | None = None
        self.planned_rate_mbps: np.ndarray | None = None  # (N,) its mean expected throughput
        self.planned_at = 0

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None or truth.mobility is None:
            raise ValueError(
                "the genie needs the episode's ground truth; it cannot fly from MAVLink data"
            )
        now = truth.uav_xy_m.reshape(-1, self.cfg.n_uavs, 2)
        step = truth.frame - self.planned_at
        # Frame 0 is a new episode even where the UAVs stand where the last plan began (every
        # episode starts at the centre): the next batch of an evaluation must not fly this one's plan.
        if (
            truth.frame == 0
            or self.path_m is None
            or not 0 <= step < len(self.path_m) - 1
            or self.path_m.shape[1] != len(now)
            or not np.allclose(self.path_m[step], now, atol=1e-6)
        ):
            self.plan(truth)
            step = 0
        assert self.path_m is not None  # plan() set it
        return self.mapping.towards(self.path_m[step + 1].reshape(-1, 2) - truth.uav_xy_m, 1.0)

    def plan(self, truth: GroundTruth) -> None:
        """Plan every env of the batch from its present state to the episode's end."""
        cfg, n_uavs = self.cfg, self.cfg.n_uavs
        frames = cfg.episode_frames - truth.frame
        assert truth.mobility is not None  # ground truth of an env (act() checks it)
        ue, velocity = future_ues(truth.mobility, frames, cfg.frame_s, cfg.area.half_width_m)
        start = truth.uav_xy_m.reshape(-1, n_uavs, 2)
        references = [
            self._replay(p, start, ue, velocity, truth.scenario_ids) for p in self.references
        ]
        tasks = [
            (
                cfg,
                self.grid,
                ue[:, env],
                env_field(truth.shadow_field, env, 1),
                start[env],
                [r[:, env] for r in references],
                self.tolerance,
                self.max_rounds,
            )
            for env in range(len(start))
        ]
        workers = min(self.workers, len(tasks))
        if workers > 1:  # episodes plan independently, and numpy's array loops release the GIL
            with ThreadPoolExecutor(workers) as pool:
                plans = list(pool.map(_plan_episode, tasks))
        else:
            plans = [_plan_episode(task) for task in tasks]
        paths, rates = zip(*plans, strict=True)
        self.path_m, self.planned_rate_mbps, self.planned_at = (
            np.stack(paths, axis=1),
            np.array(rates),
            truth.frame,
        )

    def _replay(
        self,
        policy,
        start: np.ndarray,
        ue: np.ndarray,
        velocity: np.ndarray,
        scenario_ids: np.ndarray,
    ) -> np.ndarray:
        """The path (T + 1, N, D, 2) a GPS baseline flies, stepped as ``BatchedUavEnv.step`` does."""
        n_envs, n_uavs = start.shape[:2]
        half, rows = self.cfg.area.half_width_m, n_envs * n_uavs
        path = [start.copy()]
        for t in range(len(ue) - 1):
            now = path[-1].reshape(rows, 2)
            truth = GroundTruth(now, ue[t], velocity[t], scenario_ids)
            action = self.mapping.validate(policy.act(np.zeros((rows, 0), np.float32), truth), rows)
            moves = self.mapping.to_displacement_m(action).reshape(n_envs, n_uavs, 2)
            path.append(apply_moves(path[-1], moves, half, self.cfg.uav_separation_m))
        return np.array(path)
