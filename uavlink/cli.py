"""The ``uavlink`` command line: train | evaluate | fly | plot | export | sweep | keygen.

User errors (bad arguments, unknown scenarios, unusable policy files) print one line on stderr and
exit with status 2, without a traceback. Heavy modules are imported only by the command that needs them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from uavlink.config import BASELINE_NAMES, MIXED, SCENARIOS, EnvConfig
from uavlink.errors import UserError
from uavlink.policies.contract import (
    BUILT_FOR,
    OVERRIDES_HELP,
    EnvOverrides,
    apply_overrides,
    load_with_env,
)


def scenario_list(name: str) -> list[str]:
    if name == "all":
        return list(SCENARIOS)
    if name not in (*SCENARIOS, MIXED):
        raise UserError(f"unknown scenario {name!r}; choose from {', '.join(SCENARIOS)}, {MIXED} or all")
    return [name]


def _add_env_options(p: argparse.ArgumentParser, for_policy: bool = False) -> None:
    names = f"{', '.join(SCENARIOS)}, {MIXED}"
    if for_policy:  # evaluate: a policy file flies its own scenario unless told otherwise
        p.add_argument("--scenario", default=None,
                       help=f"one of {names} or all (default: a policy file's own scenario, from its "
                            "manifest; circular for a baseline or a folder)")
    else:
        p.add_argument("--scenario", default="circular", help=f"one of {names} (default: circular)")
    p.add_argument("--aoa-noise-deg", type=float, default=None,
                   help="std of the AoA estimate noise (deg)" + (" (default: the policy's; 0 for a baseline alone)" if for_policy else ""))
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override an env config field, e.g. --set r_max_m=10 --set radio.shadowing=false"
                        + (f"; under a policy file radio fields may change, {', '.join(BUILT_FOR)} may not"
                           if for_policy else ""))


def cmd_evaluate(args: argparse.Namespace) -> int:
    from uavlink.evaluation import compare, evaluate_policy

    if args.episodes < 1:
        raise UserError(f"--episodes must be a positive integer, got {args.episodes}")
    if args.out is not None:
        if args.against:
            raise UserError("--against compares policies in a table; it does not go with --out")
        return _write_results_folder(args)
    results, comparisons = [], []
    overrides = EnvOverrides.from_command_line(None, args.aoa_noise_deg, args.overrides)
    specs = [args.policy, *(args.against or [])]
    if args.scenario is None and Path(args.policy).is_file():
        scenarios = [None]  # the file's manifest names it; a baseline beside it flies the file's world
    else:
        scenarios = scenario_list(args.scenario or "circular")
    for scenario in scenarios:
        flown = [evaluate_policy(policy, cfg, args.episodes, args.seed)
                 for policy, cfg in load_with_env(specs, overrides.on(scenario))]
        if len({r.policy for r in flown}) < len(flown):  # policies/map/x.zip vs policies/spatial/x.zip
            flown = [dataclasses.replace(r, policy=str(spec)) for r, spec in zip(flown, specs, strict=True)]
        results += flown
        comparisons += [compare(flown[0], other) for other in flown[1:]]
    if args.json:
        payload = [r.to_dict() for r in results]
        if comparisons:
            print(json.dumps({"results": payload, "comparisons": [c.to_dict() for c in comparisons]}, indent=2))
        else:
            print(json.dumps(payload[0] if len(payload) == 1 else payload, indent=2))
    else:
        print(format_table(results))
        for comparison in comparisons:
            print(comparison.describe())
    return 0


def _write_results_folder(args: argparse.Namespace) -> int:
    from uavlink.evaluation.report import write_results

    folder = Path(args.policy)
    if args.scenario != "all" or not folder.is_dir():
        raise UserError("--out needs --scenario all and --policy FOLDER (one policy file per scenario)")
    overrides = EnvOverrides.from_command_line(None, args.aoa_noise_deg, args.overrides)
    apply_overrides(EnvConfig(), overrides.on("no_move"))  # a bad --set fails before the long run
    command = "uavlink " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["evaluate"] else "uavlink evaluate ..."
    markdown = args.markdown or args.out / "results.md"

    if args.spatial is not None and not args.spatial.is_dir():
        raise UserError(f"--spatial {args.spatial}: not a folder of policies")
    if args.fleet is not None and (args.spatial is None or not args.fleet.is_dir()):
        raise UserError(f"--fleet {args.fleet}: needs a folder of fleet policies and --spatial (one UAV's, to compare)")
    if args.map is not None and (args.spatial is None or not args.map.is_dir()):
        raise UserError(f"--map {args.map}: needs a folder of map policies and --spatial (today's, to compare)")

    def kind(spec) -> str:
        env = spec.jobs()[0].env_config()
        return "fleet" if env.n_uavs > 1 else "map" if env.place_cell_m > 0 else env.radio.shadowing_model

    def shipped(spec) -> Path:
        """The folder a sweep's median seeds were shipped to: its record lies beside them."""
        return Path({"ar1": folder, "spatial": args.spatial, "fleet": args.fleet, "map": args.map}[kind(spec)]
                    or folder)

    specs = []
    if args.sweep:  # checked before the long evaluation, which would write the folder
        from uavlink.sweep.aggregate import finished_rows, read_record, record_path
        from uavlink.sweep.spec import load_spec

        specs = [load_spec(path) for path in args.sweep]
        for spec in specs:
            finished_rows(spec, args.sweep_root / spec.name, read_record(record_path(shipped(spec), spec)))

    def sweep_sections(link_prefix: Path, wanted: str) -> list[str]:
        from uavlink.sweep.aggregate import results_section

        return [section for spec in specs if kind(spec) == wanted
                for section in (results_section(spec, args.sweep_root / spec.name, args.out, link_prefix,
                                                shipped(spec), "##" if wanted == "ar1" else "###"), "")]

    status = _StatusLine()
    try:
        path = write_results(folder, args.out, markdown, args.episodes, args.seed, overrides, command,
                             progress=lambda msg: status.show(f"evaluating {msg}"),
                             sweep_sections=sweep_sections, spatial_folder=args.spatial, fleet_folder=args.fleet,
                             map_folder=args.map)
    finally:
        status.close()
    print(path.read_text())
    return 0


