"""The observation: what the base station senses, stacked over the last M frames.

One piece of code, shared by the env and the flight loop. A frame is the fields of ``FIELDS`` in
order, declared once with their encoding, decoding and bounds (newest frame first in the vector):
  UAV x, y / half-width; per-UE effective SINR, (dB - offset) / scale, clipped;
  sin and cos of the circular-mean AoA; circular std of the AoAs (radians / pi, at most 2).
Never UE positions. A fleet's UAV (layout v2, ``n_uavs`` > 1) sees the same fields from where it
is (every UE's uplink reference signal as it hears it) plus what the fleet shares over its own
links (``FLEET_FIELDS``): the other UAVs' positions, the AoA statistics of the UEs it serves (its
cell; (0, 0) and the largest std for an empty cell) and which UAV serves each UE, numbered from the
observing UAV (0 = itself, then the next ones in fleet order), so every UAV has the same layout and
one policy serves them all. The layout is versioned and saved with every policy; the frame's size,
the feature names, the bounds, the slices and the decoders all follow from the tables, so adding a
field is one entry (and a new version). With a memory of place (``place_cell_m`` > 0; layout v3,
v4 for a fleet) every frame also carries ``PLACE_FIELDS``: a summary of what the UAV sensed where
(``uavlink.env.place_memory``), kept by the builder, so env and flight build it with the same code.
A fleet of any size (layout v6, ``EnvConfig.fleet_slots`` > 0) replaces v2's per-D fields with
``SLOT_FIELDS``, whose size does not depend on D (``fleet_view``): one policy flies 2 to
``fleet_slots`` + 1 UAVs; with a memory of place too, layout v7; with each UAV's own model of the
sensed field too (``place_model = "kriging"``), layout v8; with one model per fleet that every UAV
feeds and picks from (``place_model = "pooled"``), layout v9: the same fields as v8.

Modules: ``fields`` (one UAV's fields, the memory of place's), ``fleet_view`` (a fleet's fields and
quantities) and ``layout`` (:class:`ObservationLayout`).

May import: ``config``, ``errors``, ``radio`` (a part of ``uavlink.env``).
"""

from uavlink.env.observation.fields import (
    FIELDS,
    KRIGING_FIELDS,
    PLACE_AGE_SCALE_FRAMES,
    PLACE_FIELDS,
    PLACE_GAIN_CLIP_BITS,
    Field,
)
from uavlink.env.observation.fleet_view import (
    FLEET_FIELDS,
    SLOT_FIELDS,
    fleet_quantities,
    fleet_view_quantities,
)
from uavlink.env.observation.layout import (
    ANY_FLEET_KRIGING_LAYOUT_VERSION,
    ANY_FLEET_LAYOUT_VERSION,
    ANY_FLEET_PLACE_LAYOUT_VERSION,
    ANY_FLEET_POOLED_LAYOUT_VERSION,
    FLEET_LAYOUT_VERSION,
    FLEET_PLACE_LAYOUT_VERSION,
    KRIGING_LAYOUT_VERSION,
    OBS_LAYOUT_VERSION,
    PLACE_LAYOUT_VERSION,
    ObservationLayout,
)

__all__ = [
    "ANY_FLEET_KRIGING_LAYOUT_VERSION",
    "ANY_FLEET_POOLED_LAYOUT_VERSION",
    "ANY_FLEET_LAYOUT_VERSION",
    "ANY_FLEET_PLACE_LAYOUT_VERSION",
    "FIELDS",
    "FLEET_FIELDS",
    "FLEET_LAYOUT_VERSION",
    "FLEET_PLACE_LAYOUT_VERSION",
    "KRIGING_FIELDS",
    "KRIGING_LAYOUT_VERSION",
    "OBS_LAYOUT_VERSION",
    "PLACE_AGE_SCALE_FRAMES",
    "PLACE_FIELDS",
    "PLACE_GAIN_CLIP_BITS",
    "PLACE_LAYOUT_VERSION",
    "SLOT_FIELDS",
    "Field",
    "ObservationLayout",
    "fleet_quantities",
    "fleet_view_quantities",
]
