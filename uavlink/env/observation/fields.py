"""The fields a frame of the observation may hold, each declared once: its labels, how it is encoded,
decoded and bounded. ``uavlink.env.observation.layout`` puts them together into a layout; a fleet's
own fields are in ``uavlink.env.observation.fleet_view``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class LayoutShape(Protocol):
    """What a field reads of its layout (``ObservationLayout`` has it all)."""

    @property
    def n_ues(self) -> int: ...
    @property
    def n_uavs(self) -> int: ...
    @property
    def uav_slots(self) -> int: ...
    @property
    def half_width_m(self) -> float: ...
    @property
    def sinr_offset_db(self) -> float: ...
    @property
    def sinr_scale_db(self) -> float: ...
    @property
    def sinr_clip_db(self) -> tuple[float, float]: ...
    @property
    def aoa_std_max_rad(self) -> float: ...


PLACE_GAIN_CLIP_BITS = 4.0  # a remembered spot's value minus now, bits/s/Hz, clipped
PLACE_AGE_SCALE_FRAMES = 128.0  # ages and the memory's length in episodes of 128 frames, at most 2


@dataclass(frozen=True)
class Field:
    """One field of a frame: the physical ``quantity`` it carries, its feature ``labels``, and how the
    layout encodes, decodes and bounds it. ``per`` repeats the labels: ``"frame"`` once, ``"ue"``
    per UE, ``"other_uav"`` per other UAV, ``"ue_uav"`` per UE and UAV, ``"slot"`` per slot of an
    any-size fleet's others (numbered in the names).

    ``encode(layout, quantities)`` gives (N, width) from the frame's quantities (N, ...) by name;
    ``decode(layout, encoded)`` turns encoded values (..., width) back into the quantity (a width-1
    field drops the last axis); ``bounds(layout)`` is the encoded (low, high) of every column.
    """

    quantity: str
    labels: tuple[str, ...]
    encode: Callable[[LayoutShape, Mapping[str, np.ndarray]], np.ndarray]
    decode: Callable[[LayoutShape, np.ndarray], np.ndarray]
    bounds: Callable[[LayoutShape], tuple[float, float]]
    per: str = "frame"

    def width(self, layout: LayoutShape) -> int:
        return len(self.names(layout))

    def names(self, layout: LayoutShape) -> list[str]:
        ues, others, uavs = range(layout.n_ues), range(1, layout.n_uavs), range(layout.n_uavs)
        return {
            "frame": list(self.labels),
            "ue": [f"{label}_{u}" for u in ues for label in self.labels],
            "other_uav": [f"{label}_{j}" for j in others for label in self.labels],
            "ue_uav": [f"{label}_{u}_{j}" for u in ues for j in uavs for label in self.labels],
            "slot": [f"{label}_{k}" for k in range(layout.uav_slots) for label in self.labels],
        }[self.per]


def _sinr_bounds(layout: LayoutShape) -> tuple[float, float]:
    lo_db, hi_db = layout.sinr_clip_db
    return (
        (lo_db - layout.sinr_offset_db) / layout.sinr_scale_db,
        (hi_db - layout.sinr_offset_db) / layout.sinr_scale_db,
    )


def aoa_fields(prefix: str) -> tuple[Field, Field]:
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
    *aoa_fields("aoa"),
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
    def encode(layout: LayoutShape, q: Mapping[str, np.ndarray]) -> np.ndarray:
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


def offset_field(quantity: str, labels: tuple[str, str], per: str = "frame") -> Field:
    """An offset from the UAV (m), in half-widths: within the area, at most 2; (rows, 2) or, per UE
    or slot, (rows, n, 2)."""
    return Field(
        quantity,
        labels,
        per=per,
        encode=lambda layout, q: q[quantity].reshape(len(q[quantity]), -1) / layout.half_width_m,
        decode=lambda layout, x: (
            x * layout.half_width_m
            if per == "frame"
            else x.reshape(*x.shape[:-1], -1, 2) * layout.half_width_m
        ),
        bounds=lambda layout: (-2.0, 2.0),
    )


PLACE_FIELDS: tuple[Field, ...] = (
    offset_field("place_best_offset_m", ("place_best_dx", "place_best_dy")),
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
    offset_field("place_pick_offset_m", ("place_pick_dx", "place_pick_dy")),
    _gain_bits("place_pick_gain_bits", ("place_pick_gain",)),
    _gain_bits("place_pick_std_bits", ("place_pick_std",)),
)
