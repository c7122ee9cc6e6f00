"""Throughput of a flown episode under link faults: clean, 10 % and 30 % loss, 200 ms delay.

Each row flies 128-frame episodes with `uavlink fly` (a child process) against
`python -m sitl_stub` (another) through the test relay `tests/support/udp_relay.py` on loopback, which
drops / delays datagrams in both directions (seeded). Throughput is the vehicle's own truth (its
radio payload's mean UE rate over the episode's 128 frames), so lost score messages do not bias
it; fly's own view is reported too. Loss rows run at --speed (default 20, as `uavlink fly`),
--runs times each with different relay seeds (mean and range; a relay seed does not make a run
repeatable: which packets meet which draw depends on timing);
the delay row runs at --delay-speed (default 1: 200 ms of wall time is 200 ms of vehicle time,
0.2 of a 1 s decision frame each way) and is compared with a clean run at that speed.

Target: under 10 % loss, within 5 % of the clean run; at 30 % loss the vehicle stays in
the geofence and never flies OFFBOARD on a setpoint older than COM_OF_LOSS_T (1 s).

    python research/link_faults.py [--json] [--policy policies/circular.zip] [--quick]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from entry import run_script

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from support.relay_flight import fly_through_relay, format_table, table_row  # noqa: E402
from support.udp_relay import CLEAN, Faults  # noqa: E402

from uavlink.config import SCENARIO_NAMES  # noqa: E402
from uavlink.policies.registry import BASELINES  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="policies/circular.zip")
    parser.add_argument("--scenario", default="circular", choices=SCENARIO_NAMES)
    parser.add_argument("--seed", type=int, default=0, help="scenario seed (the UEs' episode)")
    parser.add_argument(
        "--relay-seed", type=int, default=0, help="first seed of the relay's faults"
    )
    parser.add_argument(
        "--runs",
        type=int,
        default=3,
        help="flights per loss row, relay seeds relay-seed, relay-seed + 1, ...",
    )
    parser.add_argument("--speed", type=float, default=20.0, help="--speed of the loss rows")
    parser.add_argument("--delay-speed", type=float, default=1.0, help="--speed of the delay rows")
    parser.add_argument("--delay-ms", type=float, default=200.0, help="one-way delay, ms")
    parser.add_argument("--quick", action="store_true", help="skip the (slow) delay rows")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = parser.parse_args(argv)
    if not Path(args.policy).is_file() and args.policy not in BASELINES:
        parser.error(f"--policy {args.policy}: no such file or baseline")

    def run(faults: Faults, speed: float, relay_seed: int | None = None) -> dict:
        started = time.monotonic()
        result = fly_through_relay(
            faults,
            policy=args.policy,
            scenario=args.scenario,
            seed=args.seed,
            speed=speed,
            timeout_s=60 + 400 / speed,
            relay_seed=args.relay_seed if relay_seed is None else relay_seed,
        )
        print(
            f"  {faults.describe()} at --speed {speed:g}: {time.monotonic() - started:.0f} s",
            file=sys.stderr,
            flush=True,
        )
        return result

    rows = []
    clean = run(CLEAN, args.speed)
    base = clean["vehicle"]["payloads"]["158"]["mean_rate_mbps"]
    rows.append(table_row("clean", clean, base))
    for loss in (0.10, 0.30):
        runs = [run(Faults(loss=loss), args.speed, args.relay_seed + i) for i in range(args.runs)]
        rows.append(table_row(f"{loss:.0%} loss", runs, base))
    if not args.quick:
        slow_clean = run(CLEAN, args.delay_speed)
        slow_base = slow_clean["vehicle"]["payloads"]["158"]["mean_rate_mbps"]
        rows.append(table_row("clean", slow_clean, slow_base))
        delayed = run(Faults(delay_s=args.delay_ms / 1e3), args.delay_speed)
        rows.append(table_row(f"{args.delay_ms:.0f} ms delay each way", delayed, slow_base))
    if args.json:
        print(
            json.dumps(
                {
                    "policy": args.policy,
                    "scenario": args.scenario,
                    "seed": args.seed,
                    "relay_seed": args.relay_seed,
                    "rows": rows,
                },
                indent=2,
            )
        )
    else:
        print(
            f"policy {args.policy}, scenario {args.scenario} seed {args.seed}, 128 frames, "
            f"relay seeds from {args.relay_seed}"
        )
        print(format_table(rows))
    return 0


if __name__ == "__main__":
    run_script(main)
