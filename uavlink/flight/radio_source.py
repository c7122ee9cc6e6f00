"""Where the flight loop gets radio readings: one small interface.

In simulation the readings arrive over MAVLink from the SITL's radio payload
(``MavlinkRadioSource``); on a real aircraft an adapter to the onboard base station implements the
same two members and the loop does not change.
"""

from __future__ import annotations

import logging
from typing import Protocol

from uavlink.mavlink.radio_codec import RadioReport, RadioReportError, decode_readings
from uavlink.mavlink.rejects import RejectLog

log = logging.getLogger(__name__)


class RadioSource(Protocol):
    n_ues: int

    def take_reports(self) -> list[RadioReport]:
        """Reports received since the last call, oldest first (non-blocking)."""
        ...


class MavlinkRadioSource:
    """Decodes UL_RADIO messages handed over by the link; invalid ones (wrong UE count, NaN or
    out-of-range values) are counted in ``rejected`` and logged once per reason."""

    def __init__(self, n_ues: int) -> None:
        self.n_ues = n_ues
        self.rejected = 0
        self.rejects = RejectLog(log)
        self._pending: list[RadioReport] = []

    def feed(self, msg) -> None:
        try:
            self._pending.append(decode_readings(msg, self.n_ues))
        except RadioReportError as exc:
            self.rejected += 1
            self.rejects.reject("radio_report", f"radio report: {exc}", key=str(exc))

    def take_reports(self) -> list[RadioReport]:
        reports, self._pending = self._pending, []
        return reports
