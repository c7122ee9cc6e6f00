"""What a fleet's UAV sees of the others, over the fleet's own links (SPEC "A fleet").

Two layouts: v2, for a fleet of exactly D (``FLEET_FIELDS``: the others' positions in fleet order,
which UAV serves each UE), and v6, for a fleet of any size up to ``uav_slots`` + 1
(``SLOT_FIELDS``): the others as a fixed number of slots, nearest first, with a mask; per UE
whether this UAV serves it and where its server is, relative to this UAV; and where the UE is, as
the bearings every UAV hears of it cross (a fix from the fleet's AoAs, never from the UE's GPS).
``fleet_view_quantities`` gives either layout's quantities, for the env and the flight loop alike.
"""

from __future__ import annotations

import numpy as np

from uavlink.env.observation.fields import Field, LayoutShape, aoa_fields, offset_field
from uavlink.radio.aoa import bearing_fix_xy_m

FLEET_FIELDS: tuple[Field, ...] = (
    Field(
        "others_xy_m",
        ("other_x", "other_y"),
        per="other_uav",
        encode=lambda layout, q: (
            q["others_xy_m"].reshape(len(q["others_xy_m"]), -1) / layout.half_width_m
        ),
        decode=lambda layout, x: x.reshape(*x.shape[:-1], -1, 2) * layout.half_width_m,
        bounds=lambda layout: (-1.0, 1.0),
    ),
    *aoa_fields("cell_aoa"),
    Field(
        "served_by",
        ("served_by",),
        per="ue_uav",
        encode=lambda layout, q: (
            (q["served_by"][..., None] == np.arange(layout.n_uavs))
            .reshape(len(q["served_by"]), -1)
            .astype(np.float32)
        ),
        decode=lambda layout, x: x.reshape(*x.shape[:-1], layout.n_ues, layout.n_uavs).argmax(
            axis=-1
        ),
        bounds=lambda layout: (0.0, 1.0),
    ),
)


def fleet_quantities(uav_xy_m: np.ndarray, serving: np.ndarray) -> dict[str, np.ndarray]:
    """What a fleet shares, as each UAV sees it, rows (N D) in fleet order: ``others_xy_m``
    (N D, D-1, 2), the other UAVs in the order d+1, d+2, ... (wrapping), and ``served_by``
    (N D, U), the index of each UE's UAV counted from the observing one. ``uav_xy_m`` (N, D, 2),
    ``serving`` (N, U)."""
    n_envs, n_uavs = uav_xy_m.shape[:2]
    me = np.arange(n_uavs)
    order = (me[:, None] + np.arange(1, n_uavs)) % n_uavs  # (D, D-1)
    others = uav_xy_m[:, order]  # (N, D, D-1, 2)
    served_by = (serving[:, None, :] - me[None, :, None]) % n_uavs  # (N, D, U)
    return {
        "others_xy_m": others.reshape(n_envs * n_uavs, n_uavs - 1, 2),
        "served_by": served_by.reshape(n_envs * n_uavs, -1),
    }


def flag_field(quantity: str, per: str) -> Field:
    """A yes/no per ``per`` item (slot or UE), encoded 0 / 1 and decoded as bool."""
    return Field(
        quantity,
        (quantity,),
        per=per,
        encode=lambda layout, q: q[quantity].astype(np.float32),
        decode=lambda layout, x: x > 0.5,
        bounds=lambda layout: (0.0, 1.0),
    )


# Layout v6: a fleet of any size up to ``uav_slots`` + 1 (SPEC "A fleet of any size").
SLOT_FIELDS: tuple[Field, ...] = (
    offset_field("slot_offset_m", ("slot_dx", "slot_dy"), per="slot"),
    flag_field("slot_present", per="slot"),
    *aoa_fields("cell_aoa"),
    flag_field("served_here", per="ue"),
    offset_field("server_offset_m", ("server_dx", "server_dy"), per="ue"),
    offset_field("ue_fix_offset_m", ("ue_fix_dx", "ue_fix_dy"), per="ue"),
)


def slot_quantities(
    uav_xy_m: np.ndarray,
    serving: np.ndarray,
    aoa_deg: np.ndarray,
    uav_slots: int,
    half_width_m: float,
) -> dict[str, np.ndarray]:
    """Layout v6's fleet quantities, rows (N D) in fleet order, from UAV positions (N, D, 2), each
    UE's serving UAV (N, U) and the AoAs every UAV hears (N, D, U): ``slot_offset_m`` (N D, K, 2),
    the other UAVs nearest first relative to this one (zeros past the last, ``slot_present`` 0
    there); ``served_here`` (N D, U); ``server_offset_m`` (N D, U, 2), the UE's serving UAV relative
    to this one; ``ue_fix_offset_m`` (N D, U, 2), the UE's bearing fix
    (:func:`~uavlink.radio.aoa.bearing_fix_xy_m`, clipped to the area) relative to this UAV."""
    n_envs, n_uavs = uav_xy_m.shape[:2]
    if n_uavs - 1 > uav_slots:
        raise ValueError(f"{n_uavs} UAVs need {n_uavs - 1} slots; the layout has {uav_slots}")
    rows = n_envs * n_uavs
    offset = uav_xy_m[:, None, :, :] - uav_xy_m[:, :, None, :]  # (N, me, other, 2)
    gap = np.linalg.norm(offset, axis=-1)
    gap[:, np.arange(n_uavs), np.arange(n_uavs)] = np.inf
    nearest = np.argsort(gap, axis=2, kind="stable")[:, :, : n_uavs - 1]  # ties: fleet order
    slots = np.zeros((n_envs, n_uavs, uav_slots, 2))
    slots[:, :, : n_uavs - 1] = np.take_along_axis(offset, nearest[..., None], axis=2)
    present = np.zeros((rows, uav_slots), dtype=bool)
    present[:, : n_uavs - 1] = True
    server_xy = np.take_along_axis(uav_xy_m, serving[..., None], axis=1)  # (N, U, 2)
    fix_xy = np.clip(bearing_fix_xy_m(uav_xy_m, aoa_deg), -half_width_m, half_width_m)
    return {
        "slot_offset_m": slots.reshape(rows, uav_slots, 2),
        "slot_present": present,
        "served_here": (serving[:, None, :] == np.arange(n_uavs)[None, :, None]).reshape(rows, -1),
        "server_offset_m": (server_xy[:, None] - uav_xy_m[:, :, None]).reshape(rows, -1, 2),
        "ue_fix_offset_m": (fix_xy[:, None] - uav_xy_m[:, :, None]).reshape(rows, -1, 2),
    }


def fleet_view_quantities(
    layout: LayoutShape, uav_xy_m: np.ndarray, serving: np.ndarray, aoa_deg: np.ndarray
) -> dict[str, np.ndarray]:
    """What ``layout`` shows of the fleet, rows (N D): v6's slots (``uav_slots`` > 0), v2's fleet
    fields (``n_uavs`` > 1), nothing for one UAV. ``uav_xy_m`` (N, D, 2), ``serving`` (N, U),
    ``aoa_deg`` (N, D, U). The env and the flight loop both build a fleet's rows here."""
    if layout.uav_slots > 0:
        return slot_quantities(uav_xy_m, serving, aoa_deg, layout.uav_slots, layout.half_width_m)
    if uav_xy_m.shape[1] > 1:
        return fleet_quantities(uav_xy_m, serving)
    return {}