class _StatusLine:
    """One line of progress on stderr, rewritten in place; quiet when stderr is not a terminal
    (logs, pipes, CI), like the training and sweep bars (tqdm's ``disable=None``)."""

    def __init__(self) -> None:
        self.live, self.shown = sys.stderr.isatty(), False

    def show(self, message: str) -> None:
        if self.live:
            print(f"\r\033[K{message}", end="", file=sys.stderr, flush=True)
            self.shown = True

    def close(self) -> None:
        if self.shown:
            print("\r\033[K", end="", file=sys.stderr, flush=True)


def format_table(results) -> str:
    width = max([16, *(len(r.policy) for r in results)])
    lines = [f"{'scenario':<13} {'policy':<{width}} {'episodes':>8} {'Mbps':>7} {'±95%':>6} {'R_fair':>7}"]
    for r in results:
        lines.append(f"{r.scenario:<13} {r.policy:<{width}} {r.episodes:>8} {r.mean_rate_mbps:>7.3f} "
                     f"{r.ci95_mbps:>6.3f} {r.mean_fair_rate:>7.3f}")
    return "\n".join(lines)


def cmd_train(args: argparse.Namespace) -> int:
    from uavlink.config import TrainConfig
    from uavlink.config.fields import flag_of, from_options
    from uavlink.learn.training import train

    cfg = apply_overrides(EnvConfig(), EnvOverrides.from_command_line(args.scenario, args.aoa_noise_deg, args.overrides))
    tc = from_options(TrainConfig, args).validate(cfg, name=lambda path: flag_of(TrainConfig, path))
    if args.eval_episodes < 0:
        raise UserError(f"--eval-episodes must be >= 0 (0: skip), got {args.eval_episodes}")
    if args.resume is not None and not args.resume.is_file():
        raise UserError(f"--resume {args.resume}: no such checkpoint")
    run_dir = args.run_dir or Path("runs") / f"{args.out.stem}-seed{tc.seed}"
    print(f"training PPO on {cfg.scenario!r} for {tc.total_timesteps(cfg):,} env steps; "
          f"TensorBoard logs and checkpoint in {run_dir}", file=sys.stderr)
    training = train(cfg, tc, args.out, run_dir, resume=args.resume, progress=not args.no_progress)
    if args.eval_episodes:
        _attach_evaluation(args.out, cfg, args.eval_episodes)
    print(f"saved {args.out} ({training['total_timesteps']:,} steps in {training['wall_time_s']:.0f} s)")
    return 0


