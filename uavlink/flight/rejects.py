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

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def as_dict(self) -> dict[str, int]:
        return dict(sorted(self.counts.items()))
