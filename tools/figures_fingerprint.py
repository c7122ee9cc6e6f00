"""The figures a refactor must not move: `uavlink evaluate --json` of every shipped policy and of the
baselines on every scenario (one UAV and two, both channels), the genie, kriging and a comparison,
3 episodes each at seed 0, written one file per command; with --against, compared byte for byte
with an earlier run's files. What the memory table's refactor was checked with (research/log/memory-of-place.md,
"The memory's table, halved").

    python tools/figures_fingerprint.py --out /tmp/before        # at the commit before
    python tools/figures_fingerprint.py --out /tmp/after --against /tmp/before --json
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SPATIAL = ("--set", "radio.shadowing_model=spatial")


def commands() -> list[list[str]]:
    """Each `uavlink evaluate` command's arguments (without --episodes, --seed and --json)."""
    policies = sorted(
        str(p.relative_to(ROOT))
        for folder in ("", "spatial", "fleet_d2", "map")
        for p in (ROOT / "policies" / folder).glob("*.zip")
    )
    out = [["--policy", p] for p in policies]
    for baseline in ("static", "aoa", "oracle", "kmeans", "explore"):
        for extra in ([], ["--set", "n_uavs=2"], [*SPATIAL, "--set", "n_uavs=2"], [*SPATIAL]):
            out.append(["--policy", baseline, "--scenario", "all", *extra])
    out += [
        ["--policy", "genie", "--scenario", "all", *SPATIAL],
        ["--policy", "genie", "--scenario", "straight", *SPATIAL, "--set", "n_uavs=2"],
        ["--policy", "kriging", "--scenario", "no_move", *SPATIAL, "--set", "place_cell_m=12"],
        ["--policy", "policies/fleet_d2/hotspot.zip", "--against", "policies/spatial/hotspot.zip"],
    ]
    return out


def run(args: list[str]) -> str:
    """One command's output: stdout, then stderr after a marker (a refused command's line counts too)."""
    from uavlink.cli import main

    out, err = io.StringIO(), io.StringIO()
    # argparse's refusals exit
    with (
        contextlib.redirect_stdout(out),
        contextlib.redirect_stderr(err),
        contextlib.suppress(SystemExit),
    ):
        main(["evaluate", *args, "--episodes", "3", "--seed", "0", "--json"])
    return out.getvalue() + "\n--- stderr\n" + err.getvalue()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, required=True, help="folder for one file per command (made)"
    )
    parser.add_argument(
        "--against", type=Path, default=None, help="an earlier run's folder to compare with"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    index, differ, todo = [], [], commands()
    with contextlib.chdir(ROOT):  # the policies by the paths the docs give
        for i, words in enumerate(todo):
            name = f"{i:02d}.txt"
            (args.out / name).write_text(run(words))
            index.append({"file": name, "command": "uavlink evaluate " + " ".join(words)})
            earlier = None if args.against is None else args.against / name
            if earlier is not None and not (
                earlier.is_file() and earlier.read_bytes() == (args.out / name).read_bytes()
            ):
                differ.append(name)
            if sys.stderr.isatty():
                print(f"\r{i + 1}/{len(todo)} commands", end="", file=sys.stderr, flush=True)
    (args.out / "index.json").write_text(json.dumps(index, indent=1) + "\n")
    report = {
        "benchmark": "figures_fingerprint",
        "commands": len(index),
        "out": str(args.out),
        "against": str(args.against) if args.against else None,
        "differ": differ,
    }
    print(
        json.dumps(report, indent=2)
        if args.json
        else f"{len(index)} commands into {args.out}"
        + (
            f"; {len(differ)} differ from {args.against}: {', '.join(differ) or 'none'}"
            if args.against
            else ""
        )
    )
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
