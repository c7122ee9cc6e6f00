"""Failsafe reactions, as PX4's commander picks them (``commander/failsafe/failsafe.cpp``): each
cause maps its parameter onto one :class:`Action`, and the vehicle applies it. Detection stays with
what detects (the offboard stream's age, the fence's braking-point check); nothing here touches the
vehicle or MAVLink.

PX4 v1.15: COM_OBL_ACT (``commander_params.c``: 0 Land, 1 Hold, else Return; on the ground always
Hold) for a lost offboard stream; GF_ACTION (``navigator/geofence_params.c``: 0 None, 1 Warning, 2
Hold mode (the default), 3 Return mode, 4 Terminate, 5 Land mode) for a geofence breach predicted
from the braking distance (``navigator_main.cpp``; with Hold a multicopter repositions to a point
inside the fence, ``geofence_breach_avoidance.cpp``). Termination cannot be simulated usefully:
GF_ACTION 4 lands instead, and says so. A vehicle already returning or landing keeps doing that.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from sitl_stub.core.modes import FlightMode


class Action(Enum):
    WARN = "Warning"  # announce only
    HOLD = "Hold"
    RETURN = "Return"
    LAND = "Land"


@dataclass(frozen=True)
class Reaction:
    """What the vehicle does: the action, where to hold or land (None: where it is) and the
    STATUSTEXT it announces after acting ("" for none)."""

    action: Action
    at_ne: tuple[float, float] | None = None
    announce: str = ""


def offboard_lost(com_obl_act: int, in_air: bool) -> Reaction:
    """The reaction to a lost offboard setpoint stream (COM_OBL_ACT)."""
    action = {0: Action.LAND, 1: Action.HOLD}.get(com_obl_act if in_air else 1, Action.RETURN)
    return Reaction(action, announce=f"Failsafe: offboard lost, activating {action.value}")


def geofence_breach(gf_action: int, mode: FlightMode, safe_ne: tuple[float, float]) -> Reaction:
    """The reaction to a new geofence breach (GF_ACTION 1-5); ``safe_ne``: a point inside the fence."""
    if gf_action == 1 or mode in (FlightMode.RTL, FlightMode.LAND):
        return Reaction(Action.WARN)
    action = {2: Action.HOLD, 3: Action.RETURN}.get(gf_action, Action.LAND)
    name = "Land (no termination in SITL)" if gf_action == 4 else action.value
    return Reaction(action, safe_ne, f"Failsafe: geofence, activating {name}")
