"""The observation: what the base station senses, stacked over the last M frames.

One piece of code, shared by the env and the flight loop. A frame is the fields of ``FIELDS`` in
order, declared once with their encoding, decoding and bounds (newest frame first in the vector):
  UAV x, y / half-width; per-UE effective SINR, (dB - offset) / scale, clipped;
  sin and cos of the circular-mean AoA; circular std of the AoAs (radians / pi, at most 2).
Never UE positions. The layout is versioned and saved with every policy; the frame's size, the
feature names, the bounds, the slices and the decoders all follow from the table, so adding a field
is one entry (and a new version).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from uavlink.config import EnvConfig
from uavlink.errors import UserError
from uavlink.radio.aoa import circular_mean_std_deg

OBS_LAYOUT_VERSION = 1


@dataclass(frozen=True)
class Field:
    """One field of a frame: the physical ``quantity`` it carries, its feature ``labels`` (one per
    UE, numbered, when ``per_ue``), and how the layout encodes, decodes and bounds it.

    ``encode(layout, quantities)`` gives (N, width) from the frame's quantities (N, ...) by name;
    ``decode(layout, encoded)`` turns encoded values (..., width) back into the quantity (a width-1
    field drops the last axis); ``bounds(layout)`` is the encoded (low, high) of every column.
    """

    quantity: str
    labels: tuple[str, ...]
    encode: Callable[[ObservationLayout, Mapping[str, np.ndarray]], np.ndarray]
    decode: Callable[[ObservationLayout, np.ndarray], np.ndarray]
    bounds: Callable[[ObservationLayout], tuple[float, float]]
    per_ue: bool = False

    def width(self, layout: ObservationLayout) -> int:
        return layout.n_ues if self.per_ue else len(self.labels)

    def names(self, layout: ObservationLayout) -> list[str]:
        return [f"{self.labels[0]}_{u}" for u in range(layout.n_ues)] if self.per_ue else list(self.labels)


def _sinr_bounds(layout: ObservationLayout) -> tuple[float, float]:
    lo_db, hi_db = layout.sinr_clip_db
    return ((lo_db - layout.sinr_offset_db) / layout.sinr_scale_db, (hi_db - layout.sinr_offset_db) / layout.sinr_scale_db)


FIELDS: tuple[Field, ...] = (
    Field("uav_xy_m", ("uav_x", "uav_y"),
          encode=lambda layout, q: q["uav_xy_m"] / layout.half_width_m,
          decode=lambda layout, x: x * layout.half_width_m,
          bounds=lambda layout: (-1.0, 1.0)),
    Field("sinr_db", ("sinr",), per_ue=True,
          encode=lambda layout, q: (np.clip(q["sinr_db"], *layout.sinr_clip_db) - layout.sinr_offset_db) / layout.sinr_scale_db,
          decode=lambda layout, x: x * layout.sinr_scale_db + layout.sinr_offset_db,
          bounds=_sinr_bounds),
    Field("aoa_mean_deg", ("aoa_mean_sin", "aoa_mean_cos"),
          encode=lambda layout, q: np.stack([np.sin(np.radians(q["aoa_mean_deg"])),
                                             np.cos(np.radians(q["aoa_mean_deg"]))], axis=1),
          decode=lambda layout, x: np.degrees(np.arctan2(x[..., 0], x[..., 1])),
          bounds=lambda layout: (-1.0, 1.0)),
    Field("aoa_std_deg", ("aoa_std",),
          encode=lambda layout, q: np.minimum(np.radians(q["aoa_std_deg"]), layout.aoa_std_max_rad)[:, None] / np.pi,
          decode=lambda layout, x: np.degrees(x[..., 0] * np.pi),
          bounds=lambda layout: (0.0, layout.aoa_std_max_rad / np.pi)),
)


@dataclass(frozen=True)
class ObservationLayout:
    """Describes the observation vector; a policy file carries it and env and policy must agree."""

    fields: ClassVar[tuple[Field, ...]] = FIELDS

    version: int = OBS_LAYOUT_VERSION
    n_ues: int = 10
    memory: int = 4
    half_width_m: float = 200.0
    sinr_offset_db: float = 10.0
    sinr_scale_db: float = 20.0
    sinr_clip_db: tuple[float, float] = (-30.0, 50.0)
    aoa_std_max_rad: float = 2 * np.pi

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> ObservationLayout:
        return cls(n_ues=cfg.n_ues, memory=cfg.memory, half_width_m=cfg.area.half_width_m)

    @functools.cached_property
    def slices(self) -> dict[str, slice]:
        """Each field's columns within a frame, by quantity."""
        out, start = {}, 0
        for field in self.fields:
            out[field.quantity] = slice(start, start + field.width(self))
            start += field.width(self)
        return out

    @property
    def frame_size(self) -> int:
        return sum(field.width(self) for field in self.fields)

    @property
    def size(self) -> int:
        return self.memory * self.frame_size

    def feature_names(self) -> list[str]:
        frame = [name for field in self.fields for name in field.names(self)]
        return [f"t-{lag}:{name}" for lag in range(self.memory) for name in frame]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-feature (low, high) of the observation vector, float32."""
        low, high = [], []
        for field in self.fields:
            lo, hi = field.bounds(self)
            low += [lo] * field.width(self)
            high += [hi] * field.width(self)
        return (np.tile(np.array(low, np.float32), self.memory), np.tile(np.array(high, np.float32), self.memory))

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["sinr_clip_db"] = list(self.sinr_clip_db)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ObservationLayout:
        data = dict(data)
        data["sinr_clip_db"] = tuple(data.get("sinr_clip_db", cls.sinr_clip_db))
        return cls(**data)

    def check_matches(self, other: ObservationLayout, what: str = "policy") -> None:
        """Raise a one-line UserError naming both layouts when they differ."""
        if self != other:
            raise UserError(f"observation layout mismatch: {what} expects {self.describe()}, "
                             f"env provides {other.describe()}")

    def describe(self) -> str:
        return (f"v{self.version} (n_ues={self.n_ues}, memory={self.memory}, "
                f"half_width_m={self.half_width_m:g}, size={self.size})")

    def encode_frame(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        """One frame's features (N, frame_size) from UAV position (N, 2), SINR and AoA (N, U)."""
        aoa_mean_deg, aoa_std_deg = circular_mean_std_deg(aoa_deg)
        quantities = {"uav_xy_m": uav_xy_m, "sinr_db": sinr_db, "aoa_mean_deg": aoa_mean_deg,
                      "aoa_std_deg": aoa_std_deg}
        return np.concatenate([field.encode(self, quantities) for field in self.fields], axis=1)

    def frames(self, obs: np.ndarray) -> np.ndarray:
        """Observations (N, size) as (N, memory, frame_size) float64, newest frame first."""
        return obs.reshape(obs.shape[0], self.memory, self.frame_size).astype(float)

    def _field(self, quantity: str) -> Field:
        return next(field for field in self.fields if field.quantity == quantity)

    def history(self, obs: np.ndarray, quantity: str) -> np.ndarray:
        """A field decoded from every frame of observations (N, size): (N, memory, ...), newest first."""
        return self._field(quantity).decode(self, self.frames(obs)[:, :, self.slices[quantity]])

    def encoded_history(self, obs: np.ndarray, *quantities: str) -> np.ndarray:
        """Fields as encoded (N, memory, widths summed), newest frame first."""
        frames, slices = self.frames(obs), self.slices
        return np.concatenate([frames[:, :, slices[q]] for q in quantities], axis=2)

    def sinr_db_history(self, obs: np.ndarray) -> np.ndarray:
        """Per-UE SINRs (N, memory, U) in dB, newest frame first, decoded from observations (N, size)."""
        return self.history(obs, "sinr_db")

    def uav_xy_m_history(self, obs: np.ndarray) -> np.ndarray:
        """UAV positions (N, memory, 2) in m, newest frame first."""
        return self.history(obs, "uav_xy_m")

    def aoa_feature_history(self, obs: np.ndarray) -> np.ndarray:
        """The encoded AoA features (N, memory, 3): sin and cos of the circular mean, scaled std."""
        return self.encoded_history(obs, "aoa_mean_deg", "aoa_std_deg")

    def newest_frame(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """Decode the newest frame of observations (N, size) back to physical units, by quantity."""
        frame = obs[:, : self.frame_size].astype(float)
        return {field.quantity: field.decode(self, frame[:, self.slices[field.quantity]]) for field in self.fields}


class ObservationBuilder:
    """Keeps the last M frames per env and returns the flattened observation (N, size), float32."""

    def __init__(self, layout: ObservationLayout, n_envs: int) -> None:
        self.layout = layout
        self._history = np.zeros((n_envs, layout.memory, layout.frame_size), dtype=np.float32)

    def reset(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        """Start a new episode: every memory slot holds the first frame."""
        self._history[:] = self.layout.encode_frame(uav_xy_m, sinr_db, aoa_deg)[:, None, :]
        return self.observation()

    def push(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        self._history[:, 1:] = self._history[:, :-1]
        self._history[:, 0] = self.layout.encode_frame(uav_xy_m, sinr_db, aoa_deg)
        return self.observation()

    def observation(self) -> np.ndarray:
        return self._history.reshape(self._history.shape[0], -1).copy()
