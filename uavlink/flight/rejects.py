"""Counting and logging rejected input: every rejection is counted, each kind is logged once."""

from __future__ import annotations

import logging
from collections import Counter


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
            self.reject("unknown_message", f"unknown message id {msg.get_msgId()}",
                        key=f"unknown_message_{msg.get_msgId()}")
            return False
        return True

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def as_dict(self) -> dict[str, int]:
        return dict(sorted(self.counts.items()))
