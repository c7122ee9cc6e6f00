"""Run the SITL vehicle (``python -m sitl_stub``) as a child process: the one launcher behind
``uavlink fly``'s embedded vehicle and the tests that fly against a real vehicle process.

The child gets ``--connect CONNECT`` (once per URL when CONNECT is a sequence; none when it is
None: PX4 SITL's ports, see ``--instance``), ``--speed SPEED`` and then ``extra_args`` (any other sitl-stub
options: ``--scenario``, ``--seed``, ``--signing-key``, ``--param NAME=VALUE``, ...). Its
stdout/stderr go to ``log_path`` when given (kept), else to a temporary file removed afterwards;
read them with :meth:`VehicleProcess.output`. It is always stopped (SIGTERM, then SIGKILL) when the
``with`` block ends. The child imports ``sitl_stub`` from where this module was imported (that
folder goes first on its PYTHONPATH), so caller and vehicle run the same code from any directory.
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

__all__ = ["VehicleProcess", "vehicle_process"]

PACKAGE_ROOT = Path(__file__).resolve().parent.parent


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


def vehicle_command(connect: str | Sequence[str] | None, speed: float,
                    extra_args: Sequence[str] = ()) -> list[str]:
    """The child's command line."""
    urls = [] if connect is None else [connect] if isinstance(connect, str) else list(connect)
    links = [arg for url in urls for arg in ("--connect", url)]
    return [sys.executable, "-m", "sitl_stub", *links, "--speed", repr(float(speed)), *extra_args]


@contextmanager
def vehicle_process(connect: str | Sequence[str] | None, speed: float = 5.0, extra_args: Sequence[str] = (),
                    log_path: Path | None = None) -> Iterator[VehicleProcess]:
    """Run the vehicle with ``--connect connect --speed speed extra_args`` for the block (no
    ``--connect`` when ``connect`` is None)."""
    if log_path is None:
        fd, name = tempfile.mkstemp(prefix="sitl_stub_", suffix=".log")
        log_file, path = os.fdopen(fd, "wb"), Path(name)
    else:
        path = Path(log_path)
        log_file = open(path, "wb")  # noqa: SIM115 - closed once the child has it
    python_path = os.pathsep.join(p for p in (str(PACKAGE_ROOT), os.environ.get("PYTHONPATH")) if p)
    env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=python_path)
    with log_file:
        proc = subprocess.Popen(vehicle_command(connect, speed, extra_args), stdout=log_file,
                                stderr=subprocess.STDOUT, env=env)
    vehicle = VehicleProcess(proc, path)
    try:
        yield vehicle
    finally:
        vehicle.stop()
        if log_path is None:
            path.unlink(missing_ok=True)
