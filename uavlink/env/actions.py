"""Mapping from the policy's Box(-1, 1, (2,)) output to an (angle, distance) move."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from uavlink.config.env import ACTION_MAPPINGS
from uavlink.errors import ConfigError
from uavlink.radio.aoa import wrap_deg

if TYPE_CHECKING:
    from uavlink.config import EnvConfig

CARTESIAN, POLAR = ACTION_MAPPINGS


@dataclass(frozen=True)
class ActionMapping:
    """How the policy's a = (a0, a1) in [-1, 1]^2 becomes an (angle, distance) move.

    ``cartesian-v1`` (default): a is the move as a fraction of r_max, east and north:
        angle = atan2(a1, a0), distance = r_max min(1, |a|).
    ``polar-v1`` (the paper's literal reading): angle = 180 a0 degrees, distance = r_max (a1 + 1) / 2.
    Both reach every move of the SPEC's action set. Cartesian is the default because it is
    continuous: heading for an AoA of +179 or -179 degrees takes nearly the same output, whereas
    the polar angle jumps from +1 to -1 there, which an MLP policy learns slowly (measured in
    docs/design/learning.md). Saved in every policy manifest.
    """

    r_max_m: float = 12.0
    kind: str = CARTESIAN

    def __post_init__(self) -> None:
        if self.kind not in ACTION_MAPPINGS:
            raise ConfigError(
                f"unknown action mapping {self.kind!r}; choose from {', '.join(ACTION_MAPPINGS)}"
            )

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> ActionMapping:
        """The mapping an env config asks for (``r_max_m``, ``action_mapping``)."""
        return cls(cfg.r_max_m, cfg.action_mapping)

    def validate(self, action: np.ndarray, rows: int) -> np.ndarray:
        """Check shape (rows, 2), a row per agent (env x UAV), and finiteness, then clip into the box."""
        action = np.asarray(action, dtype=float)
        if action.shape != (rows, 2):
            raise ValueError(
                f"action must have shape ({rows}, 2), one row per agent, got {action.shape}"
            )
        if not np.isfinite(action).all():
            raise ValueError("action contains NaN or infinity")
        return np.clip(action, -1.0, 1.0)

    def to_polar(self, action: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(angle_deg, distance_m) for clipped actions (N, 2)."""
        if self.kind == POLAR:
            angle_deg = wrap_deg(180.0 * action[:, 0])
            distance_m = self.r_max_m * (action[:, 1] + 1.0) / 2.0
        else:
            angle_deg = wrap_deg(np.degrees(np.arctan2(action[:, 1], action[:, 0])))
            distance_m = self.r_max_m * np.minimum(1.0, np.hypot(action[:, 0], action[:, 1]))
        return angle_deg, distance_m

    def to_displacement_m(self, action: np.ndarray) -> np.ndarray:
        """(N, 2) east/north displacement in metres."""
        angle_deg, distance_m = self.to_polar(action)
        rad = np.radians(angle_deg)
        return distance_m[:, None] * np.stack([np.cos(rad), np.sin(rad)], axis=1)

    def from_polar(
        self, angle_deg: float | np.ndarray, distance_m: float | np.ndarray
    ) -> np.ndarray:
        """Inverse mapping, for rule-based policies that think in angles and metres."""
        fraction = np.clip(np.asarray(distance_m) / self.r_max_m, 0.0, 1.0)
        if self.kind == POLAR:
            a0 = wrap_deg(angle_deg) / 180.0
            return np.stack([a0, 2.0 * fraction - 1.0], axis=-1)
        rad = np.radians(angle_deg)
        return np.stack([fraction * np.cos(rad), fraction * np.sin(rad)], axis=-1)

    def towards(self, offset_m: np.ndarray, share: float | np.ndarray) -> np.ndarray:
        """The action that closes ``share`` of the way to spots at ``offset_m`` (rows, 2), r_max at
        most: a vehicle trails its setpoint, so a rule that steps the whole way from where the
        vehicle is overshoots and swings (docs/design/baselines.md, "explore")."""
        offset_m = np.asarray(offset_m)
        return self.from_polar(
            np.degrees(np.arctan2(offset_m[:, 1], offset_m[:, 0])),
            share * np.hypot(offset_m[:, 0], offset_m[:, 1]),
        )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ActionMapping:
        return cls(**data)
