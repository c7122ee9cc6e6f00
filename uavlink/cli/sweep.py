"""``uavlink sweep``: a sweep file's jobs on Dask (or in this process), its summary, and the median
seeds shipped with ``--policies-out``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from uavlink.cli.options import command_line, output_folder
from uavlink.errors import UserError


def cmd_sweep(args: argparse.Namespace) -> int:
    from uavlink.sweep.aggregate import (
        collect,
        export_median_policies,
        jobs_table,
        read_record,
        record_path,
        write_record,
        write_summary,
    )
    from uavlink.sweep.sweep_file import load_spec

    spec = load_spec(args.file)  # SweepSpecError (a UserError): one line, exit 2, before any job
    if args.workers is not None and args.workers < 0:
        raise UserError("--workers must be >= 0 (0: run in this process without Dask)")
    if args.retries < 0:
        raise UserError("--retries must be >= 0")
    output_folder(args.out_root, "--out-root")
    if args.record_out is not None:
        output_folder(args.record_out, "--record-out")
    if args.policies_out is not None:
        output_folder(args.policies_out, "--policies-out")
        if len(spec.points()) > 1:
            raise UserError(
                f"--policies-out needs one setting per scenario; {args.file} has a grid of "
                f"{len(spec.points())} points"
            )
    # Jobs in the record shipped with the policies are done: only a changed recipe's jobs run again.
    record = (
        read_record(record_path(args.policies_out, spec)) if args.policies_out is not None else {}
    )
    if args.dry_run:
        print(jobs_table(spec.jobs(), args.out_root / spec.name, record.keys()))
        return 0
    from uavlink.sweep.runner import EngineError, run_sweep

    try:
        outcome = run_sweep(
            spec,
            args.out_root,
            scheduler=args.scheduler,
            workers=args.workers,
            retries=args.retries,
            progress=not args.no_progress,
            done_keys=record.keys(),
        )
    except EngineError as exc:
        raise UserError(str(exc)) from None
    command = command_line("sweep", f"uavlink sweep {args.file}")
    markdown, table = write_summary(spec, outcome.sweep_dir, command, record)
    print(table)
    done = outcome.skipped + outcome.finished
    print(
        f"{done}/{outcome.jobs} jobs done ({outcome.finished} run now in {outcome.wall_s:.0f} s, "
        f"{outcome.skipped} skipped); summary in {markdown}",
        file=sys.stderr,
    )
    if outcome.interrupted:
        print(
            f"uavlink sweep: interrupted; {done} finished jobs are kept, rerun to do the other "
            f"{outcome.jobs - done}",
            file=sys.stderr,
        )
        return 130
    if outcome.failed:
        print(
            f"uavlink sweep: {len(outcome.failed)} jobs failed ({', '.join(sorted(outcome.failed))}); "
            f"see {outcome.sweep_dir}/<job>.error.txt, rerun to retry them",
            file=sys.stderr,
        )
        return 1
    if args.record_out is not None:
        path = record_path(args.record_out, spec)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_record(collect(spec, outcome.sweep_dir, record), spec, path)
        print(f"record of {done} jobs -> {path}", file=sys.stderr)
    if args.policies_out is not None:
        for scenario, path, seed in export_median_policies(
            spec, outcome.sweep_dir, args.policies_out
        ):
            print(f"{scenario}: median seed {seed} -> {path}", file=sys.stderr)
    return 0


def add_sweep_parser(sub) -> None:
    p = sub.add_parser(
        "sweep",
        help="train + evaluate a grid of scenarios x seeds x settings on Dask",
        description="Run a sweep file (TOML: scenarios, seeds, [train], [scenario_train.NAME], [env], [scenario_env.NAME], [eval], "
        "[grid]) on an embedded Dask cluster or --scheduler; writes "
        "OUT_ROOT/<name>/<job>/ and a per-setting summary. Finished jobs "
        "are skipped on a rerun. See sweeps/tiny.toml.",
    )
    p.add_argument("file", type=Path, help="sweep file, e.g. sweeps/table1.toml")
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="Dask scheduler, e.g. tcp://HOST:8786 (default: a local cluster, one worker per core)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes of the local cluster (default: one per core; 0: in this process, no Dask)",
    )
    p.add_argument(
        "--out-root",
        type=Path,
        default=Path("runs"),
        help="results go to OUT_ROOT/<sweep name>/ (default runs)",
    )
    p.add_argument(
        "--retries",
        type=int,
        default=2,
        help="retries of a job that raises (default 2; worker "
        "deaths are rescheduled by Dask anyway)",
    )
    p.add_argument(
        "--policies-out",
        type=Path,
        default=None,
        metavar="DIR",
        help="copy each scenario's median-seed policy to DIR/<scenario>.zip and the sweep's record "
        "to DIR/<name>.sweep.json; jobs in that record count as done",
    )
    p.add_argument(
        "--record-out",
        type=Path,
        default=None,
        metavar="DIR",
        help="write the sweep's record (every finished job's figures) to DIR/<name>.sweep.json "
        "without shipping policies: the results report rebuilds the sweep's table from it",
    )
    p.add_argument(
        "--dry-run", action="store_true", help="list the jobs and whether each is done, run nothing"
    )
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (on a terminal) nor a line per finished job (in a log or a pipe)",
    )
    p.set_defaults(func=cmd_sweep)
