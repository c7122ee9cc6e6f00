"""``kriging``: a GPS-free rule that flies to the spot its model of the sensed field picks (layout v5;
``uavlink.env.field_model``).

The model, in the observation builder, keeps a Gaussian-process posterior of the value sensed where
(mean over UEs of log2(1 + SINR)) and picks the spot worth most over the frames left, optimistically;
so the rule searches while a look still pays and then stays on the best spot it found. It only reads
the pick from the observation, so a policy that sees the same observation can clone it, and it flies
from MAVLink data like any policy file. Each frame it closes ``approach_gain`` of the distance (r_max
at most): a multicopter trails its setpoint, and a full step to a spot measured from where the
vehicle is overshoots and swings (research/log/memory-of-place.md, "A model of the field"). A model
of a still field: made for a team that stays put (no_move); when the team moves, the field it
modelled goes.
"""

from __future__ import annotations

import numpy as np

from uavlink.config import EnvConfig
from uavlink.config.env import PLACE_KRIGING
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.policies.base import RulePolicy
from uavlink.policies.explore import EXPLORE_PLACE_CELL_M


def kriging_env(cfg: EnvConfig) -> EnvConfig:
    """The env the rule flies in: ``cfg`` with the model of the field (and a memory of place)."""
    cell_m = cfg.place_cell_m if cfg.place_cell_m > 0 else EXPLORE_PLACE_CELL_M
    return cfg.replace(place_cell_m=cell_m, place_model=PLACE_KRIGING).validate()


class KrigingPolicy(RulePolicy):
    """Fly towards the spot the model of the field picks; one UAV."""

    name = "kriging"
    needs_truth = False

    def __init__(self, cfg: EnvConfig, approach_gain: float = 0.4) -> None:
        if cfg.place_model != PLACE_KRIGING or cfg.n_uavs > 1:
            raise UserError(
                "the kriging rule flies one UAV with a model of the field: env.place_model=kriging"
            )
        self.layout = ObservationLayout.for_config(cfg)
        self.mapping = ActionMapping.for_config(cfg)
        self.approach_gain = approach_gain

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        return self.mapping.towards(
            self.layout.newest_frame(obs)["place_pick_offset_m"], self.approach_gain
        )
