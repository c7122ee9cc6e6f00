"""How long one full pass of Python's cyclic garbage collector stalls `uavlink fly` with a policy
loaded, as the flight loop meets it (gc.collect of generation 2), and with the heap frozen as the loop
freezes it (``uavlink.flight.steady.steady_heap``): the offboard stream of a vehicle at 20x real time
tolerates 50 ms of wall time (research/log/flight.md, "A pause in the fleet's flights").

    python benchmarks/gc_pause.py [--policy policies/fleet_d2/straight_180.zip] [--passes 5] [--json]
"""

from __future__ import annotations

import argparse
import gc
import json
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def full_pass_ms(passes: int, allocate: int) -> list[float]:
    """Wall ms of ``passes`` full collections, each after ``allocate`` new small cycles (a flight's
    garbage: messages, arrays, dicts)."""
    times = []
    for _ in range(passes):
        garbage = []
        for _ in range(allocate):
            node: dict = {}
            node["self"] = node
            garbage.append(node)
        del garbage
        start = time.perf_counter()
        gc.collect()
        times.append((time.perf_counter() - start) * 1e3)
    return times


def run(policy: Path, passes: int, allocate: int) -> dict:
    import uavlink.flight.fly  # noqa: F401 - what fly has imported when it flies
    from uavlink.flight.steady import steady_heap
    from uavlink.policies.contract import EnvOverrides, load_with_env

    load_with_env([policy], EnvOverrides())  # torch, SB3 and the policy's weights
    gc.collect()
    objects = len(gc.get_objects())
    plain = full_pass_ms(passes, allocate)
    with steady_heap():
        frozen = full_pass_ms(passes, allocate)
    return {
        "benchmark": "gc_pause",
        "policy": str(policy),
        "tracked_objects": objects,
        "passes": passes,
        "allocated_cycles_per_pass": allocate,
        "full_pass_ms": [round(t, 2) for t in plain],
        "frozen_full_pass_ms": [round(t, 2) for t in frozen],
        "median_ms": round(sorted(plain)[passes // 2], 2),
        "frozen_median_ms": round(sorted(frozen)[passes // 2], 2),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--policy", type=Path, default=ROOT / "policies" / "fleet_d2" / "straight_180.zip"
    )
    parser.add_argument("--passes", type=int, default=5, help="timed full collections each way")
    parser.add_argument(
        "--allocate", type=int, default=10_000, help="new small cycles before each pass"
    )
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a line"
    )
    args = parser.parse_args(argv)
    if args.passes < 1 or args.allocate < 0:
        parser.error("--passes must be >= 1 and --allocate >= 0")
    report = run(args.policy, args.passes, args.allocate)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(
            f"{report['tracked_objects']:,} objects tracked with {args.policy} loaded: a full collection takes "
            f"{report['median_ms']:.1f} ms (median of {args.passes}), {report['frozen_median_ms']:.1f} ms with "
            f"the heap frozen as the flight loop freezes it"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
