"""The ``uavlink fly`` command: a policy, its vehicle(s) (``uavlink.flight.vehicles``: the embedded
SITL or ``--connect``) and the loop that flies one vehicle (``mission``) or a fleet, the policy's env
having ``n_uavs`` > 1 (``fleet_mission``); then the summary and the picture (``outcome``)."""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from uavlink.config import EnvConfig
from uavlink.errors import UserError
from uavlink.flight.outcome import StatusLine, episode_fields, finish, flown_name, link_fields
from uavlink.flight.steady import steady_heap
from uavlink.flight.vehicles import check_vehicle_options, embedded_vehicles, split_urls
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.registry import flying_baselines

if TYPE_CHECKING:
    from uavlink.flight.mission import MissionConfig
    from uavlink.policies.base import Policy


def run_fly(args: argparse.Namespace) -> int:
    from uavlink.flight.link import VehicleLink
    from uavlink.flight.mission import MissionConfig, PolicyPilot, fly_mission
    from uavlink.mavlink.signing import load_key

    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    check_vehicle_options(args.seed, args.speed)
    key = load_key(args.signing_key) if args.signing_key else None  # before anything flies
    if args.connect is not None:
        split_urls(args.connect)  # every URL checked before anything else
    overrides = EnvOverrides.from_command_line(args.scenario, args.aoa_noise_deg, args.overrides)
    [(policy, cfg)] = load_with_env([args.policy], overrides)
    frames = cfg.episode_frames if args.frames is None else args.frames
    mission = MissionConfig(frames=frames).validate(cfg.episode_frames)
    if policy.needs_truth:
        privilege = getattr(policy, "privilege", "needs UE positions (GPS)")
        raise UserError(f"{policy.name} {privilege} and cannot fly; use a policy file or one of "
                        f"{', '.join(flying_baselines())}")
    if args.lockstep and args.connect is not None:
        raise UserError("--lockstep sets up the embedded SITL; a vehicle you connect to runs in "
                        "lockstep when started so (sitl-stub --lockstep), and `uavlink fly` answers "
                        "it either way")
    if cfg.n_uavs > 1:
        return run_fleet_fly(args, policy, cfg, key, mission)
    if args.connect and "," in args.connect:
        raise UserError("--connect with several URLs is for a fleet (a policy with n_uavs > 1, or "
                        "--set n_uavs=D); give one URL for one vehicle")
    pilot = PolicyPilot(policy, cfg)  # layout checks happen here, before anything is armed
    out_dir = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    tlog = out_dir / "flight.tlog"
    status = StatusLine(args, mission.frames)

    sitl = (embedded_vehicles(cfg, args.seed, args.speed, out_dir / "sitl.log",
                              Path(args.signing_key) if key else None, args.lockstep)
            if args.connect is None else contextlib.nullcontext([args.connect]))
    start = time.monotonic()
    with steady_heap(), sitl as [url]:  # frozen before the vehicle talks to us
        link = VehicleLink(url, tlog=tlog, signing_key=key)
        try:
            result = fly_mission(link, pilot, cfg, mission, status=status)
            speed = link.speed_factor()
        finally:
            link.close()
    status.end()
    summary = {
        **episode_fields(args, cfg, result.episode, mission.frames), "policy": str(args.policy),
        "connect": args.connect or "embedded sitl_stub", "speed_factor": round(speed, 2),
        **result.summary(), "wall_s": round(time.monotonic() - start, 2), "tlog": str(tlog),
        **link_fields(link),
    }
    return finish(summary, out_dir, args.json,
                  f"flew {summary['frames']} frames of {flown_name(summary)} with {args.policy}: "
                  f"mean UE throughput {summary['mean_rate_mbps']} Mbps; decision latency p50 "
                  f"{summary['latency_ms_p50']} ms, p99 {summary['latency_ms_p99']} ms; "
                  f"log {tlog}, summary {out_dir / 'summary.json'}",
                  picture=not args.no_picture)


def run_fleet_fly(args: argparse.Namespace, policy: Policy, cfg: EnvConfig, key: bytes | None,
                  mission: MissionConfig) -> int:
    """``run_fly`` for a fleet: the options checked there, one vehicle per UAV."""
    from uavlink.flight.fleet_mission import FleetPilot, fly_fleet
    from uavlink.flight.link.group import open_fleet_links

    pilot = FleetPilot(policy, cfg)  # layout checks before anything is armed
    urls: Sequence[str] | None = split_urls(args.connect) if args.connect else None
    out_dir = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    tlog = out_dir / "flight.tlog"
    sitl = (embedded_vehicles(cfg, args.seed, args.speed, out_dir / "sitl.log",
                              Path(args.signing_key) if key else None, args.lockstep)
            if urls is None else contextlib.nullcontext(urls))
    status = StatusLine(args, mission.frames)
    start = time.monotonic()
    with steady_heap(), sitl as vehicle_urls:  # frozen before the vehicles talk to us
        group, tlog_file = open_fleet_links(vehicle_urls, cfg.n_uavs, tlog, key)
        try:
            result = fly_fleet(group.links, pilot, cfg, mission, status=status)
            speed = group.links[0].speed_factor()
            fleet = result.fleet_summary(group.links)
        finally:
            group.close()
            if tlog_file:
                tlog_file.close()
    status.end()
    summary = {**episode_fields(args, cfg, result.episode, mission.frames), "policy": str(args.policy),
               "connect": args.connect or "embedded sitl_stub --fleet", "speed_factor": round(speed, 2),
               **fleet, "wall_s": round(time.monotonic() - start, 2), "tlog": str(tlog)}
    per = "; ".join(f"system {v['system_id']}: {v['decisions']} decisions, {v['holds']} holds"
                    for v in summary["vehicles"])
    return finish(summary, out_dir, args.json,
                  f"flew {summary['frames']} frames of {flown_name(summary)} with {args.policy} and "
                  f"{cfg.n_uavs} vehicles: mean UE throughput {summary['mean_rate_mbps']} Mbps; "
                  f"min separation flown {summary['min_separation_flown_m']} m; {per}; "
                  f"log {tlog}, summary {out_dir / 'summary.json'}",
                  picture=not args.no_picture)
