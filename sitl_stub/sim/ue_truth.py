"""The simulation's truth for ground pictures: each simulated UE as an ADSB_VEHICLE, once a frame.

Encoding in :mod:`uavlink.mavlink.ue_truth` (shared with the ground's tlog reader). Sent by the radio
payload's component right after the frame's readings, so a ground station's log holds, frame by
frame, where the UEs were when the base station sensed them. ``sitl-stub --no-ue-truth`` turns it
off (a vehicle that should look like real hardware on the ground station's map).
"""

from __future__ import annotations

from typing import Any

from uavlink.env.radio_world import RadioWorld
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.ue_truth import adsb_arguments


def send_ue_truth(mav: Any, world: RadioWorld, origin: GeoOrigin) -> None:
    """One ADSB_VEHICLE per UE of ``world`` at its current position, with ``mav``."""
    for ue, ((east, north), (ve, vn)) in enumerate(
        zip(world.ue_xy_m(), world.ue_velocity_mps(), strict=True)
    ):
        mav.adsb_vehicle_send(
            *adsb_arguments(ue, float(east), float(north), float(ve), float(vn), origin)
        )
