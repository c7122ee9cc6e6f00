"""Baselines for a fleet of D UAVs (SPEC "A fleet"), acting on agent rows (N D, ...) like any policy.

``static`` needs nothing new (every UAV hovers at its start). Here: the GPS-free ``aoa`` rule run
per cell, the greedy GPS ``oracle`` that moves UAV after UAV, and the GPS ``kmeans`` that sends each
UAV to its share of a k-means split of the UEs.
"""

from __future__ import annotations

import itertools

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.mobility.fleet import separate
from uavlink.policies.base import RulePolicy
from uavlink.policies.baselines import AoaPolicy, hover_sinr_db
from uavlink.radio.cells import mean_channel_rate_bps
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
from uavlink.radio.rates import fair_rate


class FleetAoaPolicy(RulePolicy):
    """The aoa rule per cell: each UAV flies towards the circular-mean AoA of the UEs it serves,
    slower as their SINRs level off at the hover level; a UAV that serves none holds."""

    name = "aoa"
    needs_truth = False
    sinr_span_db = (
        AoaPolicy.sinr_span_db
    )  # full speed this far below the hover SINR, as one UAV's rule

    def __init__(self, cfg: EnvConfig, sinr_span_db: float = sinr_span_db) -> None:
        # A warm start's teacher may change it (uavlink.learn.teachers)
        self.sinr_span_db = sinr_span_db
        self.layout = ObservationLayout.for_config(cfg)
        self.mapping = ActionMapping.for_config(cfg)
        self.hover_sinr_db = hover_sinr_db(cfg)

    def sinr_gap_db(self, frame: dict[str, np.ndarray]) -> np.ndarray:
        """How far the mean SINR of each row's own cell lies below the hover level, dB (an empty
        cell: 0, so its UAV holds)."""
        mine = self.layout.own_cell(frame)  # (rows, U)
        with np.errstate(invalid="ignore"):
            mean_sinr_db = np.where(mine, frame["sinr_db"], 0.0).sum(axis=1) / mine.sum(axis=1)
        return np.nan_to_num(self.hover_sinr_db - mean_sinr_db)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        frame = self.layout.newest_frame(obs)
        gap = self.sinr_gap_db(frame) / self.sinr_span_db
        distance = self.mapping.r_max_m * np.clip(gap, 0.0, 1.0)
        return self.mapping.from_polar(frame["cell_aoa_mean_deg"], distance)


def mean_fleet_fair_rate(cfg: EnvConfig, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> np.ndarray:
    """R_fair of all UEs on the mean channel (path loss only) for UAVs (..., D, 2) and UEs
    (..., U, 2): strongest-UAV association, per-cell B / U_d, interference from every active cell
    (``fleet_reuse = "full"``) or none (``"orthogonal"``): ``uavlink.radio.cells.mean_channel_rate_bps``."""
    rx_dbm = mean_rx_power_dbm(distance_3d_m(uav_xy_m, ue_xy_m, cfg.area.uav_altitude_m), cfg.radio)
    return fair_rate(mean_channel_rate_bps(rx_dbm, cfg.radio, cfg.fleet_reuse))


class FleetOraclePolicy(RulePolicy):
    """GPS greedy reference: each frame, UAV after UAV, the reachable move (hover, or one of
    ``n_angles`` x ``n_radii`` up to r_max, kept apart by the separation filter) that maximises the
    mean-channel R_fair of all UEs at their next positions, the UAVs before it at their chosen
    spots. Not a bound: with one cluster it brings the UAVs close and they interfere."""

    name = "oracle"
    layout = None
    needs_truth = True

    def __init__(self, cfg: EnvConfig, n_angles: int = 16, n_radii: int = 3) -> None:
        self.cfg = cfg
        self.mapping = ActionMapping.for_config(cfg)
        angle = np.radians(np.linspace(-180.0, 180.0, n_angles, endpoint=False))
        radius = np.linspace(cfg.r_max_m / n_radii, cfg.r_max_m, n_radii)
        ring = radius[:, None, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)[None]
        self.cand_move = np.concatenate([np.zeros((1, 2)), ring.reshape(-1, 2)])  # (C, 2)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError(
                "the oracle baseline needs ground truth; it cannot fly from MAVLink data"
            )
        cfg, n_uavs = self.cfg, self.cfg.n_uavs
        half = cfg.area.half_width_m
        ue_next = np.clip(truth.ue_xy_m + truth.ue_velocity_mps * cfg.frame_s, -half, half)
        now = truth.uav_xy_m.reshape(-1, n_uavs, 2)
        plan = now.copy()
        n_envs, n_cand = len(now), len(self.cand_move)
        for d in range(n_uavs):
            cand = np.repeat(plan[:, None], n_cand, axis=1)  # (N, C, D, 2)
            cand[:, :, d] = np.clip(now[:, None, d] + self.cand_move, -half, half)
            flat = separate(
                np.repeat(plan, n_cand, axis=0), cand.reshape(-1, n_uavs, 2), cfg.uav_separation_m
            )
            cand = flat.reshape(n_envs, n_cand, n_uavs, 2)
            score = mean_fleet_fair_rate(cfg, cand, ue_next[:, None])
            plan[:, d] = cand[np.arange(n_envs), score.argmax(axis=1), d]
        return self.mapping.towards(plan.reshape(-1, 2) - truth.uav_xy_m, 1.0)


