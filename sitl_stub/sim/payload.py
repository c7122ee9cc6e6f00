"""The payload hook: extra MAVLink components on the vehicle's system, ticked per frame.

A payload (the radio simulator's base station, a camera, ...) is its own component, as on a real
aircraft. The server sends its HEARTBEAT at the autopilot's rate (>= 1 Hz wall time) with the
arguments from :meth:`Payload.heartbeat`, and calls :meth:`Payload.on_frame` once per
``frame_s`` simulated seconds, at sim times 0, frame_s, 2 frame_s, ..., with the vehicle state
at exactly that time. ``mav`` is a pymavlink ``MAVLink`` object whose ``srcSystem`` is the
vehicle's and ``srcComponent`` is the payload's ``component_id``: use its ``*_send`` methods.

Per the SPEC, MAVSDK reads the autopilot type and flight mode from *any* heartbeat of the
system, so a payload heartbeat must carry ``MAV_AUTOPILOT_INVALID`` (8) and base_mode 0; the
server refuses a payload whose heartbeat does not.

Commands (COMMAND_LONG/INT) addressed to a payload's component id go to its optional
``on_command(msg, mav) -> int | None`` (a MAV_RESULT to ACK, or None to ACK nothing); without
that method they are ACKed MAV_RESULT_UNSUPPORTED from the payload's component, and MAV_RESULT_FAILED
when it raises. An optional ``summary() -> dict`` is included in the server's ``report()`` (and so
in ``sitl-stub``'s exit stats line). Broadcast
commands (target_component 0) are answered by the autopilot only.

Lockstep: a payload whose ``lockstep`` attribute is true gets the vehicle's LOCAL_POSITION_NED sent
just before each of its frames, and its optional ``holds_clock(state) -> bool`` asked after each: while it
returns True, simulated time stays at that frame (the server keeps handling messages and sending
heartbeats), e.g. until the flight computer has answered the frame; it must give up by itself after
a while of wall time, or a silent client would stop the vehicle's world.

The CLI builds payloads with a factory ``(PayloadOptions) -> Payload | Sequence[Payload] | None``;
this hook knows no implementation (the CLI's default is the radio payload, ``sitl_stub.__main__``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

from sitl_stub.core.vehicle_state import VehicleState
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.geo import GeoOrigin

MAV_AUTOPILOT_INVALID = mavlink.MAV_AUTOPILOT_INVALID


@runtime_checkable
class Payload(Protocol):
    """An extra component of the vehicle's MAVLink system."""

    component_id: int
    frame_s: float  # simulated seconds between on_frame calls (1.0: one decision frame)

    def heartbeat(self) -> tuple[int, int, int, int, int]:
        """``heartbeat_send`` arguments: (MAV_TYPE, MAV_AUTOPILOT_INVALID, 0, custom_mode,
        MAV_STATE)."""
        ...

    def on_frame(self, sim_time_s: float, state: VehicleState, mav: Any) -> None:
        """One frame: read ``state`` and send this frame's messages with ``mav``."""
        ...


@dataclass(frozen=True)
class PayloadOptions:
    """What the CLI passes to a payload factory."""

    scenario: str = "circular"
    seed: int = 0
    aoa_noise_deg: float = 0.0
    settings: tuple[tuple[str, object], ...] = ()  # --set KEY=VALUE: the radio payload's env fields
    home: GeoOrigin = GeoOrigin()  # the LOCAL_NED origin: where the UE truth is placed on Earth
    ue_truth: bool = True  # send the simulated UEs as ADSB_VEHICLE (sitl_stub.sim.ue_truth)
    # Hold each frame of a running episode until the flight computer decides it.
    lockstep: bool = False


@dataclass
class PayloadSlot:
    """A payload as the server runs it: its own MAVLink sender and its next frame."""

    payload: Payload
    mav: Any
    next_frame: int = 0
    failures: int = 0


PayloadFactory = Callable[[PayloadOptions], "Payload | Sequence[Payload] | None"]


def as_payload_list(made: Payload | Sequence[Payload] | None) -> list[Payload]:
    """Normalise a factory's result to a list."""
    if made is None:
        return []
    if isinstance(made, Sequence):
        return list(made)
    return [made]


def check_payload(payload: Payload, system_component_ids: set[int]) -> None:
    """Raise ValueError when a payload breaks the hook's contract."""
    cid = int(payload.component_id)
    if not 2 <= cid <= 255 or cid in system_component_ids:
        raise ValueError(f"payload component_id must be unique in 2..255, got {cid}")
    if not payload.frame_s > 0:
        raise ValueError(f"payload frame_s must be > 0, got {payload.frame_s}")
    hb = tuple(payload.heartbeat())
    if len(hb) != 5 or hb[1] != MAV_AUTOPILOT_INVALID or hb[2] != 0:
        raise ValueError(
            f"payload {cid} heartbeat must be (type, MAV_AUTOPILOT_INVALID=8, base_mode=0, "
            f"custom_mode, system_status), got {hb}"
        )
