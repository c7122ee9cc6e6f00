"""``explore``: a GPS-free rule that searches, goes back to the best spot it sensed, and searches
again when the team has left (SPEC "The limit, and a memory of place").

It reads only the observation with a memory of place (layout v3, v4 for a fleet: the UAV's own
position and what it sensed where, ``uavlink.env.place_memory``), so it flies from MAVLink data like
any policy file, and a policy that sees the same observation can clone it. Per UAV row:

1. search: the first 8 ``search_leg_frames`` frames fly a cross through the start at full speed,
   sensing a new spot every frame: a leg east, two west, one back east, then the same north-south
   (4 frames a leg: 48 m either side, 32 frames);
2. then fly towards the best remembered spot (ranked with its age, so stale spots lose) whenever it
   beats what the UAV senses now by more than ``margin_bits``, and hover otherwise; each frame it
   closes ``approach_gain`` of the distance (r_max at most): a vehicle trails its target, and a
   full step towards a spot measured from where the vehicle is overshoots and swings in flight; a spot that fell below
   what was remembered is overwritten when the UAV senses it there, so the next-best spot wins;
3. search again: when the team has left (the mean SINR more than ``follow_gap_db`` below the hover
   level, as the aoa rule measures it), follow the aoa rule (per cell for a fleet), sensing new
   spots on the way; back near the team the remembered best spots pull it again.
"""

from __future__ import annotations

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.policies.base import RulePolicy
from uavlink.policies.baselines import AoaPolicy
from uavlink.policies.fleet_baselines import FleetAoaPolicy

# The memory of place explore gets when its env has none (a cell = one frame's longest move).
EXPLORE_PLACE_CELL_M = 12.0


def explore_env(cfg: EnvConfig) -> EnvConfig:
    """The env explore flies in: ``cfg`` with a memory of place (``cfg``'s own grid if it has one)."""
    return cfg if cfg.place_cell_m > 0 else cfg.replace(place_cell_m=EXPLORE_PLACE_CELL_M)


class ExplorePolicy(RulePolicy):
    """Search, go back to the best spot sensed, search again when the team leaves; one UAV or a fleet."""

    name = "explore"
    needs_truth = False

    def __init__(
        self,
        cfg: EnvConfig,
        search_leg_frames: int = 4,
        margin_bits: float = 0.05,
        follow_gap_db: float = 10.0,
        approach_gain: float = 0.5,
    ) -> None:
        if cfg.place_cell_m <= 0:
            raise UserError("the explore rule needs a memory of place: set env.place_cell_m > 0")
        self.layout = ObservationLayout.for_config(cfg)
        self.mapping = ActionMapping.for_config(cfg)
        self.follow = (
            FleetAoaPolicy(cfg) if cfg.n_uavs > 1 else AoaPolicy(cfg)
        )  # the aoa rule, per cell
        self.search_leg_frames = int(search_leg_frames)
        self.search_frames = 8 * self.search_leg_frames
        self.margin_bits = margin_bits
        self.follow_gap_db = follow_gap_db
        self.approach_gain = approach_gain

    def _sinr_gap_db(self, frame: dict[str, np.ndarray]) -> np.ndarray:
        """How far the mean SINR (of the row's own cell, in a fleet) is below the hover level, dB."""
        if isinstance(self.follow, FleetAoaPolicy):
            return self.follow.sinr_gap_db(frame)
        return self.follow.hover_sinr_db - frame["sinr_db"].mean(axis=1)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        frame = self.layout.newest_frame(obs)
        index = np.rint(frame["place_frames"]).astype(int) - 1  # frames flown this episode
        r_max = self.mapping.r_max_m
        # 1. the search cross: out one leg, back two, out one; east-west, then north-south.
        leg = self.search_leg_frames
        out = (index % (4 * leg) < leg) | (index % (4 * leg) >= 3 * leg)
        heading = np.where(index < 4 * leg, np.where(out, 0.0, 180.0), np.where(out, 90.0, -90.0))
        search = self.mapping.from_polar(heading, np.full(len(index), r_max))
        # 2. the best remembered spot, when it is worth going to.
        go = frame["place_best_gain_bits"] > self.margin_bits
        to_best = self.mapping.towards(
            frame["place_best_offset_m"], np.where(go, self.approach_gain, 0.0)
        )
        # 3. follow the team when it has left.
        follow = self._sinr_gap_db(frame) > self.follow_gap_db
        action = np.where(follow[:, None], self.follow.act(obs), to_best)
        return np.where((index < self.search_frames)[:, None], search, action)