class KMeansPolicy(RulePolicy):
    """GPS reference: split the UEs into D groups by k-means (Lloyd's iterations from the UAVs'
    positions), match groups to UAVs by the least total distance, fly each UAV towards its group's
    centroid. D = 1 flies to the centroid of all UEs."""

    name = "kmeans"
    layout = None
    needs_truth = True
    iterations = 10

    def __init__(self, cfg: EnvConfig) -> None:
        self.cfg = cfg
        self.mapping = ActionMapping.for_config(cfg)
        self.matchings = np.array(list(itertools.permutations(range(cfg.n_uavs))))  # (D!, D)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError(
                "the kmeans baseline needs ground truth; it cannot fly from MAVLink data"
            )
        centroid_m, _ = self.groups(truth)
        return self.mapping.towards(centroid_m.reshape(-1, 2) - truth.uav_xy_m, 1.0)

    def groups(self, truth: GroundTruth) -> tuple[np.ndarray, np.ndarray]:
        """Each UAV's group: its centroid and its UEs' mean velocity (N, D, 2 each, m and m/s),
        groups matched to UAVs by the least total distance to the centroids."""
        n_uavs = self.cfg.n_uavs
        uav = truth.uav_xy_m.reshape(-1, n_uavs, 2)
        ue = truth.ue_xy_m
        centroid = uav.copy()
        for _ in range(self.iterations):
            label = np.linalg.norm(ue[:, :, None] - centroid[:, None], axis=-1).argmin(
                axis=2
            )  # (N, U)
            member = label[..., None] == np.arange(n_uavs)  # (N, U, D)
            count = member.sum(axis=1)[..., None]
            mean = np.einsum("nud,nuk->ndk", member, ue) / np.maximum(count, 1)
            centroid = np.where(count > 0, mean, centroid)  # an empty group keeps its centre
        velocity = np.einsum("nud,nuk->ndk", member, truth.ue_velocity_mps) / np.maximum(count, 1)
        gap = np.linalg.norm(uav[:, :, None] - centroid[:, None], axis=-1)  # (N, UAV, group)
        cost = gap[:, np.arange(n_uavs), self.matchings].sum(axis=2)  # (N, D!)
        order = self.matchings[cost.argmin(axis=1)]  # (N, D): UAV d flies to group order[:, d]
        rows = np.arange(len(uav))[:, None]
        return centroid[rows, order], velocity[rows, order]
