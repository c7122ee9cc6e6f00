"""MAVProxy (the ``mavproxy`` package) run as a user runs it, for the tests: its console output in a
file, its commands typed on stdin, stopped at the end of the block."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

MAVPROXY = shutil.which("mavproxy.py", path=str(Path(sys.executable).parent)) or shutil.which(
    "mavproxy.py"
)


@contextlib.contextmanager
def mavproxy(
    args: Sequence[str],
    cwd: Path,
    out_path: Path,
    typed: bool = True,
) -> Iterator[Callable[[str], None]]:
    """``mavproxy.py ARGS`` in ``cwd`` (where it writes mav.tlog), its output in ``out_path``;
    yields ``type_in(command)`` (stdin closed when ``typed`` is False); terminated, then killed."""
    assert MAVPROXY is not None
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with out_path.open("wb") as out:
        mp = subprocess.Popen(
            [sys.executable, MAVPROXY, *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.PIPE if typed else subprocess.DEVNULL,
            cwd=cwd,
            env=env,
        )

    def type_in(command: str) -> None:
        assert mp.stdin is not None, "MAVProxy was started without stdin"
        mp.stdin.write(f"{command}\n".encode())
        mp.stdin.flush()

    try:
        yield type_in
    finally:
        if mp.stdin is not None:
            mp.stdin.close()
        mp.terminate()
        try:
            mp.wait(10)
        except subprocess.TimeoutExpired:
            mp.kill()
            mp.wait(10)
