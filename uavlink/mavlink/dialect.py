"""The one place that imports pymavlink: MAVLink 2, dialect ``common``, for both ends of the link.

pymavlink picks the wire protocol when ``mavutil`` is first imported (``MAVLINK20`` in the
environment) and again on ``set_dialect``; both are done here, so every module that takes
``mavlink``/``mavutil`` from here talks MAVLink 2 whatever was imported before. The variable stays
set for child processes too (the SITL vehicle, MAVProxy), which then speak MAVLink 2 as well.
Import this module before any other pymavlink import (tests included).
"""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("common")
mavlink = mavutil.mavlink

if mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # pragma: no cover - environment guard
    raise ImportError("uavlink needs pymavlink's MAVLink 2 'common' dialect")

__all__ = ["enum_name", "mavlink", "mavutil"]


def enum_name(enum: str, value: int) -> str:
    """A MAVLink enum entry's name (``enum_name("MAV_CMD", 400)``: ``MAV_CMD_COMPONENT_ARM_DISARM``),
    or ``"ENUM value"`` for a value the dialect does not know."""
    entry = mavlink.enums[enum].get(value)
    return entry.name if entry is not None else f"{enum} {value}"
