"""``python -m sitl_stub`` / ``sitl-stub``: run the SITL vehicle until SIGINT/SIGTERM.

With no flags it talks as PX4 SITL instance 0 does: system 1, an API link from UDP 14580 to
127.0.0.1:14540 (MAVSDK's default) and a GCS link from 18570 to 127.0.0.1:14550 (QGroundControl,
MAVProxy); ``--instance N`` shifts the ports and the system id as PX4's ``-i N``. ``--connect URL``
(repeatable) replaces those links. ``--fleet D`` runs D vehicles (instances N .. N+D-1) around one
shared radio world (:mod:`sitl_stub.fleet`); with ``--connect`` it takes D URLs, one per vehicle. Example: ``python -m sitl_stub --scenario circular --seed 1
--connect udpout:127.0.0.1:14550 --speed 20``. Bad arguments print one line and exit with status 2; a connection that cannot be
opened exits with status 1. On exit it prints one line ``sitl-stub: stats {json}`` with the
counters of :meth:`~sitl_stub.mavlink.server.SitlServer.report` (signing, rejected input, ACKs,
safety monitors).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import logging
import math
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.params import PARAM_DEFS
from sitl_stub.launcher import PROG
from sitl_stub.mavlink.links import MAX_INSTANCE
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import Payload, PayloadFactory, PayloadOptions, as_payload_list
from uavlink.config import MIXED, SCENARIO_NAMES, EnvConfig, parse_settings
from uavlink.errors import OneLineParser
from uavlink.mavlink.connection import normalize_connection
from uavlink.mavlink.signing import key_file_argument, load_key

if TYPE_CHECKING:
    from sitl_stub.fleet import FleetServer


class _LogFormat(logging.Formatter):
    """Log lines with the program's prefix, as its own lines: ``sitl-stub: MESSAGE`` from the
    vehicle's loggers (``sitl_stub``, ``sitl_stub.*``), ``sitl-stub: LOGGER: MESSAGE`` from others."""

    def formatMessage(self, record: logging.LogRecord) -> str:
        ours = record.name == "sitl_stub" or record.name.startswith("sitl_stub.")
        return f"{PROG}: {record.message}" if ours else f"{PROG}: {record.name}: {record.message}"


