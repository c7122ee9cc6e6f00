"""Counting and logging rejected input: every rejection is counted, each kind is logged once; and
two repairs of pymavlink's parser after garbage (``rescan_bad_frame``, ``drop_unfinished_frame``)."""

from __future__ import annotations

import logging
from collections import Counter

# The MAVLink wire format (mavlink.io, "Packet Serialization"): start markers, the header after the
# marker, the v2 "signed" flag and its 13-byte signature; here, not from pymavlink, so this module
# stays light (tests/test_mavlink_package.py).
PROTOCOL_MARKER_V1, PROTOCOL_MARKER_V2 = 0xFE, 0xFD
HEADER_LEN_V1, HEADER_LEN_V2 = 6, 10
MAVLINK_IFLAG_SIGNED = 0x01
MAVLINK_SIGNATURE_BLOCK_LEN = 13


class RejectLog:
    """``reject(kind, text)`` counts one rejected input of ``kind`` and logs ``text`` the first time
    that ``key`` (default: the kind) is seen. At most ``max_logged`` distinct keys are logged, so a
    flood of distinct garbage cannot flood the log; the counts stay exact."""

    def __init__(self, logger: logging.Logger, max_logged: int = 64) -> None:
        self.logger = logger
        self.max_logged = max_logged
        self.counts: Counter[str] = Counter()
        self._logged: set[str] = set()

    def reject(self, kind: str, text: str, key: str | None = None) -> bool:
        """Count it; returns True when this call logged (the first of its key)."""
        self.counts[kind] += 1
        key = kind if key is None else key
        if key in self._logged or len(self._logged) >= self.max_logged:
            return False
        self._logged.add(key)
        self.logger.warning("rejected input: %s (counted as %r; logged once)", text, kind)
        return True

    def screen(self, msg) -> bool:
        """True for a usable pymavlink message. BAD_DATA and unknown message ids are counted and
        logged once and give False; a bad signature is left to the signing check's own counters."""
        kind = msg.get_type()
        if kind == "BAD_DATA":
            if "signature" not in str(getattr(msg, "reason", "")):
                self.reject("bad_data", f"bad MAVLink data ({msg.reason})")
            return False
        if kind.startswith("UNKNOWN"):
            self.reject(
                "unknown_message",
                f"unknown message id {msg.get_msgId()}",
                key=f"unknown_message_{msg.get_msgId()}",
            )
            return False
        return True

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def as_dict(self) -> dict[str, int]:
        return dict(sorted(self.counts.items()))


def rescan_bad_frame(mav, msg) -> None:
    """After pymavlink's robust parser (``mav``) returns a frame it could not trust (bad CRC, length
    or flags, or an unknown message id, whose CRC it cannot check), make it read that frame's bytes
    again from the one after its start marker.

    pymavlink drops the whole length a start marker claims. When the marker was a stray byte of
    garbage, the genuine packets inside that span are lost with it, and if the packets that follow
    all have one length (a ground station repeating a command) they can stay out of frame: measured,
    a vehicle that ignored every intact command after one fuzzed datagram
    (tests/test_reliability_inputs.py). A byte-wise rescan finds the next real marker; a genuine
    frame of an unknown message costs only a few extra rejects. A bad signature belongs to a whole,
    well-framed packet and a bad prefix was already skipped byte by byte: both are left alone."""
    kind = msg.get_type()
    if kind == "BAD_DATA":
        reason = str(msg.reason)
        if "signature" in reason or reason == "Bad prefix":
            return
    elif not kind.startswith("UNKNOWN"):
        return
    data = bytes(msg.data)
    if len(data) < 2:
        return
    mav.buf = bytearray(data[1:]) + mav.buf[mav.buf_index :]
    mav.buf_index = 0


def drop_unfinished_frame(mav) -> int:
    """Before pymavlink's parser ``mav`` reads a new UDP datagram: drop the frame the bytes it holds
    leave unfinished, and return how many bytes that was. A datagram carries whole MAVLink packets,
    so the next one can never finish that frame; read as its rest, a stray start marker in garbage
    that claims 255 bytes swallowed the genuine commands of the datagrams after it (measured: five
    commands over 2.5 s after one datagram of 300 x 0xFE). Whole frames still waiting (the parser
    takes one a datagram) and garbage before them (it skips that byte by byte) are kept."""
    buf, i = mav.buf, mav.buf_index
    while i < len(buf):
        if buf[i] not in (PROTOCOL_MARKER_V1, PROTOCOL_MARKER_V2):
            i += 1
            continue
        need = None  # the frame's length, once its header's first 3 bytes are there
        if len(buf) - i >= 3:
            v2 = buf[i] == PROTOCOL_MARKER_V2
            need = buf[i + 1] + (HEADER_LEN_V2 if v2 else HEADER_LEN_V1) + 2
            if v2 and buf[i + 2] & MAVLINK_IFLAG_SIGNED:
                need += MAVLINK_SIGNATURE_BLOCK_LEN
        if need is None or len(buf) - i < need:
            dropped = len(buf) - i
            if i == mav.buf_index:  # the parser was waiting for this frame's length
                mav.expected_length = HEADER_LEN_V1 + 2
            del buf[i:]
            return dropped
        i += need
    return 0
