"""The ground end of MAVLink for ``uavlink fly``: ``vehicle_link`` (one vehicle: heartbeats, modes,
arming, commands and parameters with retries, offboard setpoints, the tlog), ``vehicle_status``
(what the link knows of each MAVLink system it hears) and ``group`` (a fleet's links polled as one).
What both ends share (connection strings, signing, mode encoding, codecs) is ``uavlink.mavlink``'s.

May import: ``mavlink`` and ``errors``; nothing else of ``flight`` (the loops above use it).
"""

from uavlink.flight.link.vehicle_link import (
    MAX_RX_PER_POLL,
    STREAM_PERIOD_VEHICLE_S,
    LinkError,
    VehicleLink,
)
from uavlink.flight.link.vehicle_status import VehicleStatus

__all__ = [
    "MAX_RX_PER_POLL",
    "STREAM_PERIOD_VEHICLE_S",
    "LinkError",
    "VehicleLink",
    "VehicleStatus",
]
