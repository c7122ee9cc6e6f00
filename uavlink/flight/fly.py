"""The ``uavlink fly`` command: policy + link + (optionally) an embedded SITL vehicle."""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from uavlink.config import EnvConfig
from uavlink.flight.connection import free_udp_port

log = logging.getLogger("uavlink.fly")


def policy_env_config(policy, scenario: str, aoa_noise_deg: float) -> EnvConfig:
    """The env config the policy was trained on (from its manifest), on the requested scenario."""
    manifest = getattr(policy, "manifest", None)
    base = EnvConfig.from_dict(manifest["env_config"]) if manifest else EnvConfig()
    return base.replace(scenario=scenario, aoa_noise_deg=aoa_noise_deg).validate()


@contextlib.contextmanager
def embedded_sitl(scenario: str, seed: int, speed: float, aoa_noise_deg: float, log_path: Path | None,
                  signing_key_file: Path | None = None):
    """Start ``python -m sitl_stub`` on a free loopback port; yields the URL to listen on."""
    port = free_udp_port()
    cmd = [sys.executable, "-m", "sitl_stub", "--scenario", scenario, "--seed", str(seed),
           "--connect", f"udpout:127.0.0.1:{port}", "--speed", f"{speed:g}",
           "--aoa-noise-deg", f"{aoa_noise_deg:g}"]
    if signing_key_file is not None:
        cmd += ["--signing-key", str(signing_key_file)]
    out = open(log_path, "w") if log_path else subprocess.DEVNULL  # noqa: SIM115
    proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT)
    try:
        yield f"udpin:127.0.0.1:{port}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
        if log_path:
            out.close()


def run_fly(args: argparse.Namespace) -> int:
    from uavlink.flight.link import VehicleLink
    from uavlink.flight.mission import MissionConfig, PolicyPilot, fly_mission
    from uavlink.flight.signing import load_key
    from uavlink.policies.loader import load_policy

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    key = load_key(args.signing_key) if args.signing_key else None  # before anything flies
    provisional = EnvConfig().replace(scenario=args.scenario, aoa_noise_deg=args.aoa_noise_deg).validate()
    policy = load_policy(args.policy, provisional)
    if policy.needs_truth:
        raise ValueError("the oracle needs UE positions (GPS) and cannot fly; use a policy file, aoa or static")
    cfg = policy_env_config(policy, args.scenario, args.aoa_noise_deg)
    pilot = PolicyPilot(policy, cfg)  # layout checks happen here, before anything is armed
    out_dir = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    tlog = out_dir / "flight.tlog"

    # The live line is for a person at a terminal; piped or logged output gets none of its \r frames.
    live = not (args.quiet or args.json) and sys.stderr.isatty()

    def status(frame: int, target: np.ndarray, rate: float | None) -> None:
        if not live:
            return
        rate_text = f"{rate:5.2f} Mbps" if rate is not None else "  --- Mbps"
        print(f"\rframe {frame + 1:4d}/{args.frames}  target E {target[0]:7.1f} N {target[1]:7.1f} m  "
              f"{rate_text}", end="", file=sys.stderr, flush=True)

    sitl = (embedded_sitl(args.scenario, args.seed, args.speed, args.aoa_noise_deg, out_dir / "sitl.log",
                          Path(args.signing_key) if key else None)
            if args.connect is None else contextlib.nullcontext(args.connect))
    start = time.monotonic()
    with sitl as url:
        link = VehicleLink(url, tlog=tlog, signing_key=key)
        try:
            result = fly_mission(link, pilot, cfg, MissionConfig(frames=args.frames), status=status)
            speed = link.speed_factor()
        finally:
            link.close()
            if link.signing is not None and link.signing.rejected_total:
                log.warning("signing: refused %d packets from the vehicle side (%s)",
                            link.signing.rejected_total, link.signing.stats())
    if live:
        print(file=sys.stderr)
    summary = {
        "scenario": args.scenario, "policy": str(args.policy), "seed": args.seed,
        "connect": args.connect or "embedded sitl_stub", "speed_factor": round(speed, 2),
        **result.summary(), "wall_s": round(time.monotonic() - start, 2), "tlog": str(tlog),
        "signing": link.signing.stats() if link.signing else None,
        "link_rejected": link.rejects.as_dict(),
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(f"flew {summary['frames']} frames of {args.scenario!r} with {args.policy}: "
              f"mean UE throughput {summary['mean_rate_mbps']} Mbps; decision latency p50 "
              f"{summary['latency_ms_p50']} ms, p99 {summary['latency_ms_p99']} ms; "
              f"log {tlog}, summary {out_dir / 'summary.json'}")
    return 130 if result.interrupted else 0


def add_fly_parser(sub) -> None:
    p = sub.add_parser("fly", help="fly a policy over MAVLink (embedded SITL without --connect)",
                       description="Fly a policy: each radio frame becomes a MAVLink position setpoint. "
                                   "Without --connect, an embedded sitl_stub vehicle is started on a free port.")
    p.add_argument("--policy", default="policies/circular.zip", help="FILE.zip | FILE.onnx | aoa | static")
    p.add_argument("--connect", default=None,
                   help="vehicle link: udp:14550 (listen), udp:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
                        "udpin://0.0.0.0:14550, udpout://HOST:PORT")
    p.add_argument("--scenario", default="circular", help="scenario of the embedded SITL (and the policy's env)")
    p.add_argument("--seed", type=int, default=0, help="seed of the embedded SITL's scenario")
    p.add_argument("--aoa-noise-deg", type=float, default=0.0)
    p.add_argument("--speed", type=float, default=20.0, help="embedded SITL speed factor")
    p.add_argument("--frames", type=int, default=128, help="decision frames to fly (one episode: 128)")
    p.add_argument("--out", type=Path, default=Path("runs/fly"), help="folder for flight.tlog and summary.json")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--quiet", action="store_true", help="no live status line")
    p.add_argument("--signing-key", metavar="FILE", default=None,
                   help="MAVLink 2 signing key (32 raw bytes, from `uavlink keygen`): sign everything "
                        "sent, accept only packets signed with it (the embedded SITL gets it too)")
    p.add_argument("--verbose", action="store_true", help="log link events")
    p.set_defaults(func=run_fly)