def _positive(text: str) -> float:
    v = _finite(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return v


def _non_negative(text: str) -> float:
    v = _finite(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return v


def _finite(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    return v


def _connection(text: str) -> str:
    try:
        normalize_connection(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _param(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    names = {d.name for d in PARAM_DEFS}
    if not sep or name not in names:
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with NAME one of {', '.join(sorted(names))}, got {text!r}"
        )
    return name, _finite(value)


def _setting(text: str) -> tuple[str, object]:
    try:
        [(key, value)] = parse_settings([text]).items()
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return key, value


def _int_in(low: int, high: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if not low <= v <= high:
            raise argparse.ArgumentTypeError(f"must be in {low}..{high}, got {text}")
        return v

    return parse


def _version() -> str:
    """The installed distribution's version (sitl_stub ships inside uavlink's)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("uavlink")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "(not installed)"


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog=PROG,
        description="A lightweight PX4-style SITL multicopter speaking "
        "MAVLink 2, with a radio payload component.",
    )
    p.add_argument("--version", action="version", version=f"{PROG} {_version()}")
    p.add_argument(
        "--connect",
        type=_connection,
        action="append",
        default=None,
        metavar="URL",
        help="talk on this connection instead of PX4's ports (repeatable: one link "
        "each): udpout:HOST:PORT sends; udp:HOST:PORT or udp:PORT listens; "
        "MAVSDK-style udpin:// and udpout:// URLs and tcp:/tcpin: work too. Default: "
        "PX4 SITL's links, API from UDP 14580+N to 127.0.0.1:14540+N and GCS from "
        "18570+N to 127.0.0.1:14550",
    )
    p.add_argument(
        "--instance",
        "-i",
        type=_int_in(0, MAX_INSTANCE),
        default=0,
        metavar="N",
        help="PX4 SITL instance number, as PX4's -i N: the ports above and system id "
        "N+1 (default 0)",
    )
    p.add_argument(
        "--fleet",
        type=_int_in(1, 16),
        default=None,
        metavar="D",
        help="run D vehicles in this process around one shared radio world (n_uavs = D), "
        "as PX4's multi-vehicle SITL: vehicle i is instance N+i, system N+i+1, on that "
        "instance's ports (all GCS links to 14550), spawning at the fleet's start "
        "position i (its home); with --connect, give D URLs, vehicle i on the i-th "
        "(default: one vehicle)",
    )
    p.add_argument(
        "--speed", type=_positive, default=1.0, help="simulated seconds per wall second (default 1)"
    )
    p.add_argument(
        "--scenario",
        choices=SCENARIO_NAMES,
        default="circular",
        help="UE mobility scenario for the radio payload (default circular); "
        f"{MIXED}: each flight's episode draws one, as `uavlink evaluate --episodes 1 "
        "--seed S` draws it for the same seed",
    )
    p.add_argument("--seed", type=int, default=0, help="radio payload seed, 0..2**31-1 (default 0)")
    p.add_argument(
        "--aoa-noise-deg",
        type=_non_negative,
        default=0.0,
        help="AoA noise std of the radio payload, degrees (default 0)",
    )
    p.add_argument(
        "--set",
        dest="settings",
        type=_setting,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="env config field of the radio payload, as uavlink's "
        "--set, e.g. action_mapping=polar-v1 or radio.shadowing=false (repeatable)",
    )
    p.add_argument(
        "--home-lat",
        type=_finite,
        default=GeoOrigin.lat_deg,
        help=f"home / LOCAL_NED origin latitude, deg (default {GeoOrigin.lat_deg})",
    )
    p.add_argument(
        "--home-lon",
        type=_finite,
        default=GeoOrigin.lon_deg,
        help=f"home / LOCAL_NED origin longitude, deg (default {GeoOrigin.lon_deg})",
    )
    p.add_argument(
        "--home-alt",
        type=_finite,
        default=GeoOrigin.alt_amsl_m,
        help=f"home altitude AMSL, m (default {GeoOrigin.alt_amsl_m})",
    )
    p.add_argument(
        "--duration-s",
        type=_positive,
        default=None,
        help="stop after this many simulated seconds (default: run until signalled)",
    )
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a parameter default, e.g. MIS_TAKEOFF_ALT=10 (repeatable)",
    )
    p.add_argument(
        "--system-id",
        type=_int_in(1, 255),
        default=None,
        help="MAVLink system id of the vehicle and its payloads (PX4's MAV_SYS_ID; "
        "default: instance + 1)",
    )
    p.add_argument("--no-payload", action="store_true", help="run without the radio payload")
    p.add_argument(
        "--no-ue-truth",
        action="store_true",
        help="do not send the simulated UE positions (one ADSB_VEHICLE per UE per frame "
        "from the radio payload, the simulation's truth that ground stations draw as "
        "traffic and `uavlink plot` draws as UE tracks)",
    )
    p.add_argument(
        "--signing-key",
        metavar="FILE",
        default=None,
        type=key_file_argument,
        help="MAVLink 2 signing key (32 raw bytes, e.g. from `uavlink keygen`): sign "
        "everything sent, drop every unsigned, wrongly signed or replayed packet (default: "
        "unsigned)",
    )
    p.add_argument(
        "--lockstep",
        action="store_true",
        help="hold simulated time at each radio frame of a running episode until the "
        "flight computer has decided it (`uavlink fly` says so after each setpoint), "
        "at most 2 s of wall time: a flight decides every frame at the instant the env "
        "does and replays exactly (needs the radio payload: not with --no-payload)",
    )
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="log vehicle events (also sent as STATUSTEXT)",
    )
    return p


def radio_payload(options: PayloadOptions) -> Payload:
    """The default payload: the radio simulator's base station (imported here, not at start: it
    loads the env)."""
    from sitl_stub.sim.radio_payload import RadioPayload

    return RadioPayload(options)


def main(argv: Sequence[str] | None = None, payload_factory: PayloadFactory | None = None) -> int:
    """Parse ``argv``, build payloads with ``payload_factory`` and run the vehicle."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.lockstep and args.no_payload:
        parser.error(
            "--lockstep holds the radio payload's frames: it does nothing with --no-payload"
        )
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_LogFormat())
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, handlers=[handler])
    home = GeoOrigin(args.home_lat, args.home_lon, args.home_alt)
    try:
        home.validate()
        options = PayloadOptions(
            args.scenario,
            args.seed,
            args.aoa_noise_deg,
            tuple(args.settings),
            home,
            not args.no_ue_truth,
            args.lockstep,
        )
        payloads = (
            []
            if args.no_payload or args.fleet
            else as_payload_list((payload_factory or radio_payload)(options))
        )
        key = load_key(args.signing_key) if args.signing_key is not None else None
        # The radio world's env, checked with or without a payload: the vehicle's hard limit is its
        # area, --set area.half_width_m included.
        from sitl_stub.sim.radio_payload import payload_env

        world_env = payload_env(options, args.fleet or 1)
        config = ServerConfig(
            area=world_env.area,
            connect=args.connect,
            instance=args.instance,
            speed=args.speed,
            home=home,
            params=dict(args.param),
            system_id=args.system_id,
            duration_s=args.duration_s,
            signing_key=key,
        )
        server = (
            SitlServer(config, payloads)
            if args.fleet is None
            else _fleet(args, config, options, world_env)
        )
    except ValueError as exc:
        parser.error(str(exc))
    try:
        server.open()
    except OSError as exc:
        hint = "" if args.connect else " (another vehicle on these ports? try --instance)"
        print(f"{PROG}: error: cannot open {exc.strerror or exc}{hint}", file=sys.stderr)
        return 1
    signing = f"signing on (key {hashlib.sha256(key).hexdigest()[:8]})" if key else "signing off"
    if isinstance(server, SitlServer):  # one vehicle: args.fleet is None
        who, count = f"vehicle {server.system_id}", len(payloads)
    else:
        who = f"fleet of {args.fleet} vehicles ({'no' if args.no_payload else 'one shared'} radio world)"
        count = len(server.world.views) if server.world else 0
    stop = threading.Event()

    def _on_signal(signum: int, _frame: object) -> None:
        stop.set()

    # before the ready line: a launcher that signals as soon as it reads it gets a clean stop
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, _on_signal)
    lockstep = ", lockstep" if args.lockstep and count else ""
    # the ready line: sitl_stub.launcher's READY_LINE recognises it
    print(
        f"{PROG}: {who} on {server.connection}, {args.speed:g}x real time{lockstep}, "
        f"{count} payload(s), {signing}",
        file=sys.stderr,
        flush=True,
    )
    try:
        server.run(stop)
    finally:
        server.close()
        print(
            f"{PROG}: stats {json.dumps(server.report(), sort_keys=True)}",
            file=sys.stderr,
            flush=True,
        )
    return 0


def _fleet(
    args: argparse.Namespace, base: ServerConfig, options: PayloadOptions, cfg: EnvConfig
) -> FleetServer:
    """``--fleet D``: D vehicles around one radio world ``cfg`` (:mod:`sitl_stub.fleet`)."""
    from sitl_stub.fleet import FleetServer, FleetWorld, fleet_configs, spawn_points_ne

    if args.instance + args.fleet - 1 > MAX_INSTANCE:
        raise ValueError(
            f"--instance {args.instance} --fleet {args.fleet} needs instances up to "
            f"{args.instance + args.fleet - 1}, more than {MAX_INSTANCE}"
        )
    world = (
        None
        if args.no_payload
        else FleetWorld(
            cfg, args.seed, options.home if options.ue_truth else None, options.lockstep
        )
    )
    return FleetServer(fleet_configs(base, args.fleet, spawn_points_ne(cfg)), world)


if __name__ == "__main__":
    sys.exit(main())
