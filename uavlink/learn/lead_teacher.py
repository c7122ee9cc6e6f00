"""A fleet's warm-start teacher whose roles the observation shows: one UAV leads, the others keep away.

With one group of UEs a second active cell only takes UEs and interferes with all the others (SPEC
"A fleet"), so the best a fleet of D can do is one UAV's policy with the other cells empty, hence
silent; the genie, which knows the field and the future, flies a fleet of two on no_move nearly so
(9.6 and 0.4 UEs per UAV; research/log/fleet.md, "No_move's model-led copy under PPO").
``SoloTeacher`` (uavlink.learn.teachers) picks its leader by GPS (nearest the UEs' centroid), which
no UAV can read from its observation: cloned, the actor averaged the roles and both UAVs fled
(research/log/fleet.md, no_move 4.7 Mbps). Here the roles are a function of what every UAV observes:
the leader is the UAV serving the most UEs (v2's ``served_by``, v6's slots; ties go to the UAV farthest east, then
north, positions every UAV sees), so a clone can learn them, and the split reinforces itself (the
others leave, the leader's cell grows; the counts are summed over the frames in memory, so a UE
that shadowing hands over for a frame does not swap the roles). The leader flies a single-UAV
policy (the single-UAV spatial policy of the scenario: it exploits the good shadowing spots) on its
single-UAV view, the v1 fields (and v3's memory of place, v5's model of the field) of its own
fleet frames (``single_view``); the others head for the corner farthest from the leader and, while
their cell still holds a UE, on along the wall to the next farthest, holding once their cell is
empty (as ``SoloTeacher`` does around the UEs' centroid); in a listening fleet (``fleet_reuse =
"listen"``, where they can take no UE) they hold where they are.
GPS-free: it reads nothing but the observation.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from uavlink.config import EnvConfig
from uavlink.config.env import PLACE_KRIGING, PLACE_POOLED, REUSE_LISTEN
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import (
    KRIGING_LAYOUT_VERSION,
    OBS_LAYOUT_VERSION,
    PLACE_LAYOUT_VERSION,
    ObservationLayout,
)
from uavlink.errors import UserError
from uavlink.policies.baselines import AoaPolicy, hover_sinr_db
from uavlink.rollout import Actor


def single_layout(fleet: ObservationLayout, place: bool = True) -> ObservationLayout:
    """The single-UAV layout with a fleet layout's UEs, memory and area: v1, or with ``place`` v3
    where the fleet's layout (v4, v7) has a memory of place, v5 where it (v8) has a model of the
    field too."""
    place_cell_m = fleet.place_cell_m if place else 0.0
    single = ObservationLayout(
        version=PLACE_LAYOUT_VERSION if place_cell_m > 0 else OBS_LAYOUT_VERSION,
        n_ues=fleet.n_ues,
        n_uavs=1,
        memory=fleet.memory,
        half_width_m=fleet.half_width_m,
        sinr_offset_db=fleet.sinr_offset_db,
        sinr_scale_db=fleet.sinr_scale_db,
        sinr_clip_db=fleet.sinr_clip_db,
        aoa_std_max_rad=fleet.aoa_std_max_rad,
        place_cell_m=place_cell_m,
    )
    if place_cell_m == 0 or not fleet.models_field:
        return single
    return dataclasses.replace(
        single,
        version=KRIGING_LAYOUT_VERSION,
        place_model=PLACE_KRIGING,
        episode_frames=fleet.episode_frames,
        r_max_m=fleet.r_max_m,
    )


def single_view(fleet: ObservationLayout, obs: np.ndarray, place: bool = True) -> np.ndarray:
    """What one UAV of a fleet would observe alone: the single-UAV fields of each of its frames,
    with ``place`` and its memory of place where the fleet's layout has one, (rows,
    ``single_layout(fleet, place).size``) float32 from fleet observations (rows, size). Each UAV's
    memory holds what it sensed where it flew."""
    single = single_layout(fleet, place)
    frames = fleet.encoded_history(
        obs, *(field.quantity for field in single.fields)
    )  # (rows, memory, single frame)
    return frames.reshape(len(obs), -1).astype(np.float32)


def leader_index(layout: ObservationLayout, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which UAV leads, as each observing row numbers them (0 = itself, then the others: v2's
    fleet order, v6's slots): the one serving the most UEs, ties to the UAV farthest east, then
    north (every UAV of an env picks the same). Returns the index (rows,) and the UAVs' positions
    (rows, 1 + others, 2)."""
    frame = layout.newest_frame(obs)
    if layout.uav_slots > 0:
        cells, xy = _slot_cells(layout, obs, frame)
    else:
        # UEs served over the frames in memory, (rows, D) numbered me, next, ...: a UE that
        # shadowing hands over for a frame does not swap the roles.
        cells = (layout.history(obs, "served_by")[..., None] == np.arange(layout.n_uavs)).sum(
            axis=(1, 2)
        )
        xy = np.concatenate([frame["uav_xy_m"][:, None], frame["others_xy_m"]], axis=1)
    # Lexicographic (cell size, x, y), positions rounded so every UAV of an env ranks alike.
    key = np.round(xy, 3)
    return np.lexsort((key[..., 1], key[..., 0], cells), axis=1)[:, -1], xy


