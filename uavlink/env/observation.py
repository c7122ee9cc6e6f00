"""The observation: what the base station senses, stacked over the last M frames.

One piece of code, shared by the env and the flight loop. A frame is the fields of ``FIELDS`` in
order, declared once with their encoding, decoding and bounds (newest frame first in the vector):
  UAV x, y / half-width; per-UE effective SINR, (dB - offset) / scale, clipped;
  sin and cos of the circular-mean AoA; circular std of the AoAs (radians / pi, at most 2).
Never UE positions. A fleet's UAV (layout v2, ``n_uavs`` > 1) sees the same fields from where it
is (every UE's uplink reference signal as it hears it) plus what the fleet shares over its own
links (``FLEET_FIELDS``): the other UAVs' positions, the AoA statistics of the UEs it serves (its
cell; (0, 0) and the largest std for an empty cell) and which UAV serves each UE, numbered from the
observing UAV (0 = itself, then the next ones in fleet order), so every UAV has the same layout and
one policy serves them all. The layout is versioned and saved with every policy; the frame's size,
the feature names, the bounds, the slices and the decoders all follow from the tables, so adding a
field is one entry (and a new version). With a memory of place (``place_cell_m`` > 0; layout v3,
v4 for a fleet) every frame also carries ``PLACE_FIELDS``: a summary of what the UAV sensed where
(``uavlink.env.place_memory``), kept by the builder, so env and flight build it with the same code.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from uavlink.config import EnvConfig
from uavlink.errors import UserError
from uavlink.radio.aoa import circular_stats_deg

OBS_LAYOUT_VERSION = 1
FLEET_LAYOUT_VERSION = 2
PLACE_LAYOUT_VERSION = 3  # v1 + the memory of place
FLEET_PLACE_LAYOUT_VERSION = 4  # v2 + the memory of place
KRIGING_LAYOUT_VERSION = 5  # v3 + the model of the sensed field
PLACE_GAIN_CLIP_BITS = 4.0  # a remembered spot's value minus now, bits/s/Hz, clipped
PLACE_AGE_SCALE_FRAMES = 128.0  # ages and the memory's length in episodes of 128 frames, at most 2


@dataclass(frozen=True)
class Field:
    """One field of a frame: the physical ``quantity`` it carries, its feature ``labels``, and how the
    layout encodes, decodes and bounds it. ``per`` repeats the labels: ``"frame"`` once, ``"ue"``
    per UE, ``"other_uav"`` per other UAV, ``"ue_uav"`` per UE and UAV (numbered in the names).

    ``encode(layout, quantities)`` gives (N, width) from the frame's quantities (N, ...) by name;
    ``decode(layout, encoded)`` turns encoded values (..., width) back into the quantity (a width-1
    field drops the last axis); ``bounds(layout)`` is the encoded (low, high) of every column.
    """

    quantity: str
    labels: tuple[str, ...]
    encode: Callable[[ObservationLayout, Mapping[str, np.ndarray]], np.ndarray]
    decode: Callable[[ObservationLayout, np.ndarray], np.ndarray]
    bounds: Callable[[ObservationLayout], tuple[float, float]]
    per: str = "frame"

    def width(self, layout: ObservationLayout) -> int:
        return len(self.names(layout))

    def names(self, layout: ObservationLayout) -> list[str]:
        ues, others, uavs = range(layout.n_ues), range(1, layout.n_uavs), range(layout.n_uavs)
        return {
            "frame": list(self.labels),
            "ue": [f"{label}_{u}" for u in ues for label in self.labels],
            "other_uav": [f"{label}_{j}" for j in others for label in self.labels],
            "ue_uav": [f"{label}_{u}_{j}" for u in ues for j in uavs for label in self.labels],
        }[self.per]


def _sinr_bounds(layout: ObservationLayout) -> tuple[float, float]:
    lo_db, hi_db = layout.sinr_clip_db
    return (
        (lo_db - layout.sinr_offset_db) / layout.sinr_scale_db,
        (hi_db - layout.sinr_offset_db) / layout.sinr_scale_db,
    )


def _aoa_fields(prefix: str) -> tuple[Field, Field]:
    """The circular mean (its sin and cos) and the circular std of a set of AoAs, as fields
    ``<prefix>_mean_deg`` and ``<prefix>_std_deg``: every UE's (``aoa``) or one cell's (``cell_aoa``)."""
    mean, std = f"{prefix}_mean_deg", f"{prefix}_std_deg"
    return (
        Field(
            mean,
            (f"{prefix}_mean_sin", f"{prefix}_mean_cos"),
            encode=lambda layout, q: _unit_vector(q[mean]),
            decode=lambda layout, x: np.degrees(np.arctan2(x[..., 0], x[..., 1])),
            bounds=lambda layout: (-1.0, 1.0),
        ),
        Field(
            std,
            (f"{prefix}_std",),
            encode=lambda layout, q: (
                np.minimum(np.radians(q[std]), layout.aoa_std_max_rad)[:, None] / np.pi
            ),
            decode=lambda layout, x: np.degrees(x[..., 0] * np.pi),
            bounds=lambda layout: (0.0, layout.aoa_std_max_rad / np.pi),
        ),
    )


def _unit_vector(angle_deg: np.ndarray) -> np.ndarray:
    """(sin, cos) of angles (N,) -> (N, 2); an undefined (NaN) angle, an empty cell's, is (0, 0)."""
    rad = np.radians(angle_deg)
    unit = np.stack([np.sin(rad), np.cos(rad)], axis=1)
    return np.where(np.isnan(unit), 0.0, unit)