def _attach_evaluation(path: Path, cfg: EnvConfig, episodes: int) -> None:
    """Evaluate the saved policy (seed 0) and store the figures in its manifest."""
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.manifest import read_zip_manifest, write_zip_manifest
    from uavlink.policies.sb3_policy import SB3Policy

    policy = SB3Policy(path)
    figures = {}
    for scenario in (SCENARIOS if cfg.scenario == MIXED else [cfg.scenario]):
        result = evaluate_policy(policy, cfg.replace(scenario=scenario), episodes, seed=0)
        figures[scenario] = {k: v for k, v in result.to_dict().items() if k != "episode_rate_mbps"}
    manifest = read_zip_manifest(path)
    manifest["evaluation"] = figures
    write_zip_manifest(path, manifest)


def cmd_export(args: argparse.Namespace) -> int:
    from uavlink.export import export_onnx, format_report

    out = args.out if args.out is not None else args.policy.with_suffix(".onnx")
    if out.suffix != ".onnx":
        raise UserError(f"--out {out}: an exported policy must end in .onnx")
    if args.n_verify < 1:
        raise UserError("--n-verify must be a positive integer")
    from uavlink.policies.registry import BASELINES

    if str(args.policy) in BASELINES and not args.policy.exists():
        raise UserError(f"{args.policy} is a baseline, not a trained policy: nothing to export"
                        + (" (it plans on the episode's future: evaluation only)" if str(args.policy) == "genie" else ""))
    if args.policy.suffix != ".zip" and args.policy.is_file():
        raise UserError(f"{args.policy}: expected an SB3 policy zip (FILE.zip)")
    report = export_onnx(args.policy, out, verify=not args.no_verify, n_verify=args.n_verify, seed=args.seed)
    print(json.dumps(report, indent=2) if args.json else format_report(report))
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from uavlink.sweep.aggregate import (
        export_median_policies,
        jobs_table,
        read_record,
        record_path,
        write_summary,
    )
    from uavlink.sweep.spec import load_spec

    spec = load_spec(args.file)  # SweepSpecError (a UserError): one line, exit 2, before any job
    if args.workers is not None and args.workers < 0:
        raise UserError("--workers must be >= 0 (0: run in this process without Dask)")
    if args.retries < 0:
        raise UserError("--retries must be >= 0")
    if args.policies_out is not None and len(spec.points()) > 1:
        raise UserError(f"--policies-out needs one setting per scenario; {args.file} has a grid of "
                        f"{len(spec.points())} points")
    # Jobs in the record shipped with the policies are done: only a changed recipe's jobs run again.
    record = read_record(record_path(args.policies_out, spec)) if args.policies_out is not None else {}
    if args.dry_run:
        print(jobs_table(spec.jobs(), args.out_root / spec.name, record.keys()))
        return 0
    from uavlink.sweep.runner import EngineError, run_sweep

    try:
        outcome = run_sweep(spec, args.out_root, scheduler=args.scheduler, workers=args.workers,
                            retries=args.retries, progress=not args.no_progress, done_keys=record.keys())
    except EngineError as exc:
        raise UserError(str(exc)) from None
    command = "uavlink " + " ".join(sys.argv[1:]) if sys.argv[1:2] == ["sweep"] else f"uavlink sweep {args.file}"
    markdown, table = write_summary(spec, outcome.sweep_dir, command, record)
    print(table)
    done = outcome.skipped + outcome.finished
    print(f"{done}/{outcome.jobs} jobs done ({outcome.finished} run now in {outcome.wall_s:.0f} s, "
          f"{outcome.skipped} skipped); summary in {markdown}", file=sys.stderr)
    if outcome.interrupted:
        print(f"uavlink sweep: interrupted; {done} finished jobs are kept, rerun to do the other "
              f"{outcome.jobs - done}", file=sys.stderr)
        return 130
    if outcome.failed:
        print(f"uavlink sweep: {len(outcome.failed)} jobs failed ({', '.join(sorted(outcome.failed))}); "
              f"see {outcome.sweep_dir}/<job>.error.txt, rerun to retry them", file=sys.stderr)
        return 1
    if args.policies_out is not None:
        for scenario, path, seed in export_median_policies(spec, outcome.sweep_dir, args.policies_out):
            print(f"{scenario}: median seed {seed} -> {path}", file=sys.stderr)
    return 0


