"""MAVLink parameter protocol (v1) over a :class:`~sitl_stub.core.params.ParamStore`, as PX4 answers it.

PARAM_REQUEST_LIST sends every PARAM_VALUE; PARAM_REQUEST_READ answers by index (>= 0) or by name;
PARAM_SET answers with the PARAM_VALUE now in force (the old value when the new one is refused:
out of range, not finite, or not whole for an INT32, said in a STATUSTEXT, where PX4 would store it).
An unknown name gets no PARAM_VALUE but PX4's STATUSTEXT, "[pm] unknown param: NAME"
(``mavlink_parameters.cpp``), so a ground station that waits for an echo can say why.
INT32 values travel bytewise-encoded in the float field (PX4, MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE).
"""

from __future__ import annotations

from typing import Any

from sitl_stub.core.params import ParamStore, ParamType, param_float_to_int
from uavlink.mavlink.dialect import mavlink


class ParamProtocol:
    """Answers parameter messages with ``mav`` (the autopilot component's MAVLink object)."""

    def __init__(self, store: ParamStore, mav: Any) -> None:
        self.store = store
        self.mav = mav
        self.rejected_sets = 0

    def handle(self, msg: Any) -> bool:
        """Handle a PARAM_* message; False when it is not one (or not a v1 parameter message)."""
        kind = msg.get_type()
        if kind == "PARAM_REQUEST_LIST":
            for name in self.store:
                self.send_value(name)
        elif kind == "PARAM_REQUEST_READ":
            wanted = self.store.name_at(msg.param_index) if msg.param_index >= 0 else _name(msg)
            if wanted is not None and wanted in self.store:  # None: no parameter at that index
                self.send_value(wanted)
        elif kind == "PARAM_SET":
            name = _name(msg)
            if name not in self.store:
                self._say(f"[pm] unknown param: {name}")
                return True
            accepted = self.store.set_from_wire(name, msg.param_value)
            self.send_value(name)
            if not accepted:
                self.rejected_sets += 1
                d = self.store.definition(name)
                sent = msg.param_value
                if d.type is ParamType.INT32:
                    sent = param_float_to_int(sent)
                self._say(f"[pm] {name} {sent:g} refused: {d.min:g}..{d.max:g}")
        else:
            return False
        return True

    def _say(self, text: str) -> None:
        self.mav.statustext_send(mavlink.MAV_SEVERITY_INFO, text[:50].encode("ascii", "replace"))

    def send_value(self, name: str) -> None:
        value, ptype = self.store.encode(name)
        self.mav.param_value_send(
            name.encode("ascii"), value, int(ptype), len(self.store), self.store.index_of(name)
        )


def _name(msg: Any) -> str:
    raw = msg.param_id
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return raw.split("\x00", 1)[0]
