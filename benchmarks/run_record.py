"""What every benchmark's JSON says of its run: the machine it ran on and the command that made it,
so that a figure quoted in the docs can be made again and its conditions read beside it."""

from __future__ import annotations

import os
import platform
import sys


def machine() -> dict:
    """CPUs, the 1-minute load average when the run ended (timings beside other work are noisy) and
    the Python version."""
    return {
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2),
        "python": platform.python_version(),
    }


def command(script: str, argv: list[str] | None) -> str:
    """``python benchmarks/SCRIPT ARGS``, the arguments ``main`` was given (the command line's)."""
    return f"python benchmarks/{script} " + " ".join(sys.argv[1:] if argv is None else argv)
