"""``uavlink fly``: its options; the command is ``uavlink.flight.fly.run_fly`` (imported when it runs)."""

from __future__ import annotations

import argparse
from pathlib import Path

from uavlink.cli.options import output_folder, seed
from uavlink.errors import EXTRA_OF_MODULE
from uavlink.flight import EMBEDDED_SPEED
from uavlink.mavlink.signing import key_file_argument
from uavlink.policies.contract import OVERRIDES_HELP
from uavlink.policies.registry import flying_baselines


def cmd_fly(args: argparse.Namespace) -> int:
    from uavlink.flight.fly import FlyOptions, run_fly

    output_folder(args.out, "--out")
    options = FlyOptions(
        policy=args.policy,
        connect=args.connect,
        scenario=args.scenario,
        seed=args.seed,
        aoa_noise_deg=args.aoa_noise_deg,
        overrides=tuple(args.overrides),
        speed=args.speed,
        lockstep=args.lockstep,
        frames=args.frames,
        out=args.out,
        picture=not args.no_picture,
        signing_key=Path(args.signing_key) if args.signing_key is not None else None,
        verbose=args.verbose,
    )
    return run_fly(options, as_json=args.json, quiet=args.quiet)


def policy_help() -> str:
    """What ``--policy`` takes: a policy file, a baseline that flies or a shipped policy's name."""
    return " | ".join(
        (
            "FILE.zip",
            "FILE.onnx",
            *flying_baselines(),
            "NAME (uavlink policies)",
            "FOLDER (its policy for --scenario)",
        )
    )


def add_fly_parser(sub) -> None:
    p = sub.add_parser(
        "fly",
        help="fly a policy over MAVLink (embedded SITL without --connect)",
        description="Fly a policy: each radio frame becomes a MAVLink position setpoint. "
        "Without --connect, an embedded sitl_stub vehicle is started on a free "
        "port, simulating the policy's env; a fleet policy (n_uavs > 1 in its "
        "manifest, or --set n_uavs=D for a baseline) flies D vehicles "
        "(sitl_stub --fleet D). Exit status: 0 when every frame set out "
        "to was flown; 1 when not (one line says why; summary.json has "
        "completed: false and the reason); 130 after Ctrl-C (the vehicle "
        "lands); 2 for bad input. " + OVERRIDES_HELP,
    )
    p.add_argument("--policy", default="circular", help=policy_help() + " (default: circular)")
    p.add_argument(
        "--connect",
        default=None,
        help="vehicle link: udp:14550 (listen), udp:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
        "udpin://0.0.0.0:14550, udpout://HOST:PORT; a fleet (n_uavs = D > 1): D URLs "
        "URL1,URL2,... (vehicle i flies UAV i), or one URL carrying every system "
        "(e.g. udp:14550: systems in ascending id order)",
    )
    p.add_argument(
        "--scenario",
        default=None,
        help="scenario of the embedded SITL and the policy's env "
        "(default: the policy's own; circular for a baseline); mixed: the flight's "
        "episode draws one from --seed, as `uavlink evaluate --episodes 1` does, and the "
        "summary names it",
    )
    p.add_argument(
        "--seed",
        type=seed,
        default=0,
        help="seed of the embedded SITL's radio episode, 0..2**31-1 (episode 0 of "
        "`uavlink evaluate --seed`); with --connect the vehicle's own episode is "
        "flown and reported (default: 0)",
    )
    p.add_argument(
        "--aoa-noise-deg",
        type=float,
        default=None,
        help="std of the AoA estimate noise (deg) (default: the policy's, 0)",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a field of the policy's env (the embedded SITL simulates it too), "
        "e.g. --set radio.shadowing=false",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=None,
        help="embedded SITL speed factor, > 0 (simulated seconds per wall second; default "
        f"{EMBEDDED_SPEED:g}; "
        "a vehicle you --connect to runs at the speed it was started with): "
        "a vehicle waits 1/speed s of wall time for setpoints, so where the flight says its "
        "vehicles fell back to hold, fly slower or with --lockstep",
    )
    p.add_argument(
        "--lockstep",
        action="store_true",
        help="run the embedded SITL in lockstep (sitl-stub --lockstep): its time waits for "
        "each frame's decision, so the flight replays exactly and follows `uavlink "
        "evaluate --episodes 1 --seed S --set uav_motion=px4` (the summary's replay) "
        "to the last digit",
    )
    p.add_argument(
        "--frames",
        type=int,
        default=None,
        help="decision frames to fly, 1 to the env's episode_frames (default: one episode, 128)",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=Path("runs/fly"),
        help="folder for flight.tlog, summary.json, flight.png (the flight's picture, "
        f"as `uavlink plot` draws it; needs pip install 'uavlink[{EXTRA_OF_MODULE['matplotlib']}]') and, "
        "with the "
        "embedded SITL, sitl.log (the vehicle's output); default runs/fly",
    )
    p.add_argument("--no-picture", action="store_true", help="do not draw flight.png")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--quiet", action="store_true", help="no live status line")
    p.add_argument(
        "--signing-key",
        metavar="FILE",
        default=None,
        type=key_file_argument,
        help="MAVLink 2 signing key (32 raw bytes, from `uavlink keygen`): sign everything "
        "sent, accept only packets signed with it (the embedded SITL gets it too)",
    )
    p.add_argument("--verbose", action="store_true", help="log link events")
    p.set_defaults(func=cmd_fly)
