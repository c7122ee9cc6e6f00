"""How much a memory of place is worth on which channel (the sensitivity table).

Each of ``genie``, ``explore``, the scenario's map policy and its spatial policy over ``static`` on
the spatial channel with its shadowing sigma (4, 8 dB) and UAV-end decorrelation (25, 50, 100 m) set
by radio overrides (``uavlink.evaluation.map_sensitivity``; docs/results.md carries the same table).

    python research/map_sensitivity.py                      # Markdown table (about 15 CPU-min)
    python research/map_sensitivity.py --episodes 10 --json # one JSON object
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from entry import run_script

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", help="default: no_move circular")
    parser.add_argument(
        "--map", type=Path, default=ROOT / "policies" / "map", help="the map policies' folder"
    )
    parser.add_argument(
        "--spatial",
        type=Path,
        default=ROOT / "policies" / "spatial",
        help="the spatial policies' folder",
    )
    parser.add_argument("--episodes", type=int, default=50, help="episodes per cell (default 50)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    args = parser.parse_args(argv)
    if args.episodes < 2:
        parser.error("--episodes must be >= 2 (a paired interval)")
    from uavlink.errors import UserError
    from uavlink.evaluation.map_sensitivity import (
        SENSITIVITY_SCENARIOS,
        sensitivity,
        sensitivity_table,
    )

    def progress(line: str) -> None:
        if sys.stderr.isatty():
            print(line, file=sys.stderr, flush=True)

    try:
        report = sensitivity(
            args.map,
            args.spatial,
            args.episodes,
            args.seed,
            args.scenarios or SENSITIVITY_SCENARIOS,
            progress,
        )
    except UserError as exc:  # a scenario without a map or spatial policy, a bad override
        parser.error(str(exc))
    report = {"benchmark": "map_sensitivity", **report}
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(
            f"memory of place by channel ({report['episodes']} episodes, seed {report['seed']}; "
            f"throughput over static's, 95 % paired interval)\n\n{sensitivity_table(report)}"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
