"""The MAVLink mission protocol (https://mavlink.io/en/services/mission.html), client side, and
the item codec both ends share.

:class:`MissionItem` is one item as a vehicle stores it (the SITL vehicle's
:mod:`sitl_stub.core.mission_store` keeps these); :func:`item_from_message` and :func:`send_item` turn it
into and out of MISSION_ITEM_INT (or the legacy float MISSION_ITEM). :class:`MissionClient` uploads,
downloads and clears a mission, fence or rally list and sets the current mission item over any
pymavlink ``mav``, with a ground station's timeouts and retries (QGroundControl's PlanManager: 1.5 s
per answer, 5 retries). Where its answers come from is the caller's: :func:`pymavlink_recv` reads a
plain pymavlink connection; ``uavlink fly`` feeds it from its own link loop.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from uavlink.mavlink.dialect import enum_name, mavlink
from uavlink.mavlink.frames import GLOBAL_FRAMES, deg_to_e7, e7_to_deg, height_above_home_m

MISSION = 0  # MAV_MISSION_TYPE_MISSION
FENCE = 1  # MAV_MISSION_TYPE_FENCE
RALLY = 2  # MAV_MISSION_TYPE_RALLY
MISSION_TYPES = (MISSION, FENCE, RALLY)
TYPE_NAMES = {MISSION: "mission", FENCE: "fence", RALLY: "rally"}
MISSION_REPLIES = (
    "MISSION_COUNT",
    "MISSION_ITEM",
    "MISSION_ITEM_INT",
    "MISSION_REQUEST",
    "MISSION_REQUEST_INT",
    "MISSION_ACK",
    "MISSION_CURRENT",
)
ANSWER_TIMEOUT_S = 1.5  # QGC PlanManager::_ackTimeoutMilliseconds
RETRIES = 5  # QGC PlanManager::_maxRetryCount

# the next mission message within ``timeout_s`` of wall time, or None
MissionRecv = Callable[[float], Any]


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT as stored: x/y are degrees * 1e7 in global frames, z metres."""

    seq: int
    frame: int
    command: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1
    mission_type: int = MISSION

    def lat_lon_deg(self) -> tuple[float, float]:
        """x/y as latitude/longitude in degrees (meaningful in a global frame)."""
        return e7_to_deg(self.x), e7_to_deg(self.y)

    def height_above_home_m(self, z_m: float, home_amsl_m: float) -> float:
        """The height above home of an altitude ``z_m`` given in this item's frame."""
        return height_above_home_m(z_m, self.frame, home_amsl_m)


class MissionTransferError(RuntimeError):
    """An upload, download or clear failed: refused (``result``, a MAV_MISSION_RESULT) or unanswered
    (``result`` None)."""

    def __init__(self, message: str, result: int | None = None) -> None:
        super().__init__(message)
        self.result = result


