"""Flying a policy: :func:`fly_policy` flies one episode from Python and returns the flight's
summary; :func:`run_fly` is the ``uavlink fly`` command around it (prints, exit status). Both take
:class:`FlyOptions`. A flight is a policy, its vehicle(s) (``uavlink.flight.vehicles``: the embedded
SITL or ``connect``) and the loop that flies one vehicle (``loop``) or a fleet, the policy's env
having ``n_uavs`` > 1 (``fleet_loop``); then the summary and the picture (``result``).

    from uavlink.flight import FlyOptions, fly_policy

    summary = fly_policy(FlyOptions(policy="circular", frames=8, out=Path("runs/demo")))
    assert summary["completed"], summary["reason"]
"""

from __future__ import annotations

import contextlib
import logging
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from uavlink.config import EnvConfig
from uavlink.errors import UserError
from uavlink.flight import EMBEDDED_SPEED
from uavlink.flight.fleet_loop import FleetPilot, fly_fleet
from uavlink.flight.link import VehicleLink
from uavlink.flight.link.group import open_fleet_links
from uavlink.flight.loop import LoopConfig, PolicyPilot, fly_vehicle
from uavlink.flight.result import (
    FrameStatusLine,
    episode_fields,
    flown_line,
    link_fields,
    record,
    report,
)
from uavlink.flight.steady import steady_heap
from uavlink.flight.vehicles import (
    check_vehicle_options,
    embedded_lockstep,
    embedded_vehicles,
    split_urls,
)
from uavlink.mavlink.signing import load_key
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.loader import locate, shipped_note
from uavlink.policies.registry import flying_baselines


@dataclass(frozen=True)
class FlyOptions:
    """What a flight flies, against which vehicle, and where its outputs go (``uavlink fly``'s
    options; ``uavlink fly --help`` says each one's meaning at length)."""

    policy: str = "circular"  # a file, a baseline that flies, or a shipped policy's name
    connect: str | None = None  # vehicle URL(s); None: an embedded sitl_stub
    scenario: str | None = None  # default: the policy's own
    seed: int = 0  # the embedded vehicle's radio episode
    aoa_noise_deg: float | None = None
    overrides: tuple[str, ...] = field(default_factory=tuple)  # KEY=VALUE, as --set
    # The embedded vehicle's simulated seconds per wall second (None: EMBEDDED_SPEED); a vehicle
    # you connect to runs at the speed it was started with.
    speed: float | None = None
    lockstep: bool = False
    frames: int | None = None  # default: the env's episode
    out: Path = Path("runs/fly")  # flight.tlog, summary.json, flight.png, sitl.log
    picture: bool = True
    signing_key: Path | None = None
    verbose: bool = False

    def validate(self) -> FlyOptions:
        """UserError for what no flight can take, before anything starts or is written."""
        check_vehicle_options(self.seed, self.embedded_speed)
        if self.speed is not None and self.connect is not None:
            raise UserError(
                "--speed sets the embedded SITL's clock; a vehicle you connect to runs at the "
                "speed it was started with (sitl-stub --speed)"
            )
        if self.lockstep and self.connect is not None:
            raise UserError(
                "--lockstep sets up the embedded SITL; a vehicle you connect to runs in "
                "lockstep when started so (sitl-stub --lockstep), and `uavlink fly` answers "
                "it either way"
            )
        return self

    @property
    def embedded_speed(self) -> float:
        """The embedded vehicle's speed: ``speed``, or EMBEDDED_SPEED when not given."""
        return EMBEDDED_SPEED if self.speed is None else self.speed


def fly_policy(options: FlyOptions, live_status: bool = False) -> dict[str, Any]:
    """Fly one episode (or ``options.frames`` of it) with one vehicle, or a fleet when the policy's
    env has ``n_uavs`` > 1; write flight.tlog, summary.json and flight.png into ``options.out`` and
    return the summary (``completed`` and, when false, ``reason``). ``live_status``: the status line
    on stderr. Raises UserError (before anything flies) for bad options."""
    options.validate()
    logging.basicConfig(
        level=logging.INFO if options.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    key = load_key(options.signing_key) if options.signing_key else None  # before anything flies
    urls = None if options.connect is None else split_urls(options.connect)
    policy_path = str(locate(options.policy))
    overrides = EnvOverrides.from_command_line(
        options.scenario, options.aoa_noise_deg, list(options.overrides)
    )
    [(policy, cfg)] = load_with_env([policy_path], overrides)
    frames = cfg.episode_frames if options.frames is None else options.frames
    loop_cfg = LoopConfig(frames=frames).validate(cfg.episode_frames)
    if policy.needs_truth:
        privilege = getattr(policy, "privilege", "needs UE positions (GPS)")
        raise UserError(
            f"{policy.name} {privilege} and cannot fly; use a policy file or one of "
            f"{', '.join(flying_baselines())}"
        )
    fleet = cfg.n_uavs > 1
    if not fleet and urls is not None and len(urls) > 1:
        raise UserError(
            "--connect with several URLs is for a fleet (a policy with n_uavs > 1, or "
            "--set n_uavs=D); give one URL for one vehicle"
        )
    # the pilot checks the layouts, before anything is armed
    pilot = (FleetPilot if fleet else PolicyPilot)(policy, cfg)
    note = shipped_note([options.policy], [policy_path])  # every input checked: say it now
    if note:
        print(note, file=sys.stderr)
    out_dir = options.out
    out_dir.mkdir(parents=True, exist_ok=True)
    tlog = out_dir / "flight.tlog"
    embedded = urls is None
    sitl = (
        embedded_vehicles(
            cfg,
            options.seed,
            options.embedded_speed,
            out_dir / "sitl.log",
            options.signing_key if key else None,
            options.lockstep,
        )
        if urls is None
        else contextlib.nullcontext(urls)
    )
    status = FrameStatusLine(live_status, loop_cfg.frames)
    start = time.monotonic()
    with steady_heap(), sitl as urls:  # frozen before the vehicles talk to us
        if isinstance(pilot, FleetPilot):  # fleet: built above
            flown = _fly_fleet(urls, tlog, key, pilot, cfg, loop_cfg, status)
        else:
            flown = _fly_one(urls, tlog, key, pilot, cfg, loop_cfg, status)
    status.end()
    summary = {
        **episode_fields(options, policy_path, cfg, flown.pop("episode"), loop_cfg.frames),
        "policy": policy_path,
        "connect": options.connect or "embedded sitl_stub" + (" --fleet" if fleet else ""),
        **(embedded_lockstep(out_dir / "sitl.log") if embedded and options.lockstep else {}),
        **flown,
        "wall_s": round(time.monotonic() - start, 2),
        "tlog": str(tlog),
    }
    return record(summary, out_dir, picture=options.picture)


def run_fly(options: FlyOptions, as_json: bool = False, quiet: bool = False) -> int:
    """``uavlink fly``: the flight, then its summary (``as_json``) or one line; its exit status
    (``result``): 0 complete, 1 incomplete, 130 interrupted."""
    live = not (quiet or as_json) and sys.stderr.isatty()
    summary = fly_policy(options, live_status=live)
    return report(summary, as_json, flown_line(summary, options.out))


def _fly_one(
    urls: Sequence[str],
    tlog: Path,
    key: bytes | None,
    pilot: PolicyPilot,
    cfg: EnvConfig,
    loop_cfg: LoopConfig,
    status: FrameStatusLine,
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
    status: FrameStatusLine,
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
