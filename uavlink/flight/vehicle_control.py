"""Commanding a PX4 vehicle over its link as a companion computer does (MAVSDK's action and offboard
plugins in the small): wait until it is ready, take off or resume one already flying, enter
OFFBOARD, land; and the mode checks both fly loops (one UAV, a fleet) make. Knows no policy and no
episode."""

from __future__ import annotations

import logging
import time

from uavlink.flight.fence import upload_area_fence
from uavlink.flight.link import LinkError, VehicleLink, VehicleStatus
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.px4_modes import (
    PX4_MAIN_AUTO,
    PX4_MAIN_OFFBOARD,
    PX4_SUB_AUTO_LAND,
    PX4_SUB_AUTO_LOITER,
    PX4_SUB_AUTO_RTL,
    px4_mode_name,
)

log = logging.getLogger(__name__)


def wait_ready(link: VehicleLink, takeoff: bool, landing_wait_vehicle_s: float) -> None:
    """Wait for the vehicle's heartbeat, position and landed state; a vehicle still landing or
    returning (an earlier flight ending) is waited for (up to ``landing_wait_vehicle_s`` of vehicle
    time) until it has landed and disarmed, and one landed but armed is disarmed when this flight
    takes off, so that it begins with an arming (a fresh episode)."""
    link.wait_vehicle()
    st = link.status
    if st.armed and (ending_mode(st) or st.landed_state == mavlink.MAV_LANDED_STATE_LANDING):
        log.warning(
            "vehicle is %s (an earlier flight ending): waiting until it has landed and disarmed",
            mode_name(st),
        )
        link.wait_until(
            lambda: not st.armed, landing_wait_vehicle_s, "the earlier flight's landing and disarm"
        )
    if st.armed and not st.in_air and takeoff:
        link.arm(False)


def take_off_or_resume(
    link: VehicleLink,
    altitude_m: float,
    fence_half_width_m: float | None,
    takeoff: bool,
    wait: bool = True,
) -> bool:
    """Upload the area as the geofence (``fence_half_width_m``, None: none), then arm and take off to
    ``altitude_m`` (when ``takeoff``; with ``wait`` until there), or resume a vehicle already armed
    and in the air; whether it resumed."""
    st = link.status
    if fence_half_width_m is not None:
        upload_area_fence(link, fence_half_width_m)
    if st.armed and st.in_air:
        log.warning(
            "vehicle already armed and in the air (%s, %.0f m): resuming without take-off",
            mode_name(st),
            -st.down_m,
        )
        return True
    if takeoff:
        link.arm()
        link.takeoff(altitude_m, wait=wait)
    return False


def land(link: VehicleLink) -> None:
    """Hold (still streaming until the hold is taken), then land."""
    try:
        link.set_mode(PX4_MAIN_AUTO, PX4_SUB_AUTO_LOITER)
        link.stream_ned = None
        link.land()
    except LinkError as exc:
        log.error("landing command failed: %s", exc)


def enter_offboard(link: VehicleLink, within_s: float) -> None:
    """DO_SET_MODE OFFBOARD until the heartbeat shows it (the setpoint stream is already running);
    a refusal or a lost ACK or heartbeat is tried again until ``within_s`` of wall time pass."""
    st = link.status
    deadline = time.monotonic() + within_s
    while not st.offboard:
        try:
            link.set_mode(PX4_MAIN_OFFBOARD, tries=3)
            if link.wait_wall(lambda: st.offboard, 2.0):
                return
            problem = "the heartbeat does not show OFFBOARD"
        except LinkError as exc:
            problem = str(exc)
        if time.monotonic() > deadline:
            raise LinkError(f"could not enter OFFBOARD within {within_s:g} s: {problem}")
        log.warning("entering OFFBOARD: %s; trying again", problem)


def ending_mode(st: VehicleStatus) -> bool:
    """AUTO.LAND or AUTO.RTL: the flight is being ended (by an operator or a failsafe)."""
    return st.main_mode == PX4_MAIN_AUTO and st.sub_mode in (PX4_SUB_AUTO_LAND, PX4_SUB_AUTO_RTL)


def mode_name(st: VehicleStatus) -> str:
    return px4_mode_name(st.main_mode, st.sub_mode) + ("" if st.armed else ", disarmed")
