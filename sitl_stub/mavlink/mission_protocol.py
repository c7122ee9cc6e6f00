"""The mission microservice on the vehicle, as PX4's ``MavlinkMissionManager`` serves it
(src/modules/mavlink/mavlink_mission.cpp; https://mavlink.io/en/services/mission.html).

For mission_type MISSION, FENCE and RALLY, one transfer at a time per link:

- upload: MISSION_COUNT -> MISSION_REQUEST_INT seq 0 -> MISSION_ITEM_INT ... -> MISSION_ACK. The
  vehicle re-requests the awaited item every :data:`RETRY_TIMEOUT_S` of wall time; items out of
  sequence are ignored (the re-request asks again); :data:`PROTOCOL_TIMEOUT_S` without a message
  from the partner ends the transfer ("Operation timeout"). A MISSION_COUNT sent again before the
  first item restarts the requests; one from another ground station, or during a download, gets
  MISSION_ACK ERROR, as does any upload while another link's upload runs (PX4's shared
  ``_transfer_in_progress``). An item whose frame or command PX4's parser refuses ends the upload
  with that result (UNSUPPORTED_FRAME, UNSUPPORTED, INVALID_PARAM1), and so does a fence or rally
  command in a mission or a polygon of fewer than 3 vertices (ERROR). A completed upload replaces the
  list in the :class:`~sitl_stub.core.mission_store.MissionStore` (one identical to the stored list
  changes nothing); a failed one leaves the old list. The last item sent again after the final ACK
  (the ACK was lost) is acknowledged again.
- download: MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST(_INT) for each seq ->
  MISSION_ITEM(_INT) -> MISSION_ACK. The next seq or the previous one again is answered, anything
  else ends the download with MISSION_ACK ERROR. Global items are sent in the frame of the request's
  kind (GLOBAL <-> GLOBAL_INT), as PX4's ``format_mavlink_mission_item``.
- MISSION_CLEAR_ALL (one type, or MAV_MISSION_TYPE_ALL) -> MISSION_ACK; MISSION_SET_CURRENT ->
  MISSION_CURRENT; both ignored with a STATUSTEXT while a transfer runs.

Legacy MISSION_ITEM / MISSION_REQUEST (float x/y) are served as PX4 serves them: the vehicle
switches to the float messages for the rest of the transfer. Differences from PX4: when an upload
times out the vehicle also sends MISSION_ACK OPERATION_CANCELLED (mavlink.io's advice; PX4 only
sends the STATUSTEXT); a download whose items were all sent ends quietly without the GCS's ACK
(MAVProxy sends none) rather than with "Operation timeout", and it blocks no other request (PX4
lets only a new MISSION_REQUEST_LIST through, so MAVProxy's ``wp list`` then ``fence load`` would
meet "Busy" for 5 s). Replies go out on ``mav``, the link the request came on.

Each refusal (an error MISSION_ACK, a REJ./IGN STATUSTEXT) is counted by ``reject`` (the server's
RejectLog, logged once per reason) as ``mission_{count,item,request,clear,current}_refused``; items
out of sequence and requests with no download running are ignored as PX4 does, not counted.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from dataclasses import replace
from enum import Enum
from typing import Any

from sitl_stub.core.mission_store import (
    FENCE,
    MISSION,
    MISSION_TYPES,
    RALLY,
    MissionItem,
    MissionStore,
)
from uavlink.mavlink.dialect import enum_name, mavlink
from uavlink.mavlink.frames import GLOBAL_FRAMES, TO_FLOAT_FRAME, TO_INT_FRAME
from uavlink.mavlink.mission import item_from_message, send_item

RETRY_TIMEOUT_S = 0.25  # MAVLINK_MISSION_RETRY_TIMEOUT_DEFAULT (wall)
PROTOCOL_TIMEOUT_S = 5.0  # MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT (wall)
# PX4's dataman capacity (dataman.h: 64 fence points, 32 safe points; missions
# CONFIG_NUM_MISSION_ITMES_SUPPORTED, 1000 here)
MAX_COUNT = {MISSION: 1000, FENCE: 64, RALLY: 32}
MISSION_PLANNER_COMPONENT = mavlink.MAV_COMP_ID_MISSIONPLANNER  # PX4 accepts it as a target
CRITICAL = mavlink.MAV_SEVERITY_CRITICAL


def _cmds(*names: str) -> frozenset[int]:
    return frozenset(
        getattr(mavlink, f"MAV_CMD_{n}") for n in names if hasattr(mavlink, f"MAV_CMD_{n}")
    )


# What PX4's parse_mavlink_mission_item takes: commands with a position (global frames) ...
POSITION_COMMANDS = _cmds(
    "NAV_WAYPOINT",
    "NAV_LOITER_UNLIM",
    "NAV_LOITER_TIME",
    "NAV_LAND",
    "NAV_TAKEOFF",
    "NAV_LOITER_TO_ALT",
    "NAV_ROI",
    "DO_SET_ROI",
    "DO_SET_ROI_LOCATION",
    "NAV_VTOL_TAKEOFF",
    "NAV_VTOL_LAND",
    "CONDITION_GATE",
    "NAV_FENCE_RETURN_POINT",
    "NAV_FENCE_POLYGON_VERTEX_INCLUSION",
    "NAV_FENCE_POLYGON_VERTEX_EXCLUSION",
    "NAV_FENCE_CIRCLE_INCLUSION",
    "NAV_FENCE_CIRCLE_EXCLUSION",
    "NAV_RALLY_POINT",
    "COMPONENT_ARM_DISARM",
    "DO_AUTOTUNE_ENABLE",
)
# ... and commands without one (MAV_FRAME_MISSION)
MISSION_FRAME_COMMANDS = _cmds(
    "DO_JUMP",
    "NAV_ROI",
    "DO_SET_ROI",
    "DO_WINCH",
    "DO_GRIPPER",
    "DO_CHANGE_SPEED",
    "DO_SET_HOME",
    "DO_LAND_START",
    "DO_TRIGGER_CONTROL",
    "DO_DIGICAM_CONTROL",
    "DO_MOUNT_CONFIGURE",
    "DO_MOUNT_CONTROL",
    "DO_GIMBAL_MANAGER_PITCHYAW",
    "SET_CAMERA_FOCUS",
    "DO_GIMBAL_MANAGER_CONFIGURE",
    "IMAGE_START_CAPTURE",
    "IMAGE_STOP_CAPTURE",
    "VIDEO_START_CAPTURE",
    "VIDEO_STOP_CAPTURE",
    "DO_CONTROL_VIDEO",
    "DO_SET_CAM_TRIGG_DIST",
    "OBLIQUE_SURVEY",
    "DO_SET_CAM_TRIGG_INTERVAL",
    "SET_CAMERA_MODE",
    "SET_CAMERA_SOURCE",
    "DO_VTOL_TRANSITION",
    "NAV_DELAY",
    "NAV_RETURN_TO_LAUNCH",
    "DO_SET_ROI_WPNEXT_OFFSET",
    "DO_SET_ROI_NONE",
    "CONDITION_DELAY",
    "CONDITION_DISTANCE",
    "DO_SET_ACTUATOR",
    "DO_AUTOTUNE_ENABLE",
    "COMPONENT_ARM_DISARM",
)
FENCE_RALLY_COMMANDS = _cmds(
    "NAV_FENCE_POLYGON_VERTEX_INCLUSION",
    "NAV_FENCE_POLYGON_VERTEX_EXCLUSION",
    "NAV_FENCE_CIRCLE_INCLUSION",
    "NAV_FENCE_CIRCLE_EXCLUSION",
    "NAV_RALLY_POINT",
)
POLYGON_COMMANDS = _cmds("NAV_FENCE_POLYGON_VERTEX_INCLUSION", "NAV_FENCE_POLYGON_VERTEX_EXCLUSION")
ROI_COMMANDS = _cmds("NAV_ROI", "DO_SET_ROI")
FLOAT_FRAMES, INT_ONLY_FRAMES = frozenset(TO_INT_FRAME), frozenset(TO_FLOAT_FRAME)

# the protocol uploading into each store: one upload per vehicle, whatever the link
_uploading: weakref.WeakKeyDictionary[MissionStore, MissionProtocol] = weakref.WeakKeyDictionary()


class State(Enum):
    IDLE = "idle"
    GETLIST = "receiving"  # an upload: the vehicle gets the list
    SENDLIST = "sending"  # a download: the vehicle sends the list


def check_item(item: MissionItem, int_mode: bool) -> int:
    """PX4's verdict on one item (``parse_mavlink_mission_item`` and the per-type checks):
    a MAV_MISSION_RESULT."""
    frames = FLOAT_FRAMES | (INT_ONLY_FRAMES if int_mode else frozenset())
    if item.frame in frames:
        if item.command not in POSITION_COMMANDS:
            return mavlink.MAV_MISSION_UNSUPPORTED
        if item.command in ROI_COMMANDS and int(item.param1) not in (
            mavlink.MAV_ROI_LOCATION,
            mavlink.MAV_ROI_NONE,
        ):
            return mavlink.MAV_MISSION_INVALID_PARAM1
    elif item.frame == mavlink.MAV_FRAME_MISSION:
        if item.command not in MISSION_FRAME_COMMANDS:
            return mavlink.MAV_MISSION_UNSUPPORTED
        if item.command in ROI_COMMANDS and int(item.param1) not in (
            mavlink.MAV_ROI_NONE,
            mavlink.MAV_ROI_WPNEXT,
            mavlink.MAV_ROI_WPINDEX,
        ):
            return mavlink.MAV_MISSION_INVALID_PARAM1
    else:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    if item.mission_type == MISSION and item.command in FENCE_RALLY_COMMANDS:
        return mavlink.MAV_MISSION_ERROR
    if (
        item.mission_type == FENCE
        and item.command in POLYGON_COMMANDS
        and int(item.param1 + 0.5) < 3
    ):
        return mavlink.MAV_MISSION_ERROR  # PX4: "Fence: too few vertices"
    return mavlink.MAV_MISSION_ACCEPTED


class MissionProtocol:
    """One link's mission manager over the vehicle's ``store``; :meth:`handle` each MISSION_*
    message, :meth:`tick` every loop (wall time drives the re-requests and timeouts)."""

    def __init__(
        self,
        store: MissionStore,
        mav: Any,
        system_id: int,
        statustext: Callable[[int, str], None],
        component_id: int = 1,
        reject: Callable[..., object] | None = None,
    ) -> None:
        self.store = store
        self.reject = reject or (lambda kind, text, key=None: None)  # RejectLog.reject
        self.mav = mav
        self.system_id = system_id
        self.component_ids = (0, component_id, MISSION_PLANNER_COMPONENT)
        self.statustext = statustext
        self.state = State.IDLE
        self.mission_type = MISSION
        self.partner = (0, 0)
        self.int_mode = True
        self.transfer_seq = 0
        self.transfer_count = 0
        self._received: list[MissionItem] = []
        self._sending: tuple[MissionItem, ...] = ()
        self._current_marked = -1
        self._last_sent = 0.0
        self._last_recv = 0.0

    # ------------------------------------------------------------------------- entry points
    def handle(self, msg: Any, wall: float) -> bool:
        """Act on a mission message addressed to this vehicle; False for anything else."""
        kind = msg.get_type()
        handler = self._HANDLERS.get(kind)
        if (
            handler is None
            or getattr(msg, "target_system", None) != self.system_id
            or msg.target_component not in self.component_ids
        ):
            return False
        if (
            self.state is State.SENDLIST
            and self.transfer_seq >= self.transfer_count
            and kind not in ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")
        ):
            self._idle()  # a finished download whose ACK never came (MAVProxy sends none)
        handler(self, msg, (msg.get_srcSystem(), msg.get_srcComponent()), wall)
        return True

    def tick(self, wall: float) -> None:
        """Re-request the awaited item; end a transfer whose partner went quiet."""
        if self.state is not State.IDLE and wall - self._last_recv > PROTOCOL_TIMEOUT_S:
            if self.state is State.GETLIST:
                self.statustext(CRITICAL, "Operation timeout")
                self._ack(self.partner, mavlink.MAV_MISSION_OPERATION_CANCELLED)
            elif self.transfer_seq < self.transfer_count:
                self.statustext(CRITICAL, "Operation timeout")
            self._idle()
        elif self.state is State.GETLIST and wall - self._last_sent > RETRY_TIMEOUT_S:
            self._request(self.transfer_seq, wall)

    # ------------------------------------------------------------------------------ upload
    def _on_count(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        if self.state is State.GETLIST:
            self._last_recv = wall
            if src != self.partner:
                self._refuse("count", "busy", "MISSION_COUNT during another station's upload")
                self._ack(src, mavlink.MAV_MISSION_ERROR)
            elif self.transfer_seq == 0:  # our first request was lost: ask again
                self._request(0, wall)
            else:
                self.statustext(CRITICAL, "WPM: REJ. CMD: Busy")
                self._refuse("count", "busy", "MISSION_COUNT during an upload: Busy")
                self._ack(src, mavlink.MAV_MISSION_ERROR)
            return
        if self.state is State.SENDLIST:
            self.statustext(CRITICAL, "WPM: IGN MISSION_COUNT: Busy")
            self._refuse("count", "busy", "MISSION_COUNT during a download: Busy")
            self._ack(src, mavlink.MAV_MISSION_ERROR, msg.mission_type)
            return
        self._last_recv = wall
        owner = _uploading.get(self.store)
        if owner is not None and owner is not self:  # another link is uploading
            self._refuse("count", "busy", "MISSION_COUNT during another link's upload")
            self._ack(src, mavlink.MAV_MISSION_ERROR, msg.mission_type)
            return
        self.partner, self.mission_type = src, msg.mission_type
        if msg.mission_type not in MISSION_TYPES:
            self._refuse("count", "type", f"MISSION_COUNT of mission_type {msg.mission_type}")
            self._ack(src, mavlink.MAV_MISSION_INVALID)
        elif msg.count > MAX_COUNT[msg.mission_type]:
            self._refuse("count", "no_space", f"MISSION_COUNT {msg.count}: too many items")
            self._ack(src, mavlink.MAV_MISSION_NO_SPACE)
        elif msg.count == 0:
            self.store.replace(msg.mission_type, ())
            self.transfer_seq = 0
            self._ack(src, mavlink.MAV_MISSION_ACCEPTED)
        else:
            _uploading[self.store] = self
            self.state = State.GETLIST
            self.transfer_seq, self.transfer_count = 0, msg.count
            self._received, self._current_marked = [], -1
            self._request(0, wall)

    def _on_item(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        self.int_mode = msg.get_type() == "MISSION_ITEM_INT"
        if src != self.partner:
            self.statustext(CRITICAL, "REJ. MIS ITEM: partner id mismatch")
            self._refuse("item", "partner", "MISSION_ITEM from a station that is not uploading")
            return
        if msg.mission_type != self.mission_type:
            self._refuse(
                "item", "type", f"MISSION_ITEM of another mission_type ({msg.mission_type})"
            )
            self._ack(src, mavlink.MAV_MISSION_ERROR)
            return
        if self.state is State.IDLE:
            if self.transfer_seq == msg.seq + 1:  # the last item again: our final ACK was lost
                self._ack(src, mavlink.MAV_MISSION_ACCEPTED)
            else:
                self.statustext(CRITICAL, "IGN MISSION_ITEM: No transfer")
                self._refuse("item", "no_transfer", "MISSION_ITEM with no upload running")
                self._ack(src, mavlink.MAV_MISSION_ERROR)
            return
        if self.state is State.SENDLIST:
            self.statustext(CRITICAL, "IGN MISSION_ITEM: Busy")
            self._refuse("item", "busy", "MISSION_ITEM during a download: Busy")
            self._ack(src, mavlink.MAV_MISSION_ERROR)
            return
        self._last_recv = wall
        if msg.seq != self.transfer_seq:
            return  # out of sequence: ignored, the re-request asks for the right one
        item = item_from_message(msg)
        verdict = check_item(item, self.int_mode)
        if verdict != mavlink.MAV_MISSION_ACCEPTED:
            self.statustext(CRITICAL, "IGN MISSION_ITEM: Invalid item")
            what = (
                f"{enum_name('MAV_CMD', item.command)} in frame {enum_name('MAV_FRAME', item.frame)}: "
                f"{enum_name('MAV_MISSION_RESULT', verdict)}"
            )
            self._refuse("item", what, f"{msg.get_type()} {msg.seq}: {what}, upload ended")
            self._ack(src, verdict)
            self._idle()
            return
        self._received.append(item)
        if msg.current:
            self._current_marked = msg.seq
        self.transfer_seq = msg.seq + 1
        if self.transfer_seq < self.transfer_count:
            self._request(self.transfer_seq, wall)
            return
        items = tuple(self._received)
        if items != self.store.items(self.mission_type):  # PX4 keeps an unchanged list as it is
            self.store.replace(self.mission_type, items)
            if self.mission_type == MISSION and self._current_marked >= 0:
                self.store.set_current(self._current_marked)
        self._idle()
        self._ack(src, mavlink.MAV_MISSION_ACCEPTED)

    def _on_ack(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        if src != self.partner:
            return
        if self.state is State.SENDLIST and msg.mission_type == self.mission_type:
            self._last_recv = wall
            self._idle()
        elif self.state is State.GETLIST:
            if msg.type == mavlink.MAV_MISSION_UNSUPPORTED:  # the GCS wants the other kind
                self.int_mode = not self.int_mode
                self._request(self.transfer_seq, wall)
            elif msg.type == mavlink.MAV_MISSION_OPERATION_CANCELLED:
                self._idle()

    # ---------------------------------------------------------------------------- download
    def _on_request_list(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        same = (
            self.state is State.SENDLIST
            and msg.mission_type == self.mission_type
            and src == self.partner
        )
        if self.state is not State.IDLE and not same:
            self.statustext(
                mavlink.MAV_SEVERITY_INFO, "Mission download request ignored, already active"
            )
            self._refuse("request", "busy", "MISSION_REQUEST_LIST during a transfer: ignored")
            return
        self._last_recv = wall
        self.partner, self.mission_type = src, msg.mission_type
        self._sending = (
            self.store.items(msg.mission_type) if msg.mission_type in MISSION_TYPES else ()
        )
        self.transfer_seq, self.transfer_count = 0, len(self._sending)
        self.state = State.SENDLIST if self._sending else State.IDLE
        self.mav.mission_count_send(src[0], src[1], self.transfer_count, msg.mission_type)

    def _on_request(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        self.int_mode = msg.get_type() == "MISSION_REQUEST_INT"
        if src != self.partner:
            self.statustext(CRITICAL, "WPM: REJ. CMD: partner id mismatch")
            self._refuse(
                "request", "partner", "MISSION_REQUEST from a station that is not downloading"
            )
            return
        if self.state is State.GETLIST:
            self.statustext(CRITICAL, "WPM: REJ. CMD: Busy")
            self._refuse("request", "busy", "MISSION_REQUEST during an upload: Busy")
        if self.state is not State.SENDLIST or msg.mission_type != self.mission_type:
            return  # no download running: ignored silently, as PX4 (buggy OSDs send these)
        self._last_recv = wall
        if msg.seq == self.transfer_seq and self.transfer_seq < self.transfer_count:
            self.transfer_seq += 1
        elif msg.seq != self.transfer_seq - 1 or msg.seq >= self.transfer_count:
            self._idle()
            self._ack(src, mavlink.MAV_MISSION_ERROR)
            self.statustext(CRITICAL, "WPM: REJ. CMD: Req. WP was unexpected")
            self._refuse("request", "seq", f"MISSION_REQUEST {msg.seq}: unexpected, download ended")
            return
        item = self._sending[msg.seq]
        if item.frame in GLOBAL_FRAMES:  # PX4 sends global items in the frame kind asked for
            table = TO_INT_FRAME if self.int_mode else TO_FLOAT_FRAME
            item = replace(item, frame=table.get(item.frame, item.frame))
        current = self.mission_type == MISSION and msg.seq == self.store.current_seq
        send_item(self.mav, item, src[0], src[1], self.int_mode, current)

    # ---------------------------------------------------------------------- clear, current
    def _on_clear_all(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        if self.state is not State.IDLE:
            self.statustext(CRITICAL, "WPM: IGN CLEAR CMD: Busy")
            self._refuse("clear", "busy", "MISSION_CLEAR_ALL during a transfer: Busy")
            return
        self._last_recv = wall
        types = (
            MISSION_TYPES
            if msg.mission_type == mavlink.MAV_MISSION_TYPE_ALL
            else ((msg.mission_type,) if msg.mission_type in MISSION_TYPES else ())
        )
        for mission_type in types:
            self.store.replace(mission_type, ())
        if not types:
            self._refuse("clear", "type", f"MISSION_CLEAR_ALL of mission_type {msg.mission_type}")
        self._ack(
            src,
            mavlink.MAV_MISSION_ACCEPTED if types else mavlink.MAV_MISSION_ERROR,
            msg.mission_type,
        )

    def _on_set_current(self, msg: Any, src: tuple[int, int], wall: float) -> None:
        if self.state is not State.IDLE:
            self.statustext(CRITICAL, "WPM: IGN WP CURR CMD: Busy")
            self._refuse("current", "busy", "MISSION_SET_CURRENT during a transfer: Busy")
        elif self.store.set_current(msg.seq):
            self._last_recv = wall
            self.mav.mission_current_send(msg.seq, len(self.store.items(MISSION)))
        else:
            self.statustext(CRITICAL, "WPM: WP CURR CMD: Not in list")
            self._refuse("current", "seq", f"MISSION_SET_CURRENT {msg.seq}: not in the mission")

    # ----------------------------------------------------------------------------- helpers
    def _refuse(self, message: str, why: str, text: str) -> None:
        """Count a refused MISSION_* message as ``mission_<message>_refused``, logged once per ``why``."""
        self.reject(f"mission_{message}_refused", text, key=f"mission_{message}_{why}")

    def _request(self, seq: int, wall: float) -> None:
        self._last_sent = wall
        send = self.mav.mission_request_int_send if self.int_mode else self.mav.mission_request_send
        send(self.partner[0], self.partner[1], seq, self.mission_type)

    def _ack(self, to: tuple[int, int], result: int, mission_type: int | None = None) -> None:
        self.mav.mission_ack_send(
            to[0], to[1], result, self.mission_type if mission_type is None else mission_type
        )

    def _idle(self) -> None:
        self.state = State.IDLE
        if _uploading.get(self.store) is self:
            del _uploading[self.store]

    _HANDLERS: dict[str, Callable[..., None]] = {
        "MISSION_COUNT": _on_count,
        "MISSION_ITEM_INT": _on_item,
        "MISSION_ITEM": _on_item,
        "MISSION_ACK": _on_ack,
        "MISSION_REQUEST_LIST": _on_request_list,
        "MISSION_REQUEST_INT": _on_request,
        "MISSION_REQUEST": _on_request,
        "MISSION_CLEAR_ALL": _on_clear_all,
        "MISSION_SET_CURRENT": _on_set_current,
    }
