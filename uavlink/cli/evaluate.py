"""``uavlink evaluate``: a policy, a folder or a baseline on seeded episodes, a paired comparison
(``--against``), or the results folder (``--out``: the report, with finished sweeps' tables)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from uavlink.cli.options import (
    add_env_options,
    command_line,
    output_file,
    output_folder,
    scenario_list,
    seed,
)
from uavlink.config import EnvConfig
from uavlink.errors import UserError, require
from uavlink.policies.contract import OVERRIDES_HELP, EnvOverrides, apply_overrides, load_with_env
from uavlink.policies.loader import locate, shipped_note
from uavlink.policies.registry import BASELINES


def cmd_evaluate(args: argparse.Namespace) -> int:
    from uavlink.evaluation import compare, evaluate_policy

    # a shipped policy by name: its file from here on, said once the other checks have passed
    given = [args.policy, *(args.against or [])]
    args.policy = str(locate(args.policy))
    args.against = [str(locate(spec)) for spec in args.against or []]
    note = shipped_note(given, [args.policy, *args.against])
    if args.episodes < 1:
        raise UserError(f"--episodes must be a positive integer, got {args.episodes}")
    if args.out is not None:
        if args.against:
            raise UserError("--against compares policies in a table; it does not go with --out")
        return _write_results_folder(args, note)
    report_only = [
        flag
        for flag, value in (
            ("--markdown", args.markdown),
            ("--spatial", args.spatial),
            ("--map", args.map),
            ("--fleet", args.fleet),
            ("--fleet-per-size", args.fleet_per_size),
            ("--sweep", args.sweep),
            ("--workers", args.workers is not None),
        )
        if value
    ]
    if report_only:
        raise UserError(
            f"{', '.join(report_only)} {'go' if len(report_only) > 1 else 'goes'} with --out FOLDER "
            "(the results folder, with --scenario all)"
        )
    results, comparisons = [], []
    overrides = EnvOverrides.from_command_line(None, args.aoa_noise_deg, args.overrides)
    specs = [args.policy, *(args.against or [])]
    scenarios: Sequence[str | None]
    if args.scenario is None and Path(args.policy).is_file():
        # the file's manifest names it; a baseline beside it flies the file's world
        scenarios = [None]
    else:
        scenarios = scenario_list(args.scenario or "circular")
    status = StatusLine()
    try:
        for scenario in scenarios:
            flown = []
            loaded = load_with_env(specs, overrides.on(scenario))
            if note:  # every input checked: say which files the names became
                print(note, file=sys.stderr)
                note = ""
            for spec, (policy, cfg) in zip(specs, loaded, strict=True):
                status.show(f"evaluating {cfg.scenario}: {spec} ({args.episodes} episodes)")
                flown.append(evaluate_policy(policy, cfg, args.episodes, args.seed))
            if len({r.policy for r in flown}) < len(flown):  # map/x.zip vs spatial/x.zip
                flown = [
                    dataclasses.replace(r, policy=str(spec))
                    for r, spec in zip(flown, specs, strict=True)
                ]
            results += flown
            comparisons += [compare(flown[0], other) for other in flown[1:]]
    finally:
        status.close()
    if args.json:
        payload = [r.to_dict() for r in results]
        if comparisons:
            print(
                json.dumps(
                    {"results": payload, "comparisons": [c.to_dict() for c in comparisons]},
                    indent=2,
                )
            )
        else:
            print(json.dumps(payload[0] if len(payload) == 1 else payload, indent=2))
    else:
        print(format_table(results))
        for comparison in comparisons:
            print(comparison.describe())
    return 0


def _write_results_folder(args: argparse.Namespace, note: str) -> int:
    from uavlink.evaluation.report import write_results
    from uavlink.evaluation.tables import ReportRun
    from uavlink.learn.teachers import policy_teacher

    folder = Path(args.policy)
    if args.scenario != "all" or not folder.is_dir():
        raise UserError(
            "--out needs --scenario all and --policy FOLDER (one policy file per scenario)"
        )
    require("matplotlib")  # the report's figures come last: without it the tables would stand alone
    overrides = EnvOverrides.from_command_line(None, args.aoa_noise_deg, args.overrides)
    apply_overrides(EnvConfig(), overrides.on("no_move"))  # a bad --set fails before the long run
    command = command_line("evaluate", "uavlink evaluate ...")
    output_folder(args.out, "--out")  # both checked before the long run, which writes them last
    markdown = output_file(args.markdown or args.out / "results.md", "--markdown")

    if args.spatial is not None and not args.spatial.is_dir():
        raise UserError(f"--spatial {args.spatial}: not a folder of policies")
    if args.fleet is not None and (args.spatial is None or not args.fleet.is_dir()):
        raise UserError(
            f"--fleet {args.fleet}: needs a folder of fleet policies and --spatial (one UAV's, to compare)"
        )
    if args.fleet_per_size is not None and (args.fleet is None or not args.fleet_per_size.is_dir()):
        raise UserError(
            f"--fleet-per-size {args.fleet_per_size}: needs a folder of per-size fleet policies and "
            "--fleet (the fleet policies to pair them with)"
        )
    workers = 1 if args.workers is None else args.workers
    if workers < 1:
        raise UserError(f"--workers must be at least 1, got {workers}")
    if args.map is not None and (args.spatial is None or not args.map.is_dir()):
        raise UserError(
            f"--map {args.map}: needs a folder of map policies and --spatial (today's, to compare)"
        )

    from uavlink.sweep.report_sections import ReportSweeps
    from uavlink.sweep.sweep_file import load_spec

    sweeps = ReportSweeps(
        [load_spec(path) for path in args.sweep or []],
        args.sweep_root,
        args.out,
        folder,
        spatial=args.spatial,
        fleet=args.fleet,
        fleet_per_size=args.fleet_per_size,
        map=args.map,
    )
    sweeps.check_finished()  # before the long evaluation, which would write the folder
    if note:
        print(note, file=sys.stderr)

    status = StatusLine(log_lines=True)  # the report runs for hours: a log says how far it got
    try:
        run = ReportRun(
            args.episodes,
            args.seed,
            overrides,
            args.out,
            markdown,
            progress=lambda msg: status.show(f"evaluating {msg}"),
            workers=workers,
        )
        path = write_results(
            run,
            folder,
            command,
            sweep_sections=sweeps.sections,
            spatial_folder=args.spatial,
            fleet_folder=args.fleet,
            map_folder=args.map,
            fleet_per_size_folder=args.fleet_per_size,
            teacher_of=policy_teacher,
        )
    finally:
        status.close()
    print(path.read_text())
    return 0


class StatusLine:
    """One line of progress on stderr, rewritten in place; where stderr is not a terminal (logs,
    pipes, CI) quiet, or with ``log_lines`` one line per message, as the training and sweep print
    where their bars do not show (for work that runs for hours, such as the results report)."""

    def __init__(self, log_lines: bool = False) -> None:
        self.live, self.shown, self.log_lines = sys.stderr.isatty(), False, log_lines

    def show(self, message: str) -> None:
        if self.live:
            print(f"\r\033[K{message}", end="", file=sys.stderr, flush=True)
            self.shown = True
        elif self.log_lines:
            print(message, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.shown:
            print("\r\033[K", end="", file=sys.stderr, flush=True)


def format_table(results) -> str:
    """One row per result; a fleet's (more than one UAV) adds Jain's index, the
    5th-percentile UE rate and the UEs per UAV, busiest first."""
    width = max([16, *(len(r.policy) for r in results)])

    def is_fleet(r) -> bool:
        return len(r.ues_per_uav) > 1

    fleet = any(is_fleet(r) for r in results)
    head = f"{'scenario':<13} {'policy':<{width}} {'episodes':>8} {'Mbps':>7} {'±95%':>6} {'R_fair':>7}"
    lines = [head + (f" {'Jain':>5} {'p5 Mbps':>7}  UEs per UAV, busiest first" if fleet else "")]
    for r in results:
        row = (
            f"{r.scenario:<13} {r.policy:<{width}} {r.episodes:>8} {r.mean_rate_mbps:>7.3f} "
            f"{r.ci95_mbps:>6.3f} {r.mean_fair_rate:>7.3f}"
        )
        if is_fleet(r):
            row += f" {r.jain_index:>5.3f} {r.p5_ue_rate_mbps:>7.3f}  {' '.join(f'{n:.1f}' for n in r.ues_per_uav)}"
        lines.append(row)
    return "\n".join(lines)


def add_evaluate_parser(sub) -> None:
    p = sub.add_parser(
        "evaluate",
        help="evaluate a policy or baseline, print a table",
        description=f"Evaluate a policy file, a folder of them, or a baseline "
        f"({', '.join(BASELINES)}). "
        + OVERRIDES_HELP
        + " Baselines get the env of the policy they are compared with.",
    )
    add_env_options(p, for_policy=True)
    p.add_argument(
        "--policy",
        default="static",
        help=f"{' | '.join(BASELINES)} (genie: evaluation only, it plans on the episode's "
        "future) | FILE.zip | FILE.onnx | FOLDER (default static)",
    )
    p.add_argument(
        "--against",
        action="append",
        default=None,
        metavar="POLICY",
        help="also fly this policy (same forms; repeatable) on the same episodes and print --policy's paired "
        "throughput gain (%%) with its 95 %% interval, the R_fair difference and the episodes won "
        "(a fleet policy may face a single-UAV one: the same UEs and channel)",
    )
    p.add_argument(
        "--episodes", type=int, default=100, help="episodes per policy and scenario (default 100)"
    )
    p.add_argument(
        "--seed", type=seed, default=0, help="seed of the episodes (default 0: docs/results.md's)"
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write a results folder (Table I/II as Markdown and CSV, figures); "
        "needs --scenario all and --policy FOLDER",
    )
    p.add_argument(
        "--markdown", type=Path, default=None, help="where the report goes (default OUT/results.md)"
    )
    p.add_argument(
        "--sweep",
        type=Path,
        action="append",
        default=[],
        help="with --out: add the across-seed table of this finished sweep file (e.g. "
        "sweeps/table1.toml; repeat for more; a spatial-channel sweep goes with --spatial)",
    )
    p.add_argument(
        "--spatial",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="with --out: add the spatial-channel tables (radio.shadowing_model=spatial): FOLDER's "
        "policies, trained on it, and --policy's flown on it (e.g. policies/spatial)",
    )
    p.add_argument(
        "--map",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="with --out and --spatial: add the memory-of-place table: FOLDER's map policies "
        "(e.g. policies/map) against --spatial's, explore, aoa and static on the spatial channel",
    )
    p.add_argument(
        "--fleet",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="with --out and --spatial: add the fleet tables (D = 1 to 4 UAVs on the spatial channel): "
        "FOLDER's fleet policies (an any-size one flown at every D its layout flies, a per-size one at "
        "its own) against the fleet baselines and --spatial's (e.g. policies/fleet)",
    )
    p.add_argument(
        "--fleet-per-size",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="with --out and --fleet: add FOLDER's per-size fleet policies, each flown at its own D "
        "and paired with --fleet's there (e.g. policies/fleet_d2)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="with --fleet: run the fleet part's evaluations in N processes (default 1; the figures "
        "do not depend on it)",
    )
    p.add_argument(
        "--sweep-root",
        type=Path,
        default=Path("runs"),
        help="where the sweep's results are (default runs)",
    )
    p.set_defaults(func=cmd_evaluate)
