"""The one place that imports pymavlink: MAVLink 2, dialect ``common``.

pymavlink picks the wire protocol when ``mavutil`` is first imported (``MAVLINK20`` in the
environment) and again on ``set_dialect``; both are done here so that every module of the stub
talks MAVLink 2 whatever was imported before.
"""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # noqa: E402

mavutil.set_dialect("common")
mavlink = mavutil.mavlink

if mavlink.WIRE_PROTOCOL_VERSION != "2.0":  # pragma: no cover - environment guard
    raise ImportError("sitl_stub needs pymavlink's MAVLink 2 'common' dialect")

__all__ = ["mavlink", "mavutil"]