def item_from_message(msg: Any) -> MissionItem:
    """A MISSION_ITEM_INT or (legacy, float x/y) MISSION_ITEM as a :class:`MissionItem`."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM":
        x, y = (deg_to_e7(x), deg_to_e7(y)) if msg.frame in GLOBAL_FRAMES else (round(x), round(y))
    return MissionItem(
        int(msg.seq),
        int(msg.frame),
        int(msg.command),
        float(msg.param1),
        float(msg.param2),
        float(msg.param3),
        float(msg.param4),
        int(x),
        int(y),
        float(msg.z),
        int(msg.autocontinue),
        int(getattr(msg, "mission_type", 0)),
    )


def send_item(
    mav: Any,
    item: MissionItem,
    target_system: int,
    target_component: int,
    int_mode: bool = True,
    current: bool = False,
) -> None:
    """Send ``item`` as MISSION_ITEM_INT (``int_mode``) or as the legacy float MISSION_ITEM, whose
    global x / y are degrees where the int message carries degE7 (the two share their field order)."""
    x: float
    y: float
    if int_mode:
        send, x, y = mav.mission_item_int_send, item.x, item.y
    else:
        send, x, y = mav.mission_item_send, item.x, item.y
        if item.frame in GLOBAL_FRAMES:
            x, y = item.lat_lon_deg()
    send(
        target_system,
        target_component,
        item.seq,
        item.frame,
        item.command,
        int(current),
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        x,
        y,
        item.z,
        item.mission_type,
    )


def pymavlink_recv(conn: Any) -> MissionRecv:
    """A :data:`MissionRecv` reading the mission messages of a pymavlink connection."""
    return lambda timeout_s: conn.recv_match(
        type=list(MISSION_REPLIES), blocking=True, timeout=timeout_s
    )


class MissionClient:
    """One ground station's mission transfers with one vehicle (``target_system``/``_component``).

    Each wait for an answer lasts ``timeout_s`` of wall time; after ``retries`` unanswered waits in
    a row the transfer fails with :class:`MissionTransferError`. What is sent again on a timeout is
    what the protocol asks for: the MISSION_COUNT until the first request, then the last item (a
    vehicle that got it ignores the duplicate, one that lost its final ACK sends it again); the
    request of a download.
    """

    def __init__(
        self,
        mav: Any,
        recv: MissionRecv,
        target_system: int,
        target_component: int = 1,
        timeout_s: float = ANSWER_TIMEOUT_S,
        retries: int = RETRIES,
    ) -> None:
        self.mav = mav
        self.recv = recv
        self.target_system = target_system
        self.target_component = target_component
        self.timeout_s = timeout_s
        self.retries = retries

    # ------------------------------------------------------------------------- operations
    def upload(self, items: Sequence[MissionItem], mission_type: int = MISSION) -> None:
        """Replace the vehicle's ``mission_type`` list with ``items`` (renumbered 0..n-1)."""
        items = [replace(it, seq=i, mission_type=mission_type) for i, it in enumerate(items)]
        what = f"{TYPE_NAMES.get(mission_type, mission_type)} upload"
        last_sent: int | None = None

        def resend() -> None:
            if last_sent is None:
                self._send_count(len(items), mission_type)
            else:
                self._send(items[last_sent], True)

        self._send_count(len(items), mission_type)
        while True:
            msg = self._await(
                ("MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"),
                mission_type,
                resend,
                what,
            )
            if msg.get_type() == "MISSION_ACK":
                done = not items or last_sent == len(items) - 1
                if msg.type == mavlink.MAV_MISSION_ACCEPTED and done:
                    return
                raise MissionTransferError(
                    f"vehicle refused the {what}: {enum_name('MAV_MISSION_RESULT', msg.type)}",
                    msg.type,
                )
            if not 0 <= msg.seq < len(items):
                raise MissionTransferError(
                    f"vehicle asked for item {msg.seq} of {len(items)} in the {what}"
                )
            last_sent = msg.seq
            self._send(items[msg.seq], msg.get_type() == "MISSION_REQUEST_INT")

    def download(self, mission_type: int = MISSION) -> list[MissionItem]:
        """The vehicle's ``mission_type`` list (acknowledged with MISSION_ACK ACCEPTED)."""
        what = f"{TYPE_NAMES.get(mission_type, mission_type)} download"
        ts, tc = self.target_system, self.target_component
        self.mav.mission_request_list_send(ts, tc, mission_type)
        count = self._await(
            ("MISSION_COUNT",),
            mission_type,
            lambda: self.mav.mission_request_list_send(ts, tc, mission_type),
            what,
        ).count
        items: list[MissionItem] = []
        for seq in range(count):

            def request(seq: int = seq) -> None:
                self.mav.mission_request_int_send(ts, tc, seq, mission_type)

            def is_item(m: Any, seq: int = seq) -> bool:
                return m.seq == seq

            request()
            msg = self._await(
                ("MISSION_ITEM_INT", "MISSION_ITEM"),
                mission_type,
                request,
                what,
                is_item,
            )
            items.append(item_from_message(msg))
        self.mav.mission_ack_send(ts, tc, mavlink.MAV_MISSION_ACCEPTED, mission_type)
        return items

    def clear(self, mission_type: int = MISSION) -> None:
        """MISSION_CLEAR_ALL, until the vehicle's ACK (an error ACK raises)."""
        ts, tc = self.target_system, self.target_component
        self.mav.mission_clear_all_send(ts, tc, mission_type)
        what = f"{TYPE_NAMES.get(mission_type, mission_type)} clear"
        ack = self._await(
            ("MISSION_ACK",),
            mission_type,
            lambda: self.mav.mission_clear_all_send(ts, tc, mission_type),
            what,
        )
        if ack.type != mavlink.MAV_MISSION_ACCEPTED:
            raise MissionTransferError(
                f"vehicle refused the {what}: {enum_name('MAV_MISSION_RESULT', ack.type)}", ack.type
            )

    def set_current(self, seq: int) -> None:
        """MISSION_SET_CURRENT, until a MISSION_CURRENT shows ``seq``."""
        ts, tc = self.target_system, self.target_component
        self.mav.mission_set_current_send(ts, tc, seq)
        self._await(
            ("MISSION_CURRENT",),
            None,
            lambda: self.mav.mission_set_current_send(ts, tc, seq),
            f"set current item {seq}",
            lambda m: m.seq == seq,
        )

    # ---------------------------------------------------------------------------- helpers
    def _send_count(self, count: int, mission_type: int) -> None:
        self.mav.mission_count_send(self.target_system, self.target_component, count, mission_type)

    def _send(self, item: MissionItem, int_mode: bool) -> None:
        send_item(self.mav, item, self.target_system, self.target_component, int_mode)

    def _await(
        self,
        kinds: tuple[str, ...],
        mission_type: int | None,
        resend: Callable[[], None],
        what: str,
        accept: Callable[[Any], bool] = lambda m: True,
    ) -> Any:
        """The next message of ``kinds`` for us (and of ``mission_type``) that ``accept`` takes;
        ``resend()`` after each unanswered wait; MissionTransferError after ``retries`` of them."""
        me = self.mav.srcSystem
        for _ in range(self.retries + 1):
            deadline = time.monotonic() + self.timeout_s
            while (left := deadline - time.monotonic()) > 0:
                msg = self.recv(left)
                if msg is not None and (
                    msg.get_type() in kinds
                    and msg.get_srcSystem() == self.target_system
                    and getattr(msg, "target_system", me) in (0, me)
                    and (mission_type is None or getattr(msg, "mission_type", 0) == mission_type)
                    and accept(msg)
                ):
                    return msg
            resend()
        raise MissionTransferError(
            f"no answer from the vehicle to the {what} after {self.retries} retries"
        )
