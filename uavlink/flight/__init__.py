"""Flying a policy over MAVLink (``uavlink fly``): ``link`` (the MAVLink ground end: one vehicle's
link, what it knows of each system, a fleet's links as one group), ``radio_source`` (the payload's
radio readings), ``vehicle_control`` (wait until ready, take off, OFFBOARD, land), ``loop`` and
``fleet_loop`` (the flight loop for one UAV and a fleet), ``result`` (what a flight did: was it
complete, and if not why and what to do; its summary and status line), ``steady`` (a frozen
heap while flying), ``start_point`` (a later flight flies to the episode's start first),
``fence``, ``vehicles`` (the embedded SITL or the vehicles ``--connect`` names) and ``fly`` (``fly_policy`` and its ``FlyOptions``: a flight from
Python; ``run_fly``: the command). Layer: the top, below only the CLI.

May import: ``config``, ``errors``, ``mobility``, ``env``, ``mavlink``, ``policies``, ``plot`` (the
flight picture) and ``sitl_stub.launcher`` (the vehicle as a child process); never ``learn``,
``evaluation`` or ``sweep``.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["FlyOptions", "fly_policy"]

# The embedded vehicle's speed unless --speed says otherwise: simulated seconds per wall second.
EMBEDDED_SPEED = 20.0


def __getattr__(name: str) -> Any:  # resolved on first use: importing the package loads no link
    if name not in __all__:
        raise AttributeError(f"module 'uavlink.flight' has no attribute {name!r}")
    return getattr(importlib.import_module("uavlink.flight.fly"), name)