def _slot_cells(
    layout: ObservationLayout, obs: np.ndarray, frame: dict[str, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """v6's cell sizes over the frames in memory (rows, 1 + K), this UAV's then each slot's (a UE
    counts for the slot its server's offset equals; an empty slot, -1, never leads), and the
    positions (rows, 1 + K, 2)."""
    here = layout.history(obs, "served_here")  # (rows, M, U)
    server = layout.history(obs, "server_offset_m")  # (rows, M, U, 2)
    slots = layout.history(obs, "slot_offset_m")  # (rows, M, K, 2)
    gap = np.linalg.norm(server[:, :, :, None] - slots[:, :, None], axis=-1)  # (rows, M, U, K)
    theirs = ((gap < 1e-2) & ~here[..., None]).sum(axis=(1, 2))
    theirs = np.where(frame["slot_present"], theirs, -1)
    cells = np.concatenate([here.sum(axis=(1, 2))[:, None], theirs], axis=1)
    me = frame["uav_xy_m"][:, None]
    return cells, np.concatenate([me, me + frame["slot_offset_m"]], axis=1)


class LeadTeacher:
    """The leader flies ``leader`` (a single-UAV policy: its layout is v1, or v3 in a fleet with a
    memory of place, v5 in one with a model of the field) on its single-UAV view; every other UAV
    keeps to the far corners (``away``). Fleet only (n_uavs > 1)."""

    name = "lead"
    needs_truth = False
    # The UEs look far while their AoAs spread less than close_spread_deg (a 10 m cluster: ~20 deg
    # from 30 m off) and their mean SINR is below hover + far_sinr_margin_db. Validation (seed 1),
    # teacher / one UAV's policy: straight 98.6 % (seed 2: 98.2 %) with the dash, 96.6 % without,
    # 97.5 % at (10 deg, 0 dB), 97.1 % on the spread alone; no_move 106.1 %, 101 % without.
    close_spread_deg = 20.0
    far_sinr_margin_db = 6.0

    def __init__(self, cfg: EnvConfig, leader: Actor) -> None:
        if cfg.n_uavs < 2:
            raise UserError("the lead teacher is a fleet's (n_uavs > 1)")
        self.layout = ObservationLayout.for_config(cfg)
        own = getattr(leader, "layout", None)
        # a leader without a memory of place (v1) flies in a fleet with one on the v1 fields alone
        self.place = own is None or own.place_cell_m > 0
        self.single = single_layout(self.layout, self.place)
        if own is not None:
            own.check_matches(
                self.single, what=f"the lead teacher's leader {getattr(leader, 'name', leader)!r}"
            )
        self.leader = leader
        # A leader with a model of the field (v5) plans its own way to the team over the episode,
        # searching spots away from it: a dash back would cut its search short (no_move, D = 2, on
        # 100 episodes of seed 1: 9.05 Mbps with the dash, 10.32 without; `python
        # research/fleet_memory_lead.py --scenario no_move --sizes 2 3 4`).
        self.dash = self.single.place_model != PLACE_KRIGING
        self.cfg = cfg
        self.mapping = ActionMapping.for_config(cfg)
        self.hover_sinr_db = hover_sinr_db(cfg)
        self.corners = area_corners_m(cfg)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        index, xy = leader_index(self.layout, obs)
        lead = index == 0
        action = np.empty((len(obs), 2), dtype=np.float32)
        if lead.any():
            action[lead] = self.lead(obs[lead])
        if (~lead).any():
            away = ~lead
            action[away] = self.away(obs[away], xy[away, index[away]])
        return action

    def lead(self, obs: np.ndarray) -> np.ndarray:
        """The leader policy's move on the single-UAV view; but full speed towards the UEs while they
        look far: AoAs spread less than ``close_spread_deg`` and the mean SINR below the hover level
        plus ``far_sinr_margin_db`` (a single UAV starts on top of the UEs: its policy never learned
        to close in from a fleet's start 100 m off, nor to leave a badly shadowed spot far from them); a
        leader with a model of the field is never dashed (``dash``)."""
        frame = self.layout.newest_frame(obs)
        far = (
            self.dash
            & (frame["aoa_std_deg"] < self.close_spread_deg)
            & (frame["sinr_db"].mean(axis=1) < self.hover_sinr_db + self.far_sinr_margin_db)
        )
        dash = self.mapping.from_polar(
            frame["aoa_mean_deg"], np.full(len(obs), self.mapping.r_max_m)
        )
        return np.where(
            far[:, None], dash, self.leader.act(single_view(self.layout, obs, self.place))
        ).astype(np.float32)

    def away(self, obs: np.ndarray, leader_xy_m: np.ndarray) -> np.ndarray:
        """Out of the way: the far corners from the leader (it is with the UEs), ``away_target_m``;
        in a listening fleet (``fleet_reuse = "listen"``) a UAV that does not serve takes no UE
        wherever it flies, so it holds where it is."""
        if self.cfg.fleet_reuse == REUSE_LISTEN:
            return np.zeros((len(obs), 2), dtype=np.float32)
        frame = self.layout.newest_frame(obs)
        me = frame["uav_xy_m"]
        serving = np.asarray(self.layout.own_cell(frame).any(axis=1))
        target = away_target_m(self.corners, me, leader_xy_m, serving)
        return self.mapping.towards(target - me, 1.0).astype(np.float32)


def area_corners_m(cfg: EnvConfig) -> np.ndarray:
    """The area's four corners (4, 2), m."""
    h = cfg.area.half_width_m
    return np.array([[h, h], [-h, h], [-h, -h], [h, -h]])


def away_target_m(
    corners_m: np.ndarray, xy_m: np.ndarray, from_xy_m: np.ndarray, serving: np.ndarray
) -> np.ndarray:
    """Where UAVs at ``xy_m`` (rows, 2) keeping out of the way head (rows, 2): the corner (of
    ``corners_m``, (4, 2)) farthest from ``from_xy_m`` (rows, 2); once there, on to the next farthest
    while their cell still holds a UE (``serving``, (rows,); shadowing can favour a far UAV), else
    where they are: an empty cell is silent."""
    far = np.argsort(-np.linalg.norm(corners_m[None] - from_xy_m[:, None], axis=2), axis=1)
    first, second = corners_m[far[:, 0]], corners_m[far[:, 1]]
    at_first = np.linalg.norm(xy_m - first, axis=1) < 1.0
    target = np.where((at_first & serving)[:, None], second, first)
    return np.where((at_first & ~serving)[:, None], xy_m, target)


def make_lead_teacher(cfg: EnvConfig, leader_policy: str = "") -> LeadTeacher:
    """The lead teacher for fleet ``cfg``; its leader flies ``leader_policy`` (a single-UAV policy
    file, e.g. policies/spatial/<scenario>.zip) or, without one, the single-UAV aoa rule."""
    from uavlink.policies.loader import load_policy  # a policy file may need torch

    # the leader's own world: one UAV, and its own model where the fleet pools one (v9 -> v5)
    place_model = PLACE_KRIGING if cfg.place_model == PLACE_POOLED else cfg.place_model
    single = cfg.replace(n_uavs=1, fleet_slots=0, place_model=place_model).validate()
    return LeadTeacher(
        cfg, load_policy(leader_policy, single) if leader_policy else AoaPolicy(single)
    )
