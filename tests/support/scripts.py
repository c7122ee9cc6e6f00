"""Run a repository script (``benchmarks/X.py``, ``tools/X.py``) as its command line would, but in
this process: its ``main`` run whole, without a child's torch and SB3 import (~8 s each on a loaded
2-core machine)."""

from __future__ import annotations

import contextlib
import io
import json
import runpy
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]


def load_script(folder: str, script: str) -> dict[str, Any]:
    """The globals of ``FOLDER/SCRIPT`` run as a module named after it, with ``FOLDER`` on the path
    while it loads, as for a script (its siblings are importable)."""
    path = str(ROOT / folder)
    sys.path.insert(0, path)
    try:
        return runpy.run_path(str(ROOT / folder / script), run_name=Path(script).stem)
    finally:
        sys.path.remove(path)


def run_json(folder: str, script: str, *args: str) -> Any:
    """``python FOLDER/SCRIPT ARGS --json``: its ``main`` run in this process, its JSON output."""
    path = str(ROOT / folder)
    sys.path.insert(0, path)  # siblings imported when main runs, too
    try:
        main = load_script(folder, script)["main"]
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main([*args, "--json"]) == 0
    finally:
        sys.path.remove(path)
    return json.loads(out.getvalue())
