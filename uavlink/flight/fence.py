"""Before take-off, ``uavlink fly`` gives the vehicle the operating area as its geofence.

The area (the env's square, ``half_width_m`` around the local origin) goes up as one inclusion
polygon (4 MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION items, MAV_FRAME_GLOBAL, as QGroundControl
uploads fences) over the mission protocol with mission_type FENCE, so the vehicle's own geofence
protects the flight whatever the loop sends, as on a real PX4. The polygon lies
:data:`FENCE_MARGIN_M` outside the area: the loop's targets reach the area's edge, and a fence on
the edge itself would turn rounding (1e-7 degree is about 1 cm) or a small overshoot into a breach.

Where the local frame sits on Earth comes from the vehicle's HOME_POSITION (home's latitude and
longitude, and its local x/y). A vehicle that does not take the fence (no HOME_POSITION, no mission
protocol, a refusal) costs a one-line warning and the flight goes on: the loop keeps every target
inside the area by itself, so the fence is a second line of defence, not the first, and refusing to
fly would strand the vehicles that cannot store fences (older sitl_stub, autopilots without fence
support).
"""

from __future__ import annotations

import logging

from uavlink.flight.link import LinkError, VehicleLink
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.frames import deg_to_e7, e7_to_deg
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.mission import FENCE, MissionClient, MissionItem, MissionTransferError

FENCE_MARGIN_M = 2.0
HOME_WAIT_S = 5.0  # wall seconds for a HOME_POSITION before asking for one

log = logging.getLogger(__name__)


def area_fence(
    origin: GeoOrigin, half_width_m: float, margin_m: float = FENCE_MARGIN_M
) -> list[MissionItem]:
    """The square ``half_width_m + margin_m`` around the local origin as an inclusion polygon."""
    h = half_width_m + margin_m
    corners_ne = [(h, h), (-h, h), (-h, -h), (h, -h)]  # NE, SE, SW, NW
    items = []
    for seq, (north, east) in enumerate(corners_ne):
        lat, lon = origin.to_global(north, east)
        items.append(
            MissionItem(
                seq,
                mavlink.MAV_FRAME_GLOBAL,
                mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                float(len(corners_ne)),
                x=deg_to_e7(lat),
                y=deg_to_e7(lon),
                mission_type=FENCE,
            )
        )
    return items


def local_origin(link: VehicleLink) -> GeoOrigin | None:
    """Where LOCAL_NED (0, 0) is on Earth, from the vehicle's HOME_POSITION (asked for once when
    none came within :data:`HOME_WAIT_S`); None when the vehicle sends none."""
    st = link.status
    if not link.wait_wall(lambda: st.home is not None, HOME_WAIT_S):
        link.send_command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
        if not link.wait_wall(lambda: st.home is not None, HOME_WAIT_S):
            return None
    home = st.home
    lat, lon = GeoOrigin(e7_to_deg(home.latitude), e7_to_deg(home.longitude)).to_global(
        -home.x, -home.y
    )
    return GeoOrigin(lat, lon)


def upload_area_fence(link: VehicleLink, half_width_m: float) -> bool:
    """Upload the operating area as the vehicle's fence; False (with a warning) when it is not
    taken."""
    origin = local_origin(link)
    if origin is None:
        log.warning(
            "geofence not uploaded: the vehicle sends no HOME_POSITION; flying on "
            "(the flight loop keeps its targets inside the area)"
        )
        return False
    assert link.target_system is not None  # a HOME_POSITION came from it: the target is known
    client = MissionClient(
        link.conn.mav, link.recv_mission, link.target_system, link.target_component
    )
    try:
        client.upload(area_fence(origin, half_width_m), FENCE)
    except MissionTransferError as exc:
        if link.unsigned_to_a_signing_vehicle:  # nothing we send will be taken: no use flying on
            raise LinkError(
                f"geofence not uploaded ({exc}): the vehicle ignores our unsigned packets"
            ) from None
        log.warning(
            "geofence not uploaded: %s; flying on (the flight loop keeps its targets "
            "inside the area)",
            exc,
        )
        return False
    log.info("geofence uploaded: the %g m operating area as an inclusion polygon", 2 * half_width_m)
    return True
