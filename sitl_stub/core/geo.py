"""The vehicle's global origin (home): :class:`uavlink.mavlink.geo.GeoOrigin`, shared with the flight side."""

from uavlink.mavlink.geo import GeoOrigin

__all__ = ["GeoOrigin"]
