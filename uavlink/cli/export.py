"""``uavlink export``: a policy zip's deterministic actor to ONNX, checked against SB3."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from uavlink.cli.options import output_file, seed
from uavlink.errors import UserError


def cmd_export(args: argparse.Namespace) -> int:
    from uavlink.export import export_onnx, format_report
    from uavlink.policies.loader import locate
    from uavlink.policies.registry import BASELINES

    if args.n_verify < 1:
        raise UserError("--n-verify must be a positive integer")
    named = not args.policy.exists() and str(args.policy) not in BASELINES
    if named:  # a shipped policy by name (uavlink policies); its ONNX file goes here, not beside it
        args.policy = Path(locate(args.policy))  # the report names the file
    if args.policy.is_dir():
        raise UserError(f"{args.policy} is a folder; give a policy zip (FILE.zip)")
    default_out = Path(args.policy.name) if named else args.policy
    out = output_file(
        args.out if args.out is not None else default_out.with_suffix(".onnx"), "--out", (".onnx",)
    )
    if str(args.policy) in BASELINES and not args.policy.exists():
        raise UserError(
            f"{args.policy} is a baseline, not a trained policy: nothing to export"
            + (
                " (it plans on the episode's future: evaluation only)"
                if str(args.policy) == "genie"
                else ""
            )
        )
    if args.policy.suffix != ".zip" and args.policy.is_file():
        raise UserError(f"{args.policy}: expected an SB3 policy zip (FILE.zip)")
    report = export_onnx(
        args.policy, out, verify=not args.no_verify, n_verify=args.n_verify, seed=args.seed
    )
    print(json.dumps(report, indent=2) if args.json else format_report(report))
    return 0


def add_export_parser(sub) -> None:
    p = sub.add_parser(
        "export",
        help="export a policy zip to ONNX (fly without torch)",
        description="Export an SB3 policy zip's deterministic actor to ONNX, with its "
        "manifest in the model metadata, and check onnxruntime's actions "
        "against SB3's on observations from seeded episodes.",
    )
    p.add_argument(
        "policy",
        type=Path,
        help="SB3 policy zip, e.g. policies/circular.zip, or a shipped policy's name "
        "(uavlink policies), e.g. fleet/hotspot",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="ONNX file to write (default: POLICY with .onnx; for a name, NAME.onnx here)",
    )
    p.add_argument("--no-verify", action="store_true", help="skip the onnxruntime-vs-SB3 check")
    p.add_argument(
        "--n-verify", type=int, default=1000, help="observations to check (default 1000)"
    )
    p.add_argument(
        "--seed", type=seed, default=0, help="seed of the verification episodes (default 0)"
    )
    p.add_argument("--json", action="store_true", help="print the export report as JSON")
    p.set_defaults(func=cmd_export)
