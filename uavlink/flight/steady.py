"""Short pauses in the flight loop: with a policy loaded (torch, SB3, pymavlink), one pass of Python's
cyclic garbage collector over every object takes 0.2-0.4 s on a 2-core machine, longer than a
vehicle at 20x real time waits for offboard setpoints (COM_OF_LOSS_T = 1 s of vehicle time: 50 ms
of wall time), so a flight that met one mid-episode fell back to hold (research/log/flight.md,
"A pause in the fleet's flights")."""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def steady_heap() -> Iterator[None]:
    """Collect once, then freeze every object there is into the collector's permanent generation
    for the flight (``gc.freeze``): its later passes scan only what the flight allocates. Unfrozen
    after, so the objects are collected as usual again. Enter it before any vehicle sends to this
    process: the collection itself pauses it as long, and messages queued meanwhile arrive together
    (``uavlink.flight.link.vehicle_status.CLOCK_WINDOW_S``)."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
