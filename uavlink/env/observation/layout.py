"""The observation layout: which fields a frame holds, in which order, and its version (the package's
docstring tells the layouts apart); everything else about the vector follows from the fields."""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from uavlink.config import EnvConfig, fleet_sizes_of
from uavlink.config.env import FIELD_MODELS, PLACE_CELLS, PLACE_POOLED
from uavlink.env.observation.fields import FIELDS, KRIGING_FIELDS, PLACE_FIELDS, Field
from uavlink.env.observation.fleet_view import FLEET_FIELDS, SLOT_FIELDS
from uavlink.errors import UserError
from uavlink.radio.aoa import circular_stats_deg

OBS_LAYOUT_VERSION = 1
FLEET_LAYOUT_VERSION = 2
PLACE_LAYOUT_VERSION = 3  # v1 + the memory of place
FLEET_PLACE_LAYOUT_VERSION = 4  # v2 + the memory of place
KRIGING_LAYOUT_VERSION = 5  # v3 + the model of the sensed field
ANY_FLEET_LAYOUT_VERSION = 6  # v1 + a fleet of any size up to uav_slots + 1 (fleet_view.py)
ANY_FLEET_PLACE_LAYOUT_VERSION = 7  # v6 + the memory of place
ANY_FLEET_KRIGING_LAYOUT_VERSION = 8  # v7 + the model of the sensed field
ANY_FLEET_POOLED_LAYOUT_VERSION = 9  # v8 with one model per fleet, every UAV's readings in it


