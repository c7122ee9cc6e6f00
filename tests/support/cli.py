"""Helpers for tests that run the CLI: the installed ``uavlink`` command in a child process or its
``main`` in this process, its JSON output, and the check that a refusal is one line with exit 2."""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# The installed console script, as users run it; `python -m uavlink.cli` where none is installed.
_SCRIPT = Path(sys.executable).with_name("uavlink")
UAVLINK = (
    [str(_SCRIPT)]
    if _SCRIPT.exists()
    else (
        [shutil.which("uavlink")]
        if shutil.which("uavlink")
        else [sys.executable, "-m", "uavlink.cli"]
    )
)


def run_uavlink(
    *args: str, timeout: float = 120, cwd: Path | None = ROOT
) -> subprocess.CompletedProcess:
    """Run ``uavlink ARGS`` in a child process, capturing text output (stderr is a pipe, not a TTY)."""
    return subprocess.run(
        [*UAVLINK, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd
    )


def run_uavlink_in_process(*args: str) -> subprocess.CompletedProcess:
    """``uavlink ARGS`` through the CLI's main in this process, as a CompletedProcess: the CLI's own
    code path and output, without a child process's torch and SB3 import (7-8 s each on a loaded
    2-core machine)."""
    import contextlib
    import io

    from uavlink.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(list(args))
        except SystemExit as exc:  # argparse's own errors (and --help) exit this way
            rc = exc.code
    return subprocess.CompletedProcess(["uavlink", *args], rc, out.getvalue(), err.getvalue())


def cli_json(*args: str) -> dict:
    """``uavlink ARGS`` (a command with ``--json``) in this process, its JSON output."""
    import json

    proc = run_uavlink_in_process(*args)
    assert proc.returncode == 0, (
        f"uavlink {' '.join(args)} exited {proc.returncode}: {proc.stderr[-2000:]}"
    )
    return json.loads(proc.stdout)


def assert_user_error(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    """Exit status 2 and exactly one line on stderr, ``uavlink COMMAND: error: ...`` naming the
    problem (each of ``fragments``), no traceback: what the CLI does with a UserError."""
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("uavlink ") and ": error: " in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0]


# Tests whose vehicles use PX4's fixed ports (14540+, 14550, 14580+, 18570+): never two at once, so
# under pytest-xdist run them apart (`pytest -n auto -m "not px4_ports"`, then `pytest -m px4_ports`).
PX4_PORTS = pytest.mark.px4_ports


def require_free_ports(*ports: int) -> None:
    """Skip the test when a UDP port it needs on 127.0.0.1 is taken (a PX4 SITL, a ground station
    or another vehicle is running)."""
    taken = []
    for port in ports:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                taken.append(port)
    if taken:
        pytest.skip(
            f"PX4 SITL port(s) {taken} on 127.0.0.1 are in use (a PX4 SITL, ground "
            "station or another vehicle is running)"
        )


TINY_TRAINING = {
    "episodes": 96,
    "n_envs": 16,
    "n_steps": 128,
    "batch_size": 512,
    "n_epochs": 10,
}  # tiny_policy_zip's
