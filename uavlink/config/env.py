"""The env's typed configuration with the SPEC's defaults: area, radio, learning problem.

Every constant of the geometry, the radio model and the learning problem lives here; modules take
these dataclasses rather than loose numbers. The scenario names are declared here, the lowest
layer, and ``uavlink.mobility`` implements them. ``validate()`` rejects configs that make no physical
sense, or hold a value of the wrong type, with a one-line ``ConfigError`` (a ``UserError``) naming the field.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from uavlink.config.fields import bounded, check_fields, coerce
from uavlink.errors import ConfigError

# The UE mobility scenarios (uavlink.mobility implements them); MIXED draws one per env and episode.
SCENARIOS: tuple[str, ...] = (
    "no_move",
    "straight",
    "circular",
    "straight_90",
    "straight_180",
    "hotspot",
)
MIXED = "mixed"
SCENARIO_NAMES: tuple[str, ...] = (*SCENARIOS, MIXED)  # every scenario a config accepts
# Shadowing: the SPEC's per-link AR(1) (the paper's) or the spatially consistent field.
SHADOWING_AR1, SHADOWING_SPATIAL = "ar1", "spatial"
SHADOWING_MODELS = (SHADOWING_AR1, SHADOWING_SPATIAL)
# How a policy's output becomes a move (uavlink.env.actions.ActionMapping implements them).
ACTION_MAPPINGS = ("cartesian-v1", "polar-v1")
# How a fleet shares the band (SPEC "A fleet"): every UAV on every RB, the band split D ways, or
# one cell on the whole band while the other UAVs listen (barred to attachment, sending nothing,
# still hearing every UE's uplink: uavlink.radio.cells.Cells.listen).
REUSE_FULL, REUSE_ORTHOGONAL, REUSE_LISTEN = "full", "orthogonal", "listen"
FLEET_REUSE = (REUSE_FULL, REUSE_ORTHOGONAL, REUSE_LISTEN)
# How the UAV reaches its setpoint in a frame (uavlink.mobility.uav_motion): at once (the paper's),
# or flown by PX4's position loop under its speed and acceleration limits, as sitl_stub flies (a
# fleet's setpoints then move as `uavlink fly` moves them: separated, and cut for the transit; what
# the policy reads and the vehicle receives is rounded to float32, as MAVLink carries it).
MOTION_INSTANT, MOTION_PX4 = "instant", "px4"
UAV_MOTIONS = (MOTION_INSTANT, MOTION_PX4)
# What the memory of place keeps: "cells", the grid of sensed values (layout v3, v4 for a fleet);
# "kriging", that grid and a model of the sensed field with the spot it makes worth flying to (v5
# for one UAV, v8 for a fleet of any size, each UAV its own; uavlink/env/field_model.py);
# "pooled", a fleet's one model that every UAV feeds and picks from (v9).
PLACE_CELLS, PLACE_KRIGING, PLACE_POOLED = "cells", "kriging", "pooled"
PLACE_MODELS = (PLACE_CELLS, PLACE_KRIGING, PLACE_POOLED)
FIELD_MODELS = (PLACE_KRIGING, PLACE_POOLED)  # the place models with a model of the field
# The finest memory-of-place grid validate() accepts: cells of at least PLACE_CELL_MIN_M, and at most
# PLACE_CELLS_ACROSS of them across the area (EnvConfig.place_cell_m says why).
PLACE_CELL_MIN_M = 1.0
PLACE_CELLS_ACROSS = 400


def fleet_sizes_of(fleet_slots: int) -> range:
    """The fleet sizes a policy that shows each UAV ``fleet_slots`` others flies (layout v6 and on):
    2 to ``fleet_slots`` + 1 UAVs; none without slots."""
    return range(2, fleet_slots + 2)


@dataclass(frozen=True)
class AreaConfig:
    """The operating area (and geofence): x = east, y = north, metres, centred at the origin."""

    half_width_m: float = bounded(200.0, low=0.0, low_open=True)
    uav_altitude_m: float = bounded(95.0, low=0.0, low_open=True)

    def validate(self) -> None:
        check_fields(self, lambda path: f"area.{path}")


@dataclass(frozen=True)
class RadioConfig:
    """3GPP TR 25.814 urban-macro downlink, amended as the paper says (omni antennas, Rician)."""

    carrier_ghz: float = bounded(2.0, low=0.0, low_open=True)
    bandwidth_hz: float = bounded(10e6, low=0.0, low_open=True)
    n_resource_blocks: int = bounded(50, low=1)
    tx_power_dbm: float = 19.0
    noise_figure_db: float = 9.0
    thermal_noise_dbm_per_hz: float = -174.0
    antenna_gain_db: float = 0.0
    outdoor_to_indoor_loss_db: float = bounded(0.0, low=0.0)
    # TR 25.814 Table A.2.1.1-3 urban macro: L = 128.1 + 37.6 log10(d / 1 km), d >= 35 m.
    path_loss_intercept_db: float = 128.1
    path_loss_slope_db: float = 37.6
    min_distance_m: float = bounded(35.0, low=0.0, low_open=True)
    shadowing: bool = True
    shadowing_std_db: float = bounded(8.0, low=0.0)
    # The UE end's (and the AR(1) model's) decorrelation distance.
    shadowing_decorrelation_m: float = bounded(50.0, low=0.0, low_open=True)
    # "ar1": the SPEC's per-link AR(1) over displacement (the paper's channel, no memory of place);
    # "spatial": one field per episode over (UE, UAV) positions (uavlink/radio/spatial_shadowing.py).
    shadowing_model: str = SHADOWING_AR1
    # The UAV end's decorrelation distance, spatial model only.
    shadowing_uav_decorrelation_m: float = bounded(50.0, low=0.0, low_open=True)
    fast_fading: bool = True
    rician_k_db: float = 10.0
    aoa_noise_deg: float = bounded(0.0, low=0.0)
    # Per-episode AoA noise: when above aoa_noise_deg, every episode draws its AoA noise std
    # uniformly from [aoa_noise_deg, aoa_noise_max_deg]; 0 (default) keeps the std fixed. The env
    # core reads it; it is training-time randomisation, set from TrainConfig.aoa_noise_max_deg by
    # uavlink.learn.training.training_env_config and never part of a policy's own env config.
    aoa_noise_max_deg: float = bounded(0.0, low=0.0)

    def validate(self) -> None:
        check_fields(self, lambda path: f"radio.{path}")
        if self.shadowing_model not in SHADOWING_MODELS:
            raise ConfigError(
                f"radio.shadowing_model must be one of {', '.join(SHADOWING_MODELS)}, "
                f"got {self.shadowing_model!r}"
            )
        if 0 < self.aoa_noise_max_deg < self.aoa_noise_deg:
            raise ConfigError("radio.aoa_noise_max_deg must be 0 (off) or >= radio.aoa_noise_deg")

    @property
    def rb_bandwidth_hz(self) -> float:
        return self.bandwidth_hz / self.n_resource_blocks

    def rbs_per_cell(self, n_cells: int) -> int:
        """RBs each of ``n_cells`` cells holds under orthogonal reuse: an equal split of the band,
        the remainder left unused."""
        return self.n_resource_blocks // n_cells

    def orthogonal_share(self, n_cells: int) -> float:
        """The fraction of the band each of ``n_cells`` cells holds under orthogonal reuse."""
        return self.rbs_per_cell(n_cells) / self.n_resource_blocks


@dataclass(frozen=True)
class EnvConfig:
    """The learning problem: scenario, episode, action range, observation memory."""

    scenario: str = "circular"
    n_ues: int = bounded(10, low=1)
    episode_frames: int = bounded(128, low=1)
    frame_s: float = bounded(1.0, low=0.0, low_open=True)
    # The longest move a frame: PX4's MPC_XY_VEL_MAX default, 12 m/s x a 1 s frame.
    r_max_m: float = bounded(12.0, low=0.0, low_open=True)
    uav_motion: str = MOTION_INSTANT
    action_mapping: str = ACTION_MAPPINGS[0]  # see uavlink.env.actions.ActionMapping
    memory: int = bounded(4, low=1)
    # A memory of place (SPEC "The limit, and a memory of place"): what the UAV sensed where, on a
    # grid of cells this wide (m) over the area; 0 (default) is off, the layouts of before.
    # uavlink/env/place_memory.py; it makes the observation layout v3 (v4 for a fleet). The shipped
    # grid is 12 m (one frame's longest move). validate() wants cells of at least
    # PLACE_CELL_MIN_M = 1 m (in flight the UAV knows its own position, LOCAL_POSITION_NED, to about a
    # metre: finer cells would file its readings by noise) and at most PLACE_CELLS_ACROSS = 400 across
    # the area: the memory keeps 12 bytes per cell and UAV, so 400 x 400 cells are 1.9 MB a UAV (0.25
    # GB for 128 envs), and it grows as 1 / cell^2 (1 mm cells over the default area: 1.7 TiB a UAV).
    place_cell_m: float = bounded(0.0, low=0.0)
    place_model: str = PLACE_CELLS  # what the memory keeps: PLACE_MODELS above
    ue_speed_mps: float = bounded(8.0, low=0.0)
    cluster_size_m: float = bounded(10.0, low=0.0)
    # The fleet (SPEC "A fleet"): D UAVs, start spread on a circle, kept apart by a safety filter.
    n_uavs: int = bounded(1, low=1)
    fleet_reuse: str = REUSE_FULL
    uav_separation_m: float = bounded(20.0, low=0.0)  # horizontal minimum between two UAVs
    # UAV d starts at this radius, 360 d / D degrees from east.
    fleet_start_radius_m: float = bounded(100.0, low=0.0)
    # A fleet of any size (SPEC "A fleet of any size"): K > 0 shows each UAV the others in K slots,
    # nearest first (layout v6; v7 with a memory of place, v8 with a model of the field too), so one
    # policy flies fleets of 2 to K + 1; 0 (default) is layout v2, a policy for exactly n_uavs.
    fleet_slots: int = bounded(0, low=0)
    area: AreaConfig = field(default_factory=AreaConfig)
    radio: RadioConfig = field(default_factory=RadioConfig)

    def validate(self) -> EnvConfig:
        check_fields(self, lambda path: path if path in ("area", "radio") else f"env.{path}")
        self.area.validate()  # the checks below read the area
        if self.scenario not in SCENARIO_NAMES:
            raise ConfigError(
                f"unknown scenario {self.scenario!r}; choose from {', '.join(SCENARIOS)} or {MIXED}"
            )
        if self.action_mapping not in ACTION_MAPPINGS:
            raise ConfigError(
                f"unknown action mapping {self.action_mapping!r}; choose from "
                f"{', '.join(ACTION_MAPPINGS)}"
            )
        if self.uav_motion not in UAV_MOTIONS:
            raise ConfigError(
                f"unknown uav_motion {self.uav_motion!r}; choose from {', '.join(UAV_MOTIONS)}"
            )
        if self.fleet_reuse not in FLEET_REUSE:
            raise ConfigError(
                f"unknown fleet_reuse {self.fleet_reuse!r}; choose from {', '.join(FLEET_REUSE)}"
            )
        if self.n_ues < 2 and self.scenario in ("straight_90", "straight_180", "hotspot", MIXED):
            raise ConfigError(
                f"scenario {self.scenario!r} needs at least 2 UEs, got n_ues={self.n_ues}"
            )
        if self.place_cell_m > self.area.half_width_m:
            raise ConfigError("env.place_cell_m must be 0 (off) or at most area.half_width_m")
        finest = max(PLACE_CELL_MIN_M, 2 * self.area.half_width_m / PLACE_CELLS_ACROSS)
        if 0 < self.place_cell_m < finest:
            raise ConfigError(
                f"env.place_cell_m must be 0 (off) or >= {finest:g} m (cells of at least "
                f"{PLACE_CELL_MIN_M:g} m, at most {PLACE_CELLS_ACROSS} across the area's "
                f"{2 * self.area.half_width_m:g} m), got {self.place_cell_m!r}"
            )
        if self.place_model not in PLACE_MODELS:
            raise ConfigError(
                f"unknown place_model {self.place_model!r}; choose from {', '.join(PLACE_MODELS)}"
            )
        if self.place_model == PLACE_KRIGING and (
            self.place_cell_m <= 0 or (self.n_uavs > 1 and self.fleet_slots == 0)
        ):
            raise ConfigError(
                "env.place_model=kriging models each UAV's memory of place: it needs "
                "place_cell_m > 0, and in a fleet fleet_slots > 0 (layout v8)"
            )
        if self.place_model == PLACE_POOLED and (self.place_cell_m <= 0 or self.fleet_slots == 0):
            raise ConfigError(
                "env.place_model=pooled models a fleet's field: it needs place_cell_m > 0 and "
                "fleet_slots > 0 (layout v9)"
            )
        if self.cluster_size_m >= 2 * self.area.half_width_m:
            raise ConfigError("env.cluster_size_m must be smaller than the area")
        sizes = fleet_sizes_of(self.fleet_slots)
        if self.fleet_slots > 0 and self.n_uavs not in sizes:
            raise ConfigError(
                f"env.fleet_slots={self.fleet_slots} flies fleets of {sizes[0]} to {sizes[-1]} "
                f"UAVs, not n_uavs={self.n_uavs}"
            )
        if self.n_uavs > 1:  # the start circle must fit the area and keep the UAVs apart
            if self.fleet_start_radius_m >= self.area.half_width_m:
                raise ConfigError("env.fleet_start_radius_m must be smaller than area.half_width_m")
            if (
                2 * self.fleet_start_radius_m * math.sin(math.pi / self.n_uavs)
                < self.uav_separation_m
            ):
                raise ConfigError(
                    f"{self.n_uavs} UAVs on a {self.fleet_start_radius_m:g} m start circle are "
                    f"closer than env.uav_separation_m={self.uav_separation_m:g}"
                )
        self.radio.validate()
        return self

    def replace(self, **changes: Any) -> EnvConfig:
        """A copy with fields changed; ``radio.x`` / ``area.x`` keys reach the nested configs. Values
        take their field's type (an int where a float goes becomes a float); a value of the wrong
        type is a ``ConfigError`` naming the key (``--set radio.fast_fading=maybe`` is refused)."""
        top: dict[str, Any] = {}
        nested: dict[str, dict[str, Any]] = {"radio": {}, "area": {}}
        for key, value in changes.items():
            if key not in _field_names(EnvConfig):  # a bare radio or area field reaches its config
                key = next(
                    (
                        f"{head}.{key}"
                        for head, cls in (("radio", RadioConfig), ("area", AreaConfig))
                        if key in _field_names(cls)
                    ),
                    key,
                )
            head, _, tail = key.partition(".")
            if tail:  # coerce refuses a key no config has, naming it
                nested[head][tail] = coerce(EnvConfig, key, value, key)
            else:
                top[key] = (
                    value if dataclasses.is_dataclass(value) else coerce(EnvConfig, key, value, key)
                )
        for head, sub in nested.items():
            if sub:
                top[head] = dataclasses.replace(top.get(head, getattr(self, head)), **sub)
        return dataclasses.replace(self, **top)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def to_flat_dict(self) -> dict[str, Any]:
        """Every field by its ``replace`` key: ``scenario``, ``radio.shadowing``, ``area.half_width_m``."""
        flat: dict[str, Any] = {}
        for key, value in self.to_dict().items():
            flat.update(
                {f"{key}.{k}": v for k, v in value.items()}
                if isinstance(value, dict)
                else {key: value}
            )
        return flat

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EnvConfig:
        data = dict(data)
        area = AreaConfig(**data.pop("area", {}))
        radio = RadioConfig(**data.pop("radio", {}))
        return cls(area=area, radio=radio, **data)


def parse_settings(pairs: Sequence[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` pairs -> {key: value}, the value a JSON literal when it parses, else a string."""
    settings: dict[str, Any] = {}
    for pair in pairs:
        key, sep, raw = pair.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects key=value, got {pair!r}")
        try:
            settings[key.strip()] = json.loads(raw)
        except json.JSONDecodeError:
            settings[key.strip()] = raw
    return settings


def changed_settings(cfg: EnvConfig, base: EnvConfig | None = None) -> list[str]:
    """``cfg``'s fields that differ from ``base`` (default: the defaults) as ``KEY=JSON`` pairs for
    ``--set`` (``radio.x`` / ``area.x`` for nested ones); ``parse_settings`` reads them back exactly."""
    ref = (base or EnvConfig()).to_flat_dict()
    return [
        f"{key}={json.dumps(value)}"
        for key, value in cfg.to_flat_dict().items()
        if value != ref[key]
    ]


def _field_names(cls: type) -> set[str]:
    return {f.name for f in dataclasses.fields(cls)}
