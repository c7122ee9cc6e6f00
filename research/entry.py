"""How every research script runs: ``run_script(main)`` calls it and exits with its status, and bad input
the product refuses (a ``UserError``: an unknown scenario, a missing sweep or policy file, a bad
``--set``) is one line on stderr and exit 2, as ``uavlink``'s commands do, not a traceback."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn


def run_script(main: Callable[[], int | None]) -> NoReturn:
    """``sys.exit(main())``, a ``UserError`` said in one line (exit 2)."""
    from uavlink.errors import UserError

    try:
        status = main()
    except UserError as exc:
        print(f"{Path(sys.argv[0]).name}: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    raise SystemExit(status)
