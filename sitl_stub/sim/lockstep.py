"""Lockstep: a radio frame that holds simulated time until the flight computer has decided it.

The env steps only when given an action; a flight computer decides while the vehicle's time runs
on, so without a hold a decision reaches the vehicle a few wall milliseconds (tens of simulated
ones at 20x) late, by a different amount every time. A held frame waits for ``FRAME_DECIDED``
(``uavlink.mavlink.radio_codec``) from each of its deciders (a fleet's vehicles in OFFBOARD), at most
``LOCKSTEP_WAIT_WALL_S`` of wall time: a flight computer that does not answer slows the world down
but never stops it.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.radio_codec import FRAME_DECIDED_COMMAND

LOCKSTEP_WAIT_WALL_S = 2.0

log = logging.getLogger(__name__)


class FrameHold:
    """The frame being held, if any, and who still has to answer it."""

    def __init__(self) -> None:
        self.frame: int | None = None
        self.waiting: set[int] = set()
        self.since_wall = 0.0
        self.timeouts = 0

    def hold(self, frame: int, deciders: set[int] | None = None) -> None:
        """Hold ``frame`` until each of ``deciders`` (vehicle indices; default the one vehicle,
        0) has answered it."""
        self.frame, self.since_wall = frame, time.monotonic()
        self.waiting = {0} if deciders is None else set(deciders)

    def on_command(self, msg: Any, decider: int = 0) -> int | None:
        """A payload's ``on_command``: FRAME_DECIDED (param1: the frame) answers the held frame
        (or a later one); no ACK. Anything else: MAV_RESULT_UNSUPPORTED."""
        if msg.command != FRAME_DECIDED_COMMAND:
            return mavlink.MAV_RESULT_UNSUPPORTED
        if self.frame is not None and msg.param1 >= self.frame:
            self.waiting.discard(decider)
            if not self.waiting:
                self.frame = None
        return None

    def holding(self, flying: bool = True) -> bool:
        """True while the held frame waits for its decisions: the wall wait is not over, and
        ``flying`` (a vehicle still in OFFBOARD: one that has left it decides nothing more)."""
        if self.frame is None:
            return False
        if not flying:
            self.frame = None
            return False
        if time.monotonic() - self.since_wall <= LOCKSTEP_WAIT_WALL_S:
            return True
        self.timeouts += 1
        if self.timeouts == 1:
            log.warning(
                "lockstep: frame %d got no FRAME_DECIDED within %g s of wall time: going on "
                "without it (is the flight computer in lockstep?)",
                self.frame,
                LOCKSTEP_WAIT_WALL_S,
            )
        self.frame = None
        return False
