"""A simulation loop run in the background, for code that runs the vehicle in its own process (tests,
scripts; ``python -m sitl_stub`` calls ``run`` in the foreground): :meth:`BackgroundLoop.start`
opens and runs ``run`` in a daemon thread, :meth:`BackgroundLoop.stop` ends it and closes, and an
exception that ends the thread is kept in ``error`` rather than lost with it. One vehicle
(``SitlServer``) and a fleet (``FleetServer``) run this way."""

from __future__ import annotations

import logging
import threading
from typing import Self

log = logging.getLogger("sitl_stub")


class BackgroundLoop:
    """``open``, ``close`` and ``run(stop)`` (which returns once ``stop`` or ``self._stop`` is set)
    are the subclass's."""

    thread_name = "sitl_stub"

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    def open(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def run(self, stop: threading.Event | None = None) -> None:
        raise NotImplementedError

    def start(self) -> Self:
        """Open and run in a daemon thread; returns self."""
        self.open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run_thread, name=self.thread_name, daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop the loop (thread or ``run``) and close."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
            self._thread = None
        self.close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _run_thread(self) -> None:
        try:
            self.run()
        except BaseException as exc:  # reported to the embedding code via .error
            self.error = exc
            log.exception("%s loop failed", self.thread_name)
