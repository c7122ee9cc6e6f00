"""What ``uavlink fly`` tells its user: the live status line while it flies; how it ends: the
episode it flew (and the command that replays it), what each link refused, the summary file, one
line for the user, and the exit status.

Exit status: 0 when the flight flew every frame it set out to (``completed: true`` in
summary.json); 1 when it did not (``completed: false`` and ``reason``: no radio reports, an
episode already running or over, a vehicle that never reached OFFBOARD, a lost link, an operator or
failsafe ending the flight), with one line on stderr that says what happened and what to do;
130 after Ctrl-C (the vehicle is told to land, the summary is written with ``completed: false``);
2 for bad input, before anything flies (``uavlink.errors.UserError``).
"""

from __future__ import annotations

import argparse
import json
import logging
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from uavlink.config import MIXED, EnvConfig
from uavlink.env.radio_world import episode_scenario
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID
from uavlink.plot.command import picture_after_flight

if TYPE_CHECKING:
    from uavlink.flight.mission import MissionResult

EXIT_COMPLETE, EXIT_INCOMPLETE, EXIT_INTERRUPTED = 0, 1, 130
log = logging.getLogger("uavlink.fly")


class StatusLine:
    """The live status line, one frame at a time, rewritten in place on stderr (the first UAV's
    target for a fleet); silent with --quiet or --json or when stderr is not a terminal."""

    def __init__(self, args: argparse.Namespace, frames: int) -> None:
        self.on = not (args.quiet or args.json) and sys.stderr.isatty()
        self.frames = frames

    def __call__(self, frame: int, target: np.ndarray, rate: float | None) -> None:
        if self.on:
            rate_text = f"{rate:5.2f} Mbps" if rate is not None else "  --- Mbps"
            print(f"\rframe {frame + 1:4d}/{self.frames}  target E {target[0]:7.1f} N {target[1]:7.1f} m  "
                  f"{rate_text}", end="", file=sys.stderr, flush=True)

    def end(self) -> None:
        if self.on:
            print(file=sys.stderr)


def link_fields(link) -> dict:
    """What a closed link refused, for the summary: signing's counts (None on an unsigned link) and
    unusable telemetry by kind; refused signed packets are also logged as a warning."""
    if link.signing is not None and link.signing.rejected_total:
        log.warning("signing: refused %d packets from system %s's side (%s)", link.signing.rejected_total,
                    link.target_system, link.signing.stats())
    return {"signing": link.signing.stats() if link.signing else None, "link_rejected": link.rejects.as_dict()}


class EndedBy:
    """Why a flight's loop ended: ``MissionResult.ended_by``, summary.json's ``ended_by``. Plain
    strings (not an Enum: Python 3.12 formats a str Enum by its name); an operator or failsafe
    ending it is ``vehicle in MODE``, whatever the mode."""

    EPISODE_DONE = "episode done"
    NO_RADIO_REPORTS = "no radio reports"
    LINK_LOST = "link lost"
    INTERRUPTED = "interrupted"
    EVERY_VEHICLE_RELEASED = "every vehicle released"  # a fleet's: every vehicle taken over


def judge(result: MissionResult, frames: int) -> None:
    """Set ``completed`` and ``reason``: did the flight fly the frames it set out to (all
    ``frames`` of a fresh episode, or the rest of the one it resumed)?"""
    first, last = result.first_frame, result.last_frame
    if result.interrupted:
        why = "interrupted (Ctrl-C); the vehicle was told to land"
    elif result.failure:
        fix = result.fix or "check the vehicle is running and reachable (--connect)"
        why = f"{result.failure}; {fix}, then fly again"
    elif result.ended_by == EndedBy.NO_RADIO_REPORTS or first is None:
        where = "no" if first is None else f"no more (after frame {last})"
        why = (f"{where} radio reports from the vehicle's radio payload (component "
               f"{RADIO_COMPONENT_ID}) in OFFBOARD: run the vehicle with its radio payload (sitl_stub "
               "without --no-payload) and fly again")
    elif first >= frames:
        why = (f"the vehicle's radio episode was already at frame {first}, past the {frames} frames "
               "to fly: restart the vehicle (a current sitl_stub begins an episode per arming)")
    elif not result.resumed and not result.met_start:
        why = (f"the vehicle's radio episode was already running (frame {first}) before this flight "
               "took off, so its start was not flown: restart the vehicle and fly again")
    elif result.ended_by != EndedBy.EPISODE_DONE:
        why = (f"the flight ended early, after frame {last}: {result.ended_by} (operator or "
               "failsafe); see the vehicle's log, then fly again")
    else:
        why = ""
    result.completed, result.reason = not why, why


