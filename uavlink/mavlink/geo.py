"""Local NED <-> WGS-84 around a global origin, as PX4's ``map_projection`` does it.

Both ends use it: the SITL vehicle for its global telemetry, ``uavlink fly`` to turn the local
operating area into the global fence it uploads.

Azimuthal equidistant projection on a sphere of radius 6371 km (PX4 ``CONSTANTS_RADIUS_OF_EARTH``).
Defaults are PX4 SITL's home: 47.397742 N, 8.545594 E, 488 m AMSL (Zurich).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

EARTH_RADIUS_M = 6_371_000.0


@dataclass(frozen=True)
class GeoOrigin:
    """Where LOCAL_NED (0, 0, 0) sits on Earth; also the vehicle's home. Degrees, metres AMSL."""

    lat_deg: float = 47.397742
    lon_deg: float = 8.545594
    alt_amsl_m: float = 488.0

    def validate(self) -> None:
        if not (math.isfinite(self.lat_deg) and -90.0 < self.lat_deg < 90.0):
            raise ValueError(f"home latitude must be in (-90, 90) degrees, got {self.lat_deg}")
        if not (math.isfinite(self.lon_deg) and -180.0 <= self.lon_deg <= 180.0):
            raise ValueError(f"home longitude must be in [-180, 180] degrees, got {self.lon_deg}")
        if not math.isfinite(self.alt_amsl_m):
            raise ValueError(f"home altitude must be finite, got {self.alt_amsl_m}")

    def to_global(self, north_m: float, east_m: float) -> tuple[float, float]:
        """(lat, lon) in degrees of a local point."""
        lat0 = math.radians(self.lat_deg)
        lon0 = math.radians(self.lon_deg)
        x = north_m / EARTH_RADIUS_M
        y = east_m / EARTH_RADIUS_M
        c = math.hypot(x, y)
        if c == 0.0:
            return self.lat_deg, self.lon_deg
        sin_c, cos_c = math.sin(c), math.cos(c)
        lat = math.asin(cos_c * math.sin(lat0) + x * sin_c * math.cos(lat0) / c)
        lon = lon0 + math.atan2(y * sin_c, c * math.cos(lat0) * cos_c - x * math.sin(lat0) * sin_c)
        lon_deg = (math.degrees(lon) + 180.0) % 360.0 - 180.0
        return math.degrees(lat), lon_deg

    def to_local(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """(north, east) in metres of a global point."""
        lat0 = math.radians(self.lat_deg)
        lat = math.radians(lat_deg)
        dlon = math.radians(lon_deg - self.lon_deg)
        cos_c = math.sin(lat0) * math.sin(lat) + math.cos(lat0) * math.cos(lat) * math.cos(dlon)
        cos_c = max(-1.0, min(1.0, cos_c))
        c = math.acos(cos_c)
        k = 1.0 if c == 0.0 else c / math.sin(c)
        north = k * (
            math.cos(lat0) * math.sin(lat) - math.sin(lat0) * math.cos(lat) * math.cos(dlon)
        )
        east = k * math.cos(lat) * math.sin(dlon)
        return north * EARTH_RADIUS_M, east * EARTH_RADIUS_M
