"""A small PX4 parameter set and PX4's bytewise parameter encoding (no sockets, no MAVLink I/O).

Names, meanings and units are PX4's (``src/modules/*/params.c``); defaults are PX4's except
``MIS_TAKEOFF_ALT`` (95 m, the SPEC's operating altitude) and ``COM_OBL_ACT`` (1 = Hold, the
SPEC's offboard-loss reaction).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from enum import IntEnum

from uavlink.config.position_loop import MPC_ACC_HOR_MAX_MPS2, MPC_XY_VEL_MAX_MPS


class ParamType(IntEnum):
    """MAV_PARAM_TYPE values used here."""

    INT32 = 6
    REAL32 = 9


@dataclass(frozen=True)
class ParamDef:
    """One parameter: PX4 name (<= 16 chars), type, default and accepted range (inclusive)."""

    name: str
    type: ParamType
    default: float
    min: float
    max: float
    doc: str


PARAM_DEFS: tuple[ParamDef, ...] = (
    ParamDef(
        "COM_OF_LOSS_T",
        ParamType.REAL32,
        1.0,
        0.0,
        60.0,
        "Offboard loss timeout, s (PX4 commander).",
    ),
    ParamDef(
        "COM_OBL_ACT",
        ParamType.INT32,
        1,
        0,
        2,
        "Offboard loss action: 0 Land, 1 Hold (AUTO.LOITER), 2 Return.",
    ),
    ParamDef(
        "COM_DISARM_LAND",
        ParamType.REAL32,
        2.0,
        -1.0,
        20.0,
        "Auto-disarm this long after landing, s; <= 0 disables.",
    ),
    ParamDef(
        "MPC_XY_VEL_MAX",
        ParamType.REAL32,
        MPC_XY_VEL_MAX_MPS,
        0.5,
        20.0,
        "Maximum horizontal speed, m/s.",
    ),
    ParamDef(
        "MPC_XY_CRUISE",
        ParamType.REAL32,
        5.0,
        0.5,
        20.0,
        "Horizontal speed in auto modes (RTL), m/s.",
    ),
    ParamDef(
        "MPC_ACC_HOR_MAX",
        ParamType.REAL32,
        MPC_ACC_HOR_MAX_MPS2,
        0.5,
        15.0,
        "Maximum horizontal acceleration, m/s^2.",
    ),
    ParamDef("MPC_Z_VEL_MAX_UP", ParamType.REAL32, 3.0, 0.5, 8.0, "Maximum climb rate, m/s."),
    ParamDef("MPC_Z_VEL_MAX_DN", ParamType.REAL32, 1.5, 0.5, 4.0, "Maximum descent rate, m/s."),
    ParamDef("MPC_TKO_SPEED", ParamType.REAL32, 1.5, 0.5, 5.0, "Climb rate in AUTO.TAKEOFF, m/s."),
    ParamDef(
        "MPC_LAND_SPEED",
        ParamType.REAL32,
        0.7,
        0.2,
        2.0,
        "Descent rate for the last MPC_LAND_ALT2 metres of a landing, m/s.",
    ),
    ParamDef(
        "MPC_LAND_ALT2",
        ParamType.REAL32,
        5.0,
        0.0,
        50.0,
        "Below this altitude a landing slows to MPC_LAND_SPEED, m.",
    ),
    ParamDef(
        "MIS_TAKEOFF_ALT",
        ParamType.REAL32,
        95.0,
        0.5,
        500.0,
        "Takeoff altitude above home when NAV_TAKEOFF gives none, m.",
    ),
    ParamDef(
        "SYS_FAILURE_EN",
        ParamType.INT32,
        0,
        0,
        1,
        "Failure injection (MAV_CMD_INJECT_FAILURE): 0 refused, 1 enabled.",
    ),
    ParamDef(
        "RTL_RETURN_ALT",
        ParamType.REAL32,
        60.0,
        0.0,
        500.0,
        "RTL climbs to at least this altitude above home before returning, m.",
    ),
    ParamDef(
        "NAV_ACC_RAD",
        ParamType.REAL32,
        10.0,
        0.05,
        200.0,
        "Mission waypoint acceptance radius when the item gives none, m (PX4 navigator).",
    ),
    ParamDef(
        "GF_ACTION",
        ParamType.INT32,
        2,
        0,
        5,
        "Geofence breach action: 0 None, 1 Warning, 2 Hold, 3 Return, 4 Terminate (flown "
        "as Land here), 5 Land.",
    ),
)


def int_to_param_float(value: int) -> float:
    """PX4 bytewise encoding: the int32's bytes reinterpreted as a float32 (1 -> 1.4e-45)."""
    return struct.unpack("<f", struct.pack("<i", int(value)))[0]


def param_float_to_int(value: float) -> int:
    """Inverse of :func:`int_to_param_float`."""
    return struct.unpack("<i", struct.pack("<f", float(value)))[0]


class ParamStore(Mapping[str, float]):
    """Current parameter values by name; iteration order is the fixed index order.

    INT32 values are held as Python ints, REAL32 as floats.
    """

    def __init__(
        self,
        overrides: Mapping[str, float] | None = None,
        *,
        defs: tuple[ParamDef, ...] = PARAM_DEFS,
    ) -> None:
        self._defs = {d.name: d for d in defs}
        self._order = [d.name for d in defs]
        self._values: dict[str, float] = {d.name: _typed(d, d.default) for d in defs}
        for name, value in (overrides or {}).items():
            if not self.set(name, value):
                d = self._defs.get(name)
                if d is None:
                    raise ValueError(f"unknown parameter {name!r}")
                raise ValueError(f"parameter {name} must be in [{d.min:g}, {d.max:g}], got {value}")

    def __getitem__(self, name: str) -> float:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._order)

    def __len__(self) -> int:
        return len(self._order)

    def definition(self, name: str) -> ParamDef:
        return self._defs[name]

    def index_of(self, name: str) -> int:
        return self._order.index(name)

    def name_at(self, index: int) -> str | None:
        return self._order[index] if 0 <= index < len(self._order) else None

    def set(self, name: str, value: float) -> bool:
        """Set a value given as a number; False (and no change) when unknown, non-finite or
        outside the parameter's range. INT32 values must be whole numbers."""
        d = self._defs.get(name)
        if d is None:
            return False
        try:
            v = float(value)
        except (TypeError, ValueError):
            return False
        if not math.isfinite(v) or not d.min <= v <= d.max:
            return False
        if d.type is ParamType.INT32 and v != int(v):
            return False
        self._values[name] = _typed(d, v)
        return True

    def encode(self, name: str) -> tuple[float, ParamType]:
        """(param_value, param_type) for a PARAM_VALUE message, ints bytewise-encoded."""
        d = self._defs[name]
        v = self._values[name]
        if d.type is ParamType.INT32:
            return int_to_param_float(int(v)), d.type
        return float(v), d.type

    def set_from_wire(self, name: str, param_value: float) -> bool:
        """Apply a PARAM_SET value, decoding by the parameter's own type as PX4 does."""
        d = self._defs.get(name)
        if d is None:
            return False
        if d.type is ParamType.INT32:
            return self.set(name, param_float_to_int(param_value))
        return self.set(name, param_value)


def _typed(d: ParamDef, v: float) -> float:
    return int(v) if d.type is ParamType.INT32 else float(v)
