"""``uavlink plot``: its options; the command is ``uavlink.plot.command.run_plot`` (imported when it runs)."""

from __future__ import annotations

import argparse
from pathlib import Path

from uavlink.cli.options import output_file
from uavlink.errors import EXTRA_OF_MODULE


def cmd_plot(args: argparse.Namespace) -> int:
    from uavlink.plot.command import run_plot

    if args.out is not None:  # what --gif or not writes, under a name that says so
        output_file(args.out, "--out", (".gif",) if args.gif else (".png",))
    return run_plot(args.tlog, args.out, args.gif, args.title, as_json=args.json)


def add_plot_parser(sub) -> None:
    p = sub.add_parser(
        "plot",
        help="draw a flight from its telemetry log (.tlog): PNG, or --gif",
        description="Draw the picture `uavlink fly` draws (flight.png) from any MAVLink "
        "telemetry log: one written by `uavlink fly`, or by MAVProxy or "
        "QGroundControl while a vehicle with the radio payload flew. The "
        "map shows the fence, every UAV's track, the UEs' tracks (the "
        "simulation's truth, ADSB_VEHICLE; a fleet's coloured by serving UAV) and "
        "the bearings sensed; below, the mean UE throughput and each UE's "
        "SINR per radio frame, decision frames marked. A log without radio "
        "messages gives the tracks. Needs matplotlib: "
        f"pip install 'uavlink[{EXTRA_OF_MODULE['matplotlib']}]'.",
    )
    p.add_argument("tlog", type=Path, metavar="FLIGHT.tlog", help="the telemetry log")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="file to write (default: the log's name with .png, or .gif with --gif)",
    )
    p.add_argument(
        "--gif",
        action="store_true",
        help="an animation instead: one GIF frame per decision frame (a few hundred KB)",
    )
    p.add_argument(
        "--title", default=None, help="title above the picture (default: the log's name)"
    )
    p.add_argument("--json", action="store_true", help="print what was drawn as JSON")
    p.set_defaults(func=cmd_plot)
