"""The vehicle's stored plans: mission, geofence and rally lists (MAVLink mission_type 0, 1, 2).

The mission microservice (https://mavlink.io/en/services/mission.html) fills and reads these
lists; the mission executor, the geofence and RTL read them. A list is replaced whole when an
upload completes, as PX4's dataman does (a failed or partial upload leaves the old list). No
MAVLink I/O here.
"""

from __future__ import annotations

from collections.abc import Callable

# the item and the mission types are the MAVLink package's, shared with the flight side's client
from uavlink.mavlink.mission import FENCE, MISSION, MISSION_TYPES, RALLY, MissionItem

__all__ = ["FENCE", "MISSION", "MISSION_TYPES", "RALLY", "MissionItem", "MissionStore"]


class MissionStore:
    """The three lists and the mission's current item; listeners hear of every replacement."""

    def __init__(self) -> None:
        self._lists: dict[int, tuple[MissionItem, ...]] = {t: () for t in MISSION_TYPES}
        self.current_seq = 0
        self._listeners: list[Callable[[int], None]] = []

    def items(self, mission_type: int) -> tuple[MissionItem, ...]:
        """The stored list of ``mission_type`` (empty when none was uploaded)."""
        return self._lists[mission_type]

    def replace(self, mission_type: int, items: tuple[MissionItem, ...]) -> None:
        """Store a completed upload (or ``()`` for MISSION_CLEAR_ALL); resets the current item."""
        if mission_type not in self._lists:
            raise ValueError(f"unknown mission_type {mission_type}")
        self._lists[mission_type] = tuple(items)
        if mission_type == MISSION:
            self.current_seq = 0
        for listener in self._listeners:
            listener(mission_type)

    def set_current(self, seq: int) -> bool:
        """MISSION_SET_CURRENT: False when ``seq`` is not an item of the mission."""
        if not 0 <= seq < len(self._lists[MISSION]):
            return False
        self.current_seq = seq
        return True

    def on_change(self, listener: Callable[[int], None]) -> None:
        """Call ``listener(mission_type)`` after each :meth:`replace`."""
        self._listeners.append(listener)