def signing_hint(link) -> str:
    """What to do when a flight failed on a link whose signing disagrees with the vehicle's, or "":
    without a key of ours, the vehicle's packets arrived signed (``unsigned_to_a_signing_vehicle``:
    the vehicle heard fine, then dropped our unsigned commands); with one, nothing of the vehicle's
    was accepted and its packets were unsigned or signed with another key."""
    if link.unsigned_to_a_signing_vehicle:
        return "the vehicle signs its link: pass --signing-key FILE (its key)"
    guard = link.signing
    if guard is None or guard.accepted:
        return ""
    if guard.rejected["bad_signature"]:
        return "the vehicle signs its link with another key: pass the key it was started with"
    if guard.rejected["unsigned"]:
        return ("the vehicle does not sign its link: start it with the same --signing-key, or fly "
                "without one")
    return ""


def episode_fields(args: argparse.Namespace, cfg: EnvConfig, episode: dict[str, int], frames: int) -> dict:
    """Which radio episode was flown, its scenario and how to replay it: the vehicle's payload names
    it (its UL_EP_SEED / UL_EPISODE messages); an embedded vehicle serves episode 0 of ``--seed``.
    ``mixed`` draws the episode's scenario from its seed, as the replay's evaluation does: the
    summary names the one flown. A lockstep flight of one UAV is replayed with the vehicle's
    motion (``uav_motion=px4``); a flight of the first ``frames`` of the episode, with an episode that
    long (none for a policy that plans over the episode's length: the model of the field's)."""
    seed = episode.get("seed", args.seed if args.connect is None else None)
    scenario = {"scenario": cfg.scenario}
    if cfg.scenario == MIXED and seed is not None:
        scenario = {"scenario": episode_scenario(cfg, seed), "scenario_drawn_from": MIXED}
    replay = None
    short = frames < cfg.episode_frames
    if seed is not None and not (short and cfg.place_model == "kriging"):
        words = ["uavlink", "evaluate", "--policy", str(args.policy), "--scenario", cfg.scenario,
                 "--seed", str(seed), "--episodes", "1"]
        if args.aoa_noise_deg is not None:
            words += ["--aoa-noise-deg", repr(float(args.aoa_noise_deg))]
        for pair in args.overrides:
            words += ["--set", pair]
        if args.lockstep and cfg.n_uavs == 1 and cfg.uav_motion != "px4":
            words += ["--set", "uav_motion=px4"]
        if short:  # the episode's first frames are the same in a shorter episode
            words += ["--set", f"episode_frames={frames}"]
        replay = shlex.join(words)
    return {**scenario, "seed": seed,
            "episode": {"seed": seed, "index": 0, "on_vehicle": episode.get("count")}, "replay": replay}


def flown_name(summary: dict) -> str:
    """The scenario flown, for the line after a flight: ``'hotspot' (drawn from mixed)``."""
    drawn = summary.get("scenario_drawn_from")
    return repr(summary["scenario"]) + (f" (drawn from {drawn})" if drawn else "")


def finish(summary: dict, out_dir: Path, as_json: bool, flown_line: str, picture: bool = True) -> int:
    """Draw flight.png from the flight's tlog (unless ``picture`` is off; complete or not), write
    summary.json and print the summary (``--json``); then ``flown_line`` (stdout) for a complete
    flight, one line on stderr for one that is not; then why there is no picture, if there is none
    (after: the flight's own outcome is the first thing to read). Returns the exit status."""
    if picture:
        summary.update(picture_after_flight(Path(summary["tlog"]), out_dir / "flight.png"))
        flown_line += f", picture {summary['picture']}" if summary.get("picture") else ""
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if as_json:
        print(json.dumps(summary, indent=2))
    if summary["completed"]:
        if not as_json:
            print(flown_line)
        status = EXIT_COMPLETE
    else:
        print(f"uavlink fly: flight incomplete ({summary['decisions']} decisions, {summary['frames']} "
              f"scored frames): {summary['reason']}", file=sys.stderr)
        status = EXIT_INTERRUPTED if summary["interrupted"] else EXIT_INCOMPLETE
    if summary.get("picture_skipped"):
        print(f"uavlink fly: no flight picture: {summary['picture_skipped']}", file=sys.stderr)
    return status
