"""The vehicle's global origin (home): :class:`uavlink.mavlink.geo.GeoOrigin`, shared with the flight side."""

from uavlink.mavlink.geo import EARTH_RADIUS_M, GeoOrigin

__all__ = ["EARTH_RADIUS_M", "GeoOrigin"]
