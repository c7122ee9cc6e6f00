"""Helpers for tests that fly against the stub: run ``python -m sitl_stub`` as a child process.

The process's stdout/stderr go to a temporary file (read it with :meth:`VehicleProcess.output`),
and it is always terminated (SIGTERM, then SIGKILL) when the ``with`` block ends.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from uavlink.mavlink.connection import free_udp_port

__all__ = ["VehicleProcess", "free_udp_port", "vehicle_process"]

REPO_ROOT = Path(__file__).resolve().parent.parent


@dataclass
class VehicleProcess:
    """A running vehicle: the Popen handle and the file its output goes to."""

    proc: subprocess.Popen
    log_path: Path

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout_s: float = 5.0) -> int:
        """SIGTERM, wait, SIGKILL if needed; returns the exit status."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout_s)
        return int(self.proc.returncode)


@contextmanager
def vehicle_process(connect: str, speed: float = 5.0,
                    extra_args: Sequence[str] = ()) -> Iterator[VehicleProcess]:
    """Run the vehicle with ``--connect connect --speed speed extra_args`` for the block."""
    fd, name = tempfile.mkstemp(prefix="sitl_stub_", suffix=".log")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "sitl_stub", "--connect", connect, "--speed", str(speed),
           *extra_args]
    with os.fdopen(fd, "wb") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=REPO_ROOT, env=env)
    vehicle = VehicleProcess(proc, Path(name))
    try:
        yield vehicle
    finally:
        vehicle.stop()
        vehicle.log_path.unlink(missing_ok=True)
