"""The ``uavlink fly`` command: a policy, its vehicle(s) (``uavlink.flight.vehicles``: the embedded
SITL or ``--connect``) and the loop that flies one vehicle (``loop``) or a fleet, the policy's env
having ``n_uavs`` > 1 (``fleet_loop``); then the summary and the picture (``result``)."""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from collections.abc import Sequence
from pathlib import Path

from uavlink.config import EnvConfig
from uavlink.errors import UserError
from uavlink.flight.fleet_loop import FleetPilot, fly_fleet
from uavlink.flight.link import VehicleLink
from uavlink.flight.link.group import open_fleet_links
from uavlink.flight.loop import LoopConfig, PolicyPilot, fly_vehicle
from uavlink.flight.result import StatusLine, episode_fields, finish, flown_name, link_fields
from uavlink.flight.steady import steady_heap
from uavlink.flight.vehicles import check_vehicle_options, embedded_vehicles, split_urls
from uavlink.mavlink.signing import load_key
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.registry import flying_baselines


def run_fly(args: argparse.Namespace) -> int:
    """``uavlink fly``: every option checked, then one episode flown with one vehicle, or a fleet
    when the policy's env has ``n_uavs`` > 1; its exit status (``result``)."""
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    check_vehicle_options(args.seed, args.speed)
    key = load_key(args.signing_key) if args.signing_key else None  # before anything flies
    urls = (
        None if args.connect is None else split_urls(args.connect)
    )  # checked before anything else
    overrides = EnvOverrides.from_command_line(args.scenario, args.aoa_noise_deg, args.overrides)
    [(policy, cfg)] = load_with_env([args.policy], overrides)
    frames = cfg.episode_frames if args.frames is None else args.frames
    loop_cfg = LoopConfig(frames=frames).validate(cfg.episode_frames)
    if policy.needs_truth:
        privilege = getattr(policy, "privilege", "needs UE positions (GPS)")
        raise UserError(
            f"{policy.name} {privilege} and cannot fly; use a policy file or one of "
            f"{', '.join(flying_baselines())}"
        )
    if args.lockstep and args.connect is not None:
        raise UserError(
            "--lockstep sets up the embedded SITL; a vehicle you connect to runs in "
            "lockstep when started so (sitl-stub --lockstep), and `uavlink fly` answers "
            "it either way"
        )
    fleet = cfg.n_uavs > 1
    if not fleet and urls is not None and len(urls) > 1:
        raise UserError(
            "--connect with several URLs is for a fleet (a policy with n_uavs > 1, or "
            "--set n_uavs=D); give one URL for one vehicle"
        )
    pilot = (FleetPilot if fleet else PolicyPilot)(
        policy, cfg
    )  # layout checks, before anything is armed
    out_dir = args.out
    out_dir.mkdir(parents=True, exist_ok=True)
    tlog = out_dir / "flight.tlog"
    sitl = (
        embedded_vehicles(
            cfg,
            args.seed,
            args.speed,
            out_dir / "sitl.log",
            Path(args.signing_key) if key else None,
            args.lockstep,
        )
        if urls is None
        else contextlib.nullcontext(urls)
    )
    status = StatusLine(args, loop_cfg.frames)
    start = time.monotonic()
    with steady_heap(), sitl as urls:  # frozen before the vehicles talk to us
        if isinstance(pilot, FleetPilot):  # fleet: built above
            flown = _fly_fleet(urls, tlog, key, pilot, cfg, loop_cfg, status)
        else:
            flown = _fly_one(urls, tlog, key, pilot, cfg, loop_cfg, status)
    status.end()
    summary = {
        **episode_fields(args, cfg, flown.pop("episode"), loop_cfg.frames),
        "policy": str(args.policy),
        "connect": args.connect or "embedded sitl_stub" + (" --fleet" if fleet else ""),
        **flown,
        "wall_s": round(time.monotonic() - start, 2),
        "tlog": str(tlog),
    }
    if fleet:
        per = "; ".join(
            f"system {v['system_id']}: {v['decisions']} decisions, {v['holds']} holds"
            for v in summary["vehicles"]
        )
        how = (
            f" and {cfg.n_uavs} vehicles: mean UE throughput {summary['mean_rate_mbps']} Mbps; min "
            f"separation flown {summary['min_separation_flown_m']} m; {per}"
        )
    else:
        how = (
            f": mean UE throughput {summary['mean_rate_mbps']} Mbps; decision latency p50 "
            f"{summary['latency_ms_p50']} ms, p99 {summary['latency_ms_p99']} ms"
        )
    return finish(
        summary,
        out_dir,
        args.json,
        f"flew {summary['frames']} frames of {flown_name(summary)} with {args.policy}{how}; "
        f"log {tlog}, summary {out_dir / 'summary.json'}",
        picture=not args.no_picture,
    )


def _fly_one(
    urls: Sequence[str],
    tlog: Path,
    key: bytes | None,
    pilot: PolicyPilot,
    cfg: EnvConfig,
    loop_cfg: LoopConfig,
    status: StatusLine,
) -> dict:
    """One vehicle's flight; the summary's part of it (``episode``: what the payload said it flew)."""
    [url] = urls
    link = VehicleLink(url, tlog=tlog, signing_key=key)
    try:
        result = fly_vehicle(link, pilot, cfg, loop_cfg, status=status)
        speed = link.speed_factor()
    finally:
        link.close()
    return {
        "episode": result.episode,
        "speed_factor": round(speed, 2),
        **result.summary(),
        **link_fields(link),
    }


def _fly_fleet(
    urls: Sequence[str],
    tlog: Path,
    key: bytes | None,
    pilot: FleetPilot,
    cfg: EnvConfig,
    loop_cfg: LoopConfig,
    status: StatusLine,
) -> dict:
    """A fleet's flight, one vehicle per UAV; the summary's part of it, as ``_fly_one``'s."""
    group, tlog_file = open_fleet_links(urls, cfg.n_uavs, tlog, key)
    try:
        result = fly_fleet(group.links, pilot, cfg, loop_cfg, status=status)
        speed = group.links[0].speed_factor()
        fleet = result.fleet_summary(group.links)
    finally:
        group.close()
        if tlog_file:
            tlog_file.close()
    return {"episode": result.episode, "speed_factor": round(speed, 2), **fleet}
