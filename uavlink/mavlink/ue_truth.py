"""Where the simulated UEs are, sent to the ground as ADSB_VEHICLE (id 246) for pictures and maps.

The radio payload of ``sitl_stub`` knows the simulated UE positions; a real base station does not.
They reach the ground only as the simulation's truth, so that ground stations draw the team and
``uavlink plot`` draws its tracks: one ADSB_VEHICLE per UE per radio frame, from the radio payload's
component, in the message ground stations already draw as traffic (QGroundControl's map shows
ADSB_VEHICLE as vehicles, MAVProxy's map module as ``adsb`` icons). The flight loop never reads them:
the link hands the radio source only DEBUG_FLOAT_ARRAY readings (:mod:`uavlink.flight.link.vehicle_link`).

Encoding (MAVLink common.xml): ``ICAO_address`` = :data:`UE_ICAO_BASE` + UE index (a 24-bit
address no transponder is assigned: the E-prefix block reserved for test equipment in practice),
``callsign`` ``"UE<index>"``, ``emitter_type`` ADSB_EMITTER_TYPE_SERVICE_SURFACE (18: a vehicle on
the ground), ``flags`` VALID_COORDS | VALID_ALTITUDE | VALID_HEADING | VALID_VELOCITY |
VALID_CALLSIGN | SIMULATED, latitude/longitude from the vehicle's LOCAL_NED origin
(:class:`uavlink.mavlink.geo.GeoOrigin`), geometric altitude AMSL of the UE's antenna.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from uavlink.mavlink.frames import deg_to_e7, e7_to_deg
from uavlink.mavlink.geo import GeoOrigin

UE_ICAO_BASE = 0xE0E000
MAX_TRUTH_UES = 0x1000
EMITTER_SERVICE_SURFACE = 18  # ADSB_EMITTER_TYPE_SERVICE_SURFACE
ALTITUDE_GEOMETRIC = 1  # ADSB_ALTITUDE_TYPE_GEOMETRIC
FLAGS = (
    1 | 2 | 4 | 8 | 16 | 64
)  # VALID_COORDS, _ALTITUDE, _HEADING, _VELOCITY, _CALLSIGN, SIMULATED
FLAG_SIMULATED = 64
UE_ANTENNA_HEIGHT_M = 1.5  # TR 38.901 Table 7.4.1-1: UE height 1.5 m outdoors


@dataclass(frozen=True)
class UeFix:
    """One UE's position as a ground station receives it."""

    ue: int
    lat_deg: float
    lon_deg: float


def adsb_arguments(
    ue: int, east_m: float, north_m: float, ve_mps: float, vn_mps: float, origin: GeoOrigin
) -> tuple:
    """``MAVLink.adsb_vehicle_send`` arguments for UE ``ue`` at local (east, north) metres."""
    if not 0 <= ue < MAX_TRUTH_UES:
        raise ValueError(f"UE index {ue} outside 0..{MAX_TRUTH_UES - 1}")
    lat, lon = origin.to_global(north_m, east_m)
    speed = math.hypot(ve_mps, vn_mps)
    heading_cdeg = int(round(math.degrees(math.atan2(ve_mps, vn_mps)) * 100)) % 36000
    return (
        UE_ICAO_BASE + ue,
        deg_to_e7(lat),
        deg_to_e7(lon),
        ALTITUDE_GEOMETRIC,
        int(round((origin.alt_amsl_m + UE_ANTENNA_HEIGHT_M) * 1000)),
        heading_cdeg,
        min(int(round(speed * 100)), 65534),
        0,
        f"UE{ue}".encode(),
        EMITTER_SERVICE_SURFACE,
        0,
        FLAGS,
        0,
    )


def decode_ue_fix(msg) -> UeFix | None:
    """A UE's position from an ADSB_VEHICLE this encoding made; None for any other traffic."""
    if msg.get_type() != "ADSB_VEHICLE" or msg.emitter_type != EMITTER_SERVICE_SURFACE:
        return None
    ue = msg.ICAO_address - UE_ICAO_BASE
    if not (0 <= ue < MAX_TRUTH_UES and msg.flags & FLAG_SIMULATED):
        return None
    if not (math.isfinite(msg.lat) and math.isfinite(msg.lon)):
        return None
    return UeFix(ue, e7_to_deg(msg.lat), e7_to_deg(msg.lon))