@dataclass(frozen=True)
class ObservationLayout:
    """Describes the observation vector; a policy file carries it and env and policy must agree.

    The defaults are what a record that omits a field means (``to_dict`` drops n_uavs, the place
    and the model fields where they are off), so they are the layouts' own and not read from
    ``EnvConfig``: a change of the env's defaults must not change what a shipped policy sees."""

    version: int = OBS_LAYOUT_VERSION
    n_ues: int = 10
    n_uavs: int = 1
    memory: int = 4
    half_width_m: float = 200.0
    sinr_offset_db: float = 10.0
    sinr_scale_db: float = 20.0
    sinr_clip_db: tuple[float, float] = (-30.0, 50.0)
    aoa_std_max_rad: float = 2 * np.pi
    place_cell_m: float = 0.0  # the memory of place's grid (0: none; layouts v1 and v2)
    # "kriging": v5 (v8), with the model of the field, which plans over an episode of
    # episode_frames frames at r_max_m a frame (both recorded with a model only); "pooled": v9.
    place_model: str = PLACE_CELLS
    episode_frames: int = 128
    r_max_m: float = 12.0
    uav_slots: int = 0  # v6: the other UAVs' slots (flies fleets of 2 to uav_slots + 1); n_uavs 1

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> ObservationLayout:
        fleet, place = cfg.n_uavs > 1, cfg.place_cell_m > 0
        version = {
            (False, False): OBS_LAYOUT_VERSION,
            (True, False): FLEET_LAYOUT_VERSION,
            (False, True): PLACE_LAYOUT_VERSION,
            (True, True): FLEET_PLACE_LAYOUT_VERSION,
        }[fleet, place]
        kriging = place and cfg.place_model in FIELD_MODELS
        # a fleet of any size has one layout for every size: it records no n_uavs
        if place and cfg.place_model == PLACE_POOLED:
            version = ANY_FLEET_POOLED_LAYOUT_VERSION
        elif kriging:
            version = (
                ANY_FLEET_KRIGING_LAYOUT_VERSION if cfg.fleet_slots > 0 else KRIGING_LAYOUT_VERSION
            )
        elif cfg.fleet_slots > 0:
            version = ANY_FLEET_PLACE_LAYOUT_VERSION if place else ANY_FLEET_LAYOUT_VERSION
        return cls(
            version=version,
            n_ues=cfg.n_ues,
            n_uavs=1 if cfg.fleet_slots > 0 else cfg.n_uavs,
            uav_slots=cfg.fleet_slots,
            memory=cfg.memory,
            half_width_m=cfg.area.half_width_m,
            place_cell_m=float(cfg.place_cell_m),
            place_model=cfg.place_model if kriging else PLACE_CELLS,
            episode_frames=cfg.episode_frames if kriging else cls.episode_frames,
            r_max_m=cfg.r_max_m if kriging else cls.r_max_m,
        )

    @property
    def fields(self) -> tuple[Field, ...]:
        fields = FIELDS if self.n_uavs == 1 else FIELDS + FLEET_FIELDS
        fields = fields + SLOT_FIELDS if self.uav_slots > 0 else fields
        fields = fields + PLACE_FIELDS if self.place_cell_m > 0 else fields
        return fields + KRIGING_FIELDS if self.models_field else fields

    @property
    def models_field(self) -> bool:
        """Whether a frame carries a model of the sensed field's pick (v5, v8, v9)."""
        return self.place_model in FIELD_MODELS

    @functools.cached_property
    def slices(self) -> dict[str, slice]:
        """Each field's columns within a frame, by quantity."""
        out, start = {}, 0
        for field in self.fields:
            out[field.quantity] = slice(start, start + field.width(self))
            start += field.width(self)
        return out

    @functools.cached_property
    def frame_size(self) -> int:
        """Columns of one frame; cached, as every step reads it and each field counts its names."""
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
        return (
            np.tile(np.array(low, np.float32), self.memory),
            np.tile(np.array(high, np.float32), self.memory),
        )

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["sinr_clip_db"] = list(self.sinr_clip_db)
        if self.n_uavs == 1:  # a single UAV's record stays what it has always been
            del data["n_uavs"]
        if self.place_cell_m == 0:  # so does a record without a memory of place
            del data["place_cell_m"]
        if self.place_model == PLACE_CELLS:  # and one without a model of the field
            del data["place_model"], data["episode_frames"], data["r_max_m"]
        if self.uav_slots == 0:  # and one for a fleet of a given size
            del data["uav_slots"]
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ObservationLayout:
        data = dict(data)
        data["sinr_clip_db"] = tuple(data.get("sinr_clip_db", cls.sinr_clip_db))
        return cls(**data)

    def check_matches(self, other: ObservationLayout, what: str = "policy") -> None:
        """Raise a one-line UserError naming both layouts when they differ."""
        if self != other:
            raise UserError(
                f"observation layout mismatch: {what} expects {self.describe()}, "
                f"env provides {other.describe()}"
            )

    def describe(self) -> str:
        fleet = f"n_uavs={self.n_uavs}, " if self.n_uavs > 1 else ""
        fleet += (
            f"uav_slots={self.uav_slots} (fleets of {_span(fleet_sizes_of(self.uav_slots))}), "
            if self.uav_slots > 0
            else ""
        )
        fleet += f"place_cell_m={self.place_cell_m:g}, " if self.place_cell_m > 0 else ""
        fleet += (
            f"place_model={self.place_model}, episode_frames={self.episode_frames}, "
            f"r_max_m={self.r_max_m:g}, "
            if self.models_field
            else ""
        )
        return (
            f"v{self.version} ({fleet}n_ues={self.n_ues}, memory={self.memory}, "
            f"half_width_m={self.half_width_m:g}, size={self.size})"
        )

    def encode_frame(
        self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray, **extra: np.ndarray
    ) -> np.ndarray:
        """One frame's features (rows, frame_size) from UAV position (rows, 2), SINR and AoA
        (rows, U) as each row's UAV senses them, for a fleet ``others_xy_m`` (rows, D-1, 2)
        and ``served_by`` (rows, U) (see :func:`fleet_quantities`), and with a memory of place
        its quantities (``PlaceMemory.update``)."""
        rad = np.radians(aoa_deg)
        sin, cos = np.sin(rad), np.cos(rad)  # shared by every AoA statistic below
        aoa_mean_deg, aoa_std_deg = circular_stats_deg(sin, cos)
        quantities = {
            "uav_xy_m": uav_xy_m,
            "sinr_db": sinr_db,
            "aoa_mean_deg": aoa_mean_deg,
            "aoa_std_deg": aoa_std_deg,
            **extra,
        }
        if self.is_fleet:  # the AoA statistics of the UEs this UAV serves (none: undefined)
            quantities["cell_aoa_mean_deg"], quantities["cell_aoa_std_deg"] = circular_stats_deg(
                sin, cos, mask=self.own_cell(extra)
            )
        return np.concatenate([field.encode(self, quantities) for field in self.fields], axis=1)

    @property
    def is_fleet(self) -> bool:
        """Whether a frame shows a fleet (v2's fields, or v6's of any size)."""
        return self.n_uavs > 1 or self.uav_slots > 0

    @staticmethod
    def own_cell(quantities: dict[str, np.ndarray]) -> np.ndarray:
        """Which UEs each row's UAV serves (rows, U) bool, from a fleet's quantities, encoded or
        decoded: v6's ``served_here``, v2's ``served_by``."""
        if "served_here" in quantities:
            return np.asarray(quantities["served_here"]) > 0.5
        return np.asarray(quantities["served_by"]) == 0

    def frames(self, obs: np.ndarray) -> np.ndarray:
        """Observations (N, size) as (N, memory, frame_size) float64, newest frame first."""
        return obs.reshape(obs.shape[0], self.memory, self.frame_size).astype(float)

    def _field(self, quantity: str) -> Field:
        """The field carrying ``quantity``; KeyError naming this layout's quantities if none does."""
        for field in self.fields:
            if field.quantity == quantity:
                return field
        raise KeyError(
            f"no quantity {quantity!r} in observation layout {self.describe()}; "
            f"its quantities: {', '.join(self.slices)}"
        )

    def history(self, obs: np.ndarray, quantity: str) -> np.ndarray:
        """A field decoded from every frame of observations (N, size): (N, memory, ...), newest first."""
        return self._field(quantity).decode(self, self.frames(obs)[:, :, self.slices[quantity]])

    def encoded_history(self, obs: np.ndarray, *quantities: str) -> np.ndarray:
        """Fields as encoded (N, memory, widths summed), newest frame first."""
        frames, slices = self.frames(obs), self.slices
        return np.concatenate(
            [frames[:, :, slices[self._field(q).quantity]] for q in quantities], axis=2
        )

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
        return {
            field.quantity: field.decode(self, frame[:, self.slices[field.quantity]])
            for field in self.fields
        }


def _span(sizes: range) -> str:
    """``2-4`` for the sizes 2, 3 and 4."""
    return f"{sizes[0]}-{sizes[-1]}"