def cmd_keygen(args: argparse.Namespace) -> int:
    """Write a new MAVLink 2 signing key: 32 random bytes (os.urandom), mode 0600, never overwriting."""
    import hashlib

    from uavlink.mavlink.signing import write_key

    try:
        path = write_key(args.out)
    except FileExistsError:
        raise UserError(f"{args.out} exists; refusing to overwrite a key (delete it first)") from None
    except OSError as exc:
        raise UserError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"wrote a 32-byte MAVLink signing key to {path} (mode 0600, fingerprint "
          f"{hashlib.sha256(path.read_bytes()).hexdigest()[:8]}); give it to the vehicle and to "
          f"`uavlink fly` with --signing-key {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="uavlink", description=__doc__.splitlines()[0])
    from uavlink import __version__

    parser.add_argument("--version", action="version", version=f"uavlink {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("evaluate", help="evaluate a policy or baseline, print a table",
                       description=f"Evaluate a policy file, a folder of them, or a baseline "
                                   f"({', '.join(BASELINE_NAMES)}, genie). " + OVERRIDES_HELP)
    _add_env_options(p, for_policy=True)
    p.add_argument("--policy", default="static",
                   help=f"{' | '.join(BASELINE_NAMES)} | genie (evaluation only: plans on the episode's "
                        "future) | FILE.zip | FILE.onnx | FOLDER")
    p.add_argument("--against", action="append", default=None, metavar="POLICY",
                   help="also fly this policy (same forms; repeatable) on the same episodes and print --policy's paired "
                        "throughput ratio with its 95 %% interval, the R_fair difference and the episodes won "
                        "(a fleet policy may face a single-UAV one: the same UEs and channel)")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--out", type=Path, default=None,
                   help="write a results folder (Table I/II as Markdown and CSV, figures); "
                        "needs --scenario all and --policy FOLDER")
    p.add_argument("--markdown", type=Path, default=None, help="where the report goes (default OUT/results.md)")
    p.add_argument("--sweep", type=Path, action="append", default=[],
                   help="with --out: add the across-seed table of this finished sweep file (e.g. "
                        "sweeps/table1.toml; repeat for more; a spatial-channel sweep goes with --spatial)")
    p.add_argument("--spatial", type=Path, default=None, metavar="FOLDER",
                   help="with --out: add the spatial-channel tables (radio.shadowing_model=spatial): FOLDER's "
                        "policies, trained on it, and --policy's flown on it (e.g. policies/spatial)")
    p.add_argument("--map", type=Path, default=None, metavar="FOLDER",
                   help="with --out and --spatial: add the memory-of-place table: FOLDER's map policies "
                        "(e.g. policies/map) against --spatial's, explore, aoa and static on the spatial channel")
    p.add_argument("--fleet", type=Path, default=None, metavar="FOLDER",
                   help="with --out and --spatial: add the fleet tables (D = 1, 2, 3 UAVs on the spatial channel): "
                        "FOLDER's fleet policies against the fleet baselines and --spatial's (e.g. policies/fleet)")
    p.add_argument("--sweep-root", type=Path, default=Path("runs"), help="where the sweep's results are (default runs)")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("train", help="train a PPO policy",
                       description="Train PPO on the batched env. Defaults are the paper's; the training "
                                   "options are TrainConfig's fields (uavlink/config/train.py).")
    _add_env_options(p)
    p.add_argument("--out", type=Path, required=True, help="policy zip to write")
    from uavlink.config import TrainConfig
    from uavlink.config.fields import add_options

    add_options(p, TrainConfig)
    p.add_argument("--run-dir", type=Path, default=None, help="TensorBoard logs and checkpoint (default runs/OUT-seedN)")
    p.add_argument("--resume", type=Path, default=None, help="continue from a checkpoint zip")
    p.add_argument("--eval-episodes", type=int, default=100, help="evaluate after training into the manifest (0: skip)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("export", help="export a policy zip to ONNX (fly without torch)",
                       description="Export an SB3 policy zip's deterministic actor to ONNX, with its "
                                   "manifest in the model metadata, and check onnxruntime's actions "
                                   "against SB3's on observations from seeded episodes.")
    p.add_argument("policy", type=Path, help="SB3 policy zip, e.g. policies/circular.zip")
    p.add_argument("--out", type=Path, default=None, help="ONNX file to write (default: POLICY with .onnx)")
    p.add_argument("--no-verify", action="store_true", help="skip the onnxruntime-vs-SB3 check")
    p.add_argument("--n-verify", type=int, default=1000, help="observations to check (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the verification episodes")
    p.add_argument("--json", action="store_true", help="print the export report as JSON")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("sweep", help="train + evaluate a grid of scenarios x seeds x settings on Dask",
                       description="Run a sweep file (TOML: scenarios, seeds, [train], [scenario_train.NAME], [env], [scenario_env.NAME], [eval], "
                                   "[grid]) on an embedded Dask cluster or --scheduler; writes "
                                   "OUT_ROOT/<name>/<job>/ and a per-setting summary. Finished jobs "
                                   "are skipped on a rerun. See sweeps/tiny.toml.")
    p.add_argument("file", type=Path, help="sweep file, e.g. sweeps/table1.toml")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler, e.g. tcp://HOST:8786 (default: a local cluster, one worker per core)")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes of the local cluster (default: one per core; 0: in this process, no Dask)")
    p.add_argument("--out-root", type=Path, default=Path("runs"), help="results go to OUT_ROOT/<sweep name>/")
    p.add_argument("--retries", type=int, default=2, help="retries of a job that raises (worker deaths are "
                                                          "rescheduled by Dask anyway)")
    p.add_argument("--policies-out", type=Path, default=None, metavar="DIR",
                   help="copy each scenario's median-seed policy to DIR/<scenario>.zip and the sweep's record "
                        "to DIR/<name>.sweep.json; jobs in that record count as done")
    p.add_argument("--dry-run", action="store_true", help="list the jobs and whether each is done, run nothing")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("keygen", help="make a MAVLink 2 signing key for fly and the vehicle",
                       description="Write 32 random bytes (os.urandom) to a new file with mode 0600, "
                                   "for --signing-key of `uavlink fly` and `sitl-stub`. Never overwrites.")
    p.add_argument("--out", type=Path, required=True, help="key file to create")
    p.set_defaults(func=cmd_keygen)

    from uavlink.flight.fly import add_fly_parser
    from uavlink.plot.command import add_plot_parser

    add_fly_parser(sub)
    add_plot_parser(sub)
    return parser




def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except UserError as exc:
        print(f"uavlink {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:  # the vehicle link (LinkError) and other run-time failures
        if type(exc).__name__ != "LinkError":
            raise
        print(f"uavlink {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # e.g. piped into head
        return 0
    except KeyboardInterrupt:
        print(f"uavlink {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
