"""Run the SITL vehicle (``python -m sitl_stub``) as a child process: the one launcher behind
``uavlink fly``'s embedded vehicle and the tests that fly against a real vehicle process.

The child gets ``--connect CONNECT`` (once per URL when CONNECT is a sequence; none when it is
None: PX4 SITL's ports, see ``--instance``), ``--speed SPEED`` and then ``extra_args`` (any other sitl-stub
options: ``--scenario``, ``--seed``, ``--signing-key``, ``--param NAME=VALUE``, ...). Its
stdout/stderr go to ``log_path`` when given (kept), else to a temporary file removed afterwards;
read them with :meth:`VehicleProcess.output`; :meth:`VehicleProcess.wait_started` waits for its
ready line, or reports the error line of a vehicle that exited instead. It is always stopped
(SIGTERM, then SIGKILL) when the ``with`` block ends. The child imports ``sitl_stub`` from where this module was imported (that
folder goes first on its PYTHONPATH), so caller and vehicle run the same code from any directory.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

__all__ = ["VehicleExited", "VehicleProcess", "exit_stats", "lockstep_timeouts", "vehicle_process"]

PACKAGE_ROOT = Path(__file__).resolve().parent.parent
# The program's name, which begins every message the vehicle prints (its log lines too); once its
# links are open it prints the ready line, "sitl-stub: vehicle 1 on ..., 20x real time, ..." or
# "sitl-stub: fleet of 2 vehicles (...) on ..." (sitl_stub/__main__.py), matched by READY_LINE.
PROG = "sitl-stub"
READY_LINE = re.compile(
    re.escape(f"{PROG}: ") + r"(vehicle \d+|fleet of \d+ vehicles \([^)]*\)) on .*x real time"
)


STATS_PREFIX = f"{PROG}: stats "  # the line a vehicle prints on exit: its counters as JSON


def exit_stats(output: str) -> dict | None:
    """The counters a vehicle printed on exit (the last ``sitl-stub: stats {json}`` line of its
    output); None while it runs, or where it was killed before printing them."""
    for line in reversed(output.splitlines()):
        if line.startswith(STATS_PREFIX):
            return json.loads(line[len(STATS_PREFIX) :])
    return None


def lockstep_timeouts(stats: dict) -> int | None:
    """Frames a lockstep vehicle went on without the flight computer's decision (each held at most
    ``sitl_stub.sim.lockstep.LOCKSTEP_WAIT_WALL_S`` of wall time), from its exit stats: the largest
    count any payload reports, since a fleet's vehicles each report their shared world's one hold;
    None where no payload reports one (a vehicle not in lockstep)."""
    found: list[int] = []
    todo: list = [stats]
    while todo:
        tree = todo.pop()
        if isinstance(tree, dict):
            found += [v for k, v in tree.items() if k == "lockstep_timeouts"]
            todo += list(tree.values())
        elif isinstance(tree, list):
            todo += tree
    return max(found, default=None)


class VehicleExited(RuntimeError):
    """The vehicle process ended before it was ready; the message carries its last output line."""

    def __init__(self, status: int, last_line: str) -> None:
        super().__init__(f"exited with status {status}: {last_line or '(no output)'}")
        self.status, self.last_line = status, last_line


@dataclass
class VehicleProcess:
    """A running vehicle: the Popen handle and the file its output goes to."""

    proc: subprocess.Popen
    log_path: Path

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_started(self, timeout_s: float, poll_s: float = 0.05) -> bool:
        """Wait until the vehicle prints its ready line (True) or ``timeout_s`` pass (False: still
        starting, e.g. on a loaded machine); VehicleExited as soon as it has exited instead (a
        bad argument): a caller reports the vehicle's own error at once rather than waiting for a
        heartbeat that cannot come."""
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.proc.poll()
            lines = self.output().splitlines()
            if any(READY_LINE.match(line) for line in lines):
                return True
            if status is not None:
                raise VehicleExited(
                    status, next((ln.strip() for ln in reversed(lines) if ln.strip()), "")
                )
            if time.monotonic() > deadline:
                return False
            time.sleep(poll_s)

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


def vehicle_command(
    connect: str | Sequence[str] | None, speed: float, extra_args: Sequence[str] = ()
) -> list[str]:
    """The child's command line."""
    urls = [] if connect is None else [connect] if isinstance(connect, str) else list(connect)
    links = [arg for url in urls for arg in ("--connect", url)]
    return [sys.executable, "-m", "sitl_stub", *links, "--speed", repr(float(speed)), *extra_args]


@contextmanager
def vehicle_process(
    connect: str | Sequence[str] | None,
    speed: float = 5.0,
    extra_args: Sequence[str] = (),
    log_path: Path | None = None,
) -> Iterator[VehicleProcess]:
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
        proc = subprocess.Popen(
            vehicle_command(connect, speed, extra_args),
            stdout=log_file,
            stderr=subprocess.STDOUT,
            env=env,
        )
    vehicle = VehicleProcess(proc, path)
    try:
        yield vehicle
    finally:
        vehicle.stop()
        if log_path is None:
            path.unlink(missing_ok=True)
