"""The results report's memory-of-place table alone (``uavlink evaluate --out ... --spatial ...
--map ...``'s part, uavlink/evaluation/report_map.py), for checks the whole report would make too
costly: more or other episodes, and without the genie's columns (about a CPU-second per episode).

Per scenario with a map policy, and mixed: the map policy, the spatial policy, explore, aoa, static (and the
genie) on the spatial channel on the same seeded episodes, with paired ratios.

    python research/map_table.py                                  # results.md's 100 episodes, seed 0
    python research/map_table.py --episodes 1000 --seed 7 --no-genie   # fresh episodes
    python research/map_table.py --set uav_motion=px4                 # every UAV flown as PX4 flies
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
    parser.add_argument(
        "--map", type=Path, default=ROOT / "policies" / "map", help="the map policies' folder"
    )
    parser.add_argument(
        "--spatial",
        type=Path,
        default=ROOT / "policies" / "spatial",
        help="the spatial policies' folder",
    )
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-genie", action="store_true", help="leave out the genie's columns")
    parser.add_argument("--csv", type=Path, default=None, help="also write the table here")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object (the table's rows by column, as the report writes the cells)",
    )
    parser.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an env override for every column, e.g. uav_motion=px4 (the genie keeps "
        "instant moves: its plan bounds a PX4-flown UAV); repeatable",
    )
    args = parser.parse_args(argv)
    if args.episodes < 2:
        parser.error("--episodes must be >= 2 (a paired interval)")
    for option, folder in (("--map", args.map), ("--spatial", args.spatial)):
        if not folder.is_dir() or not any(folder.glob("*.zip")):
            parser.error(f"{option} {folder}: not a folder of policy zips")
    from uavlink.errors import UserError
    from uavlink.evaluation.report_map import map_table
    from uavlink.evaluation.tables import markdown_table, write_csv
    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides

    def progress(line: str) -> None:
        if sys.stderr.isatty():
            print(line, file=sys.stderr, flush=True)

    try:
        overrides = EnvOverrides.from_command_line(None, None, args.settings)
        header, body = map_table(
            args.map,
            args.spatial,
            args.episodes,
            args.seed,
            overrides,
            policy_teacher,
            progress,
            with_genie=not args.no_genie,
        )
    except UserError as exc:
        parser.error(str(exc))
    if args.csv is not None:
        write_csv(args.csv, header, body)
    if args.json:
        print(
            json.dumps(
                {
                    "benchmark": "map_table",
                    "episodes": args.episodes,
                    "seed": args.seed,
                    "settings": args.settings,
                    "rows": [dict(zip(header, row, strict=True)) for row in body],
                },
                indent=2,
            )
        )
        return 0
    print(
        f"{args.episodes} episodes, seed {args.seed}, spatial channel"
        + "".join(f", {pair}" for pair in args.settings)
        + "\n"
    )
    print(markdown_table(header, body))
    return 0


if __name__ == "__main__":
    run_script(main)