FIELDS: tuple[Field, ...] = (
    Field(
        "uav_xy_m",
        ("uav_x", "uav_y"),
        encode=lambda layout, q: q["uav_xy_m"] / layout.half_width_m,
        decode=lambda layout, x: x * layout.half_width_m,
        bounds=lambda layout: (-1.0, 1.0),
    ),
    Field(
        "sinr_db",
        ("sinr",),
        per="ue",
        encode=lambda layout, q: (
            (np.clip(q["sinr_db"], *layout.sinr_clip_db) - layout.sinr_offset_db)
            / layout.sinr_scale_db
        ),
        decode=lambda layout, x: x * layout.sinr_scale_db + layout.sinr_offset_db,
        bounds=_sinr_bounds,
    ),
    *_aoa_fields("aoa"),
)


FLEET_FIELDS: tuple[Field, ...] = (
    Field(
        "others_xy_m",
        ("other_x", "other_y"),
        per="other_uav",
        encode=lambda layout, q: (
            q["others_xy_m"].reshape(len(q["others_xy_m"]), -1) / layout.half_width_m
        ),
        decode=lambda layout, x: x.reshape(*x.shape[:-1], -1, 2) * layout.half_width_m,
        bounds=lambda layout: (-1.0, 1.0),
    ),
    *_aoa_fields("cell_aoa"),
    Field(
        "served_by",
        ("served_by",),
        per="ue_uav",
        encode=lambda layout, q: (
            (q["served_by"][..., None] == np.arange(layout.n_uavs))
            .reshape(len(q["served_by"]), -1)
            .astype(np.float32)
        ),
        decode=lambda layout, x: x.reshape(*x.shape[:-1], layout.n_ues, layout.n_uavs).argmax(
            axis=-1
        ),
        bounds=lambda layout: (0.0, 1.0),
    ),
)


def _scaled_frames(quantity: str, label: str) -> Field:
    return Field(
        quantity,
        (label,),
        encode=lambda layout, q: (
            np.minimum(q[quantity], 2 * PLACE_AGE_SCALE_FRAMES)[:, None] / PLACE_AGE_SCALE_FRAMES
        ),
        decode=lambda layout, x: x[..., 0] * PLACE_AGE_SCALE_FRAMES,
        bounds=lambda layout: (0.0, 2.0),
    )


def _gain_bits(quantity: str, labels: tuple[str, ...]) -> Field:
    def encode(layout: ObservationLayout, q: Mapping[str, np.ndarray]) -> np.ndarray:
        value = np.maximum(
            q[quantity], -PLACE_GAIN_CLIP_BITS
        )  # np.clip's values, without its overhead
        np.minimum(value, PLACE_GAIN_CLIP_BITS, out=value)
        return value.reshape(len(value), -1)

    return Field(
        quantity,
        labels,
        encode=encode,
        decode=lambda layout, x: x[..., 0] if len(labels) == 1 else x,
        bounds=lambda layout: (-PLACE_GAIN_CLIP_BITS, PLACE_GAIN_CLIP_BITS),
    )


def _offset_m(quantity: str, labels: tuple[str, str]) -> Field:
    """A spot's offset from the UAV (m), in half-widths: within the area, at most 2."""
    return Field(
        quantity,
        labels,
        encode=lambda layout, q: q[quantity] / layout.half_width_m,
        decode=lambda layout, x: x * layout.half_width_m,
        bounds=lambda layout: (-2.0, 2.0),
    )


