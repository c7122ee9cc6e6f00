"""The vehicle's reaction to a geofence breach, PX4's GF_ACTION (no MAVLink I/O).

PX4 v1.15: ``src/modules/navigator/geofence_params.c`` (GF_ACTION 0 None, 1 Warning, 2 Hold mode
(the default), 3 Return mode, 4 Terminate, 5 Land mode), ``navigator_main.cpp`` (the breach is
predicted from the braking distance and announced once, "Geofence violation"; with Hold a
multicopter repositions to a point inside the fence, ``geofence_breach_avoidance.cpp``).
Termination cannot be simulated usefully: GF_ACTION 4 lands instead, and says so. A vehicle
already returning or landing keeps doing that.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from sitl_stub.core.modes import FlightMode
from sitl_stub.core.vehicle_state import SEVERITY_CRITICAL, SEVERITY_WARNING
from sitl_stub.flight.pos_control import stopping_point

if TYPE_CHECKING:
    from sitl_stub.flight.vehicle import Vehicle

# The vehicle's own helper for STATUSTEXT events (_event) is used: this module is its part.
ACTION_NAMES = {2: "Hold", 3: "Return", 4: "Land (no termination in SITL)", 5: "Land"}


def geofence_failsafe(v: Vehicle) -> None:
    """Check the vehicle's fence at its braking point; on a new breach act on GF_ACTION."""
    action = int(v.params["GF_ACTION"])
    if action == 0:
        v.fence.breached = False
        return
    n, e, _ = stopping_point(v.pos, v.vel, v.params["MPC_ACC_HOR_MAX"])
    f = v.fence_m  # the operating area stops the vehicle first
    safe = v.fence.check((v.pos[0], v.pos[1]), (max(-f, min(f, n)), max(-f, min(f, e))))
    if safe is None:
        return
    v._event(SEVERITY_CRITICAL, "Geofence violation")
    if action == 1 or v.mode in (FlightMode.RTL, FlightMode.LAND):
        return
    if action == 2:
        v.hold(at_ne=safe)
    elif action == 3:
        v.return_to_launch()
    else:
        v.land(at_ne=safe)
    v._event(SEVERITY_WARNING, f"Failsafe: geofence, activating {ACTION_NAMES[action]}")
