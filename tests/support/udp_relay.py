"""A test-only UDP relay on loopback that drops, delays, duplicates and reorders datagrams.

Topology: one endpoint sends to the relay's ``port`` (e.g. the vehicle with
``--connect udpout:127.0.0.1:PORT``); the relay forwards its datagrams to ``dest`` (e.g.
``uavlink fly --connect udpin:127.0.0.1:DEST``) from a second socket, and forwards what comes back
to that socket to the first endpoint's address. Each datagram (one MAVLink packet) meets the
current :class:`Faults` independently, in each direction, drawn from a seeded ``random.Random``:

- ``loss``: dropped with this probability;
- ``delay_s`` + uniform(0, ``jitter_s``): held this long before it is sent;
- ``duplicate``: sent twice (the copy ``dup_gap_s`` later);
- ``reorder``: held ``reorder_s`` longer than the datagrams around it, so it arrives after them.

The relay runs in a daemon thread, stops by itself after ``max_duration_s`` (wall), and always on
:meth:`UdpRelay.stop` / leaving its ``with`` block. :meth:`UdpRelay.set_faults` changes the faults
while it runs (e.g. a blackout, then a clear link). ``stats`` counts what it did per direction.
``tap(direction, datagram)``, when given, sees every datagram as it arrives (before any fault).

Flights through it: ``tests/support/relay_flight.py``; a ground station for tests: ``tests/support/mavlink_gcs.py``.
``python research/link_faults.py`` flies through it (the throughput table).
"""

from __future__ import annotations

import heapq
import random
import select
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

MAX_DATAGRAM = 65535


@dataclass(frozen=True)
class Faults:
    loss: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    duplicate: float = 0.0
    dup_gap_s: float = 0.002
    reorder: float = 0.0
    reorder_s: float = 0.03

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a probability, got {getattr(self, name)}")
        for name in ("delay_s", "jitter_s", "dup_gap_s", "reorder_s"):
            if not 0.0 <= getattr(self, name) <= 10.0:
                raise ValueError(f"{name} must be in [0, 10] s, got {getattr(self, name)}")

    def describe(self) -> str:
        parts = [
            f"{self.loss:.0%} loss" if self.loss else "",
            f"{self.delay_s * 1e3:.0f} ms delay" if self.delay_s else "",
            f"{self.jitter_s * 1e3:.0f} ms jitter" if self.jitter_s else "",
            f"{self.duplicate:.0%} duplicated" if self.duplicate else "",
            f"{self.reorder:.0%} reordered" if self.reorder else "",
        ]
        return ", ".join(p for p in parts if p) or "clean"


CLEAN = Faults()
BLACKOUT = Faults(loss=1.0)


class UdpRelay:
    """Relay between whoever sends to ``port`` and ``dest``; see the module docstring."""

    def __init__(
        self,
        dest: tuple[str, int],
        faults: Faults = CLEAN,
        seed: int = 0,
        max_duration_s: float = 120.0,
        host: str = "127.0.0.1",
        tap: Callable[[str, bytes], None] | None = None,
    ) -> None:
        if host not in ("127.0.0.1", "localhost"):
            raise ValueError("the test relay stays on loopback")
        self.dest = dest
        self.faults = faults
        self.max_duration_s = max_duration_s
        self.tap = tap
        self.stats: Counter[str] = Counter()
        self._rng = {"up": random.Random(f"{seed}-up"), "down": random.Random(f"{seed}-down")}
        self._front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for sock in (self._front, self._back):
            # Room for a burst while a loaded machine keeps the relay's thread waiting: the
            # kernel must not add losses of its own to the ones the relay is asked for.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
            sock.bind((host, 0))
        self._client: tuple[str, int] | None = None
        self._queue: list[tuple[float, int, str, bytes]] = []
        self._n = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    @property
    def port(self) -> int:
        """Where the first endpoint sends."""
        return int(self._front.getsockname()[1])

    def set_faults(self, faults: Faults) -> None:
        self.faults = faults

    # ---------------------------------------------------------------- lifecycle
    def start(self) -> UdpRelay:
        self._thread = threading.Thread(target=self._run, name="udp_relay", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
        self._front.close()
        self._back.close()

    def __enter__(self) -> UdpRelay:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # --------------------------------------------------------------------- loop
    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # reported to the test
            self.error = exc

    def _loop(self) -> None:
        ends = time.monotonic() + self.max_duration_s
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= ends:
                self.stats["expired"] += 1
                return
            self._release(now)
            wait = 0.05 if not self._queue else max(0.0, min(0.05, self._queue[0][0] - now))
            readable, _, _ = select.select([self._front, self._back], [], [], wait)
            for sock in readable:
                try:
                    data, addr = sock.recvfrom(MAX_DATAGRAM)
                except OSError:  # e.g. ICMP port unreachable from a peer that went away
                    continue
                if sock is self._front:
                    self._client = addr
                    self._admit("up", data)
                else:
                    self._admit("down", data)

    def _admit(self, direction: str, data: bytes) -> None:
        f, rng = self.faults, self._rng[direction]
        self.stats[f"{direction}_in"] += 1
        if self.tap is not None:
            self.tap(direction, data)
        if f.loss and rng.random() < f.loss:
            self.stats[f"{direction}_dropped"] += 1
            return
        at = time.monotonic() + f.delay_s + (rng.uniform(0.0, f.jitter_s) if f.jitter_s else 0.0)
        if f.reorder and rng.random() < f.reorder:
            at += f.reorder_s
            self.stats[f"{direction}_reordered"] += 1
        self._schedule(at, direction, data)
        if f.duplicate and rng.random() < f.duplicate:
            self.stats[f"{direction}_duplicated"] += 1
            self._schedule(at + f.dup_gap_s, direction, data)

    def _schedule(self, at: float, direction: str, data: bytes) -> None:
        self._n += 1
        heapq.heappush(self._queue, (at, self._n, direction, data))

    def _release(self, now: float) -> None:
        while self._queue and self._queue[0][0] <= now:
            _, _, direction, data = heapq.heappop(self._queue)
            try:
                if direction == "up":
                    self._back.sendto(data, self.dest)
                elif self._client is not None:
                    self._front.sendto(data, self._client)
                self.stats[f"{direction}_out"] += 1
            except OSError:
                self.stats[f"{direction}_send_errors"] += 1