PLACE_FIELDS: tuple[Field, ...] = (
    _offset_m("place_best_offset_m", ("place_best_dx", "place_best_dy")),
    _gain_bits("place_best_gain_bits", ("place_best_gain",)),
    _scaled_frames("place_best_age_frames", "place_best_age"),
    _scaled_frames("place_frames", "place_frames"),
    _gain_bits(
        "place_neighbour_gain_bits",
        ("place_east_gain", "place_north_gain", "place_west_gain", "place_south_gain"),
    ),
    Field(
        "place_neighbour_known",
        ("place_east_known", "place_north_known", "place_west_known", "place_south_known"),
        encode=lambda layout, q: q["place_neighbour_known"],
        decode=lambda layout, x: x,
        bounds=lambda layout: (0.0, 1.0),
    ),
)

# The model of the sensed field (layout v5, uavlink/env/field_model.py): the spot it picks, from the
# UAV (m), its posterior mean minus the value now and its posterior std (bits/s/Hz).
KRIGING_FIELDS: tuple[Field, ...] = (
    _offset_m("place_pick_offset_m", ("place_pick_dx", "place_pick_dy")),
    _gain_bits("place_pick_gain_bits", ("place_pick_gain",)),
    _gain_bits("place_pick_std_bits", ("place_pick_std",)),
)


def fleet_quantities(uav_xy_m: np.ndarray, serving: np.ndarray) -> dict[str, np.ndarray]:
    """What a fleet shares, as each UAV sees it, rows (N D) in fleet order: ``others_xy_m``
    (N D, D-1, 2), the other UAVs in the order d+1, d+2, ... (wrapping), and ``served_by``
    (N D, U), the index of each UE's UAV counted from the observing one. ``uav_xy_m`` (N, D, 2),
    ``serving`` (N, U)."""
    n_envs, n_uavs = uav_xy_m.shape[:2]
    me = np.arange(n_uavs)
    order = (me[:, None] + np.arange(1, n_uavs)) % n_uavs  # (D, D-1)
    others = uav_xy_m[:, order]  # (N, D, D-1, 2)
    served_by = (serving[:, None, :] - me[None, :, None]) % n_uavs  # (N, D, U)
    return {
        "others_xy_m": others.reshape(n_envs * n_uavs, n_uavs - 1, 2),
        "served_by": served_by.reshape(n_envs * n_uavs, -1),
    }


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
    place_model: str = "cells"  # "kriging": v5, with the model of the field, which plans over an
    episode_frames: int = 128  # episode of this many frames at this longest move a frame (recorded
    r_max_m: float = 12.0  # for v5 only)

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> ObservationLayout:
        fleet, place = cfg.n_uavs > 1, cfg.place_cell_m > 0
        version = {
            (False, False): OBS_LAYOUT_VERSION,
            (True, False): FLEET_LAYOUT_VERSION,
            (False, True): PLACE_LAYOUT_VERSION,
            (True, True): FLEET_PLACE_LAYOUT_VERSION,
        }[fleet, place]
        kriging = place and cfg.place_model == "kriging"
        return cls(
            version=KRIGING_LAYOUT_VERSION if kriging else version,
            n_ues=cfg.n_ues,
            n_uavs=cfg.n_uavs,
            memory=cfg.memory,
            half_width_m=cfg.area.half_width_m,
            place_cell_m=float(cfg.place_cell_m),
            place_model=cfg.place_model if kriging else "cells",
            episode_frames=cfg.episode_frames if kriging else cls.episode_frames,
            r_max_m=cfg.r_max_m if kriging else cls.r_max_m,
        )

    @property
    def fields(self) -> tuple[Field, ...]:
        fields = FIELDS if self.n_uavs == 1 else FIELDS + FLEET_FIELDS
        fields = fields + PLACE_FIELDS if self.place_cell_m > 0 else fields
        return fields + KRIGING_FIELDS if self.place_model == "kriging" else fields

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
        if self.place_model == "cells":  # and one without a model of the field
            del data["place_model"], data["episode_frames"], data["r_max_m"]
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
        fleet += f"place_cell_m={self.place_cell_m:g}, " if self.place_cell_m > 0 else ""
        fleet += (
            f"place_model=kriging, episode_frames={self.episode_frames}, r_max_m={self.r_max_m:g}, "
            if self.place_model == "kriging"
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
        if (
            "served_by" in extra
        ):  # the AoA statistics of the UEs this UAV serves (undefined for an empty cell)
            quantities["cell_aoa_mean_deg"], quantities["cell_aoa_std_deg"] = circular_stats_deg(
                sin, cos, mask=extra["served_by"] == 0
            )
        return np.concatenate([field.encode(self, quantities) for field in self.fields], axis=1)

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
