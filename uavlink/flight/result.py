"""A flight's result (:class:`FlightResult`, :class:`FleetResult`: what the flight loops fill in)
and what ``uavlink fly`` tells its user: the live status line while it flies; how it ends: the
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

import json
import logging
import math
import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from uavlink.config import MIXED, EnvConfig
from uavlink.config.env import FIELD_MODELS, MOTION_PX4
from uavlink.env.radio_world import episode_scenario
from uavlink.flight.link import VehicleLink
from uavlink.flight.vehicle_control import mode_name
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID, ScoreReport
from uavlink.plot.command import picture_after_flight

EXIT_COMPLETE, EXIT_INCOMPLETE, EXIT_INTERRUPTED = 0, 1, 130
log = logging.getLogger("uavlink.fly")


class FlownOptions(Protocol):
    """What the summary reads of a flight's options (``fly.FlyOptions``) to name its replay."""

    @property
    def seed(self) -> int: ...
    @property
    def connect(self) -> str | None: ...
    @property
    def aoa_noise_deg(self) -> float | None: ...
    @property
    def overrides(self) -> Sequence[str]: ...
    @property
    def lockstep(self) -> bool: ...


class Piloting(Protocol):
    """What a flight's result reads of its pilot at the end (``loop.PolicyPilot``)."""

    guarded: int
    inference_s: list[float]


@dataclass
class FlightResult:
    frames: int = 0
    frame_rates_mbps: list[float] = field(default_factory=list)
    latencies_s: list[float] = field(default_factory=list)
    guarded_actions: int = 0
    rejected_reports: int = 0
    resumed: bool = False
    episode_wall_s: float = 0.0
    interrupted: bool = False
    first_frame: int | None = None
    last_frame: int | None = None  # the newest frame taken
    decisions: int = 0
    # Frames between decisions that went undecided, one UAV or a fleet: their reports lost, or
    # late (stale_reports, which the loop still puts into the policy's memory; a fleet's, when
    # every vehicle's report of the frame came).
    frames_missed: int = 0
    # a fleet's: frames gone by before its first decision, which needs every vehicle's report
    frames_before_first_decision: int = 0
    stale_reports: int = 0
    offboard_reentries: int = 0
    ended_by: str = ""
    met_start: bool = False  # the radio episode was still waiting for OFFBOARD after take-off
    episode: dict[str, int] = field(default_factory=dict)  # the payload's: seed, count
    failure: str = ""  # the LinkError that ended the flight
    fix: str = ""  # what to do about the failure, when known (else: check the vehicle is running)
    completed: bool = False
    reason: str = ""  # why not completed: what happened, what to do

    inference_s: list[float] = field(default_factory=list)

    def take_scores(
        self,
        scores: dict[int, ScoreReport],
        frames: int,
        pilot: Piloting,
        rejected: int,
    ) -> None:
        """The flight's figures at its end: the payload's score of each frame 1..``frames`` it sent,
        and what the pilot guarded and spent."""
        self.frame_rates_mbps = [
            scores[k].mean_rate_mbps for k in sorted(scores) if 1 <= k <= frames
        ]
        self.frames = len(self.frame_rates_mbps)
        self.guarded_actions, self.inference_s = pilot.guarded, pilot.inference_s
        self.rejected_reports = rejected

    def summary(self) -> dict:
        lat_ms = np.array(self.latencies_s) * 1e3 if self.latencies_s else np.array([np.nan])
        inf_us = np.array(self.inference_s) * 1e6 if self.inference_s else np.array([np.nan])
        return {
            "frames": self.frames,
            "mean_rate_mbps": round(float(np.mean(self.frame_rates_mbps)), 6)
            if self.frame_rates_mbps
            else None,
            "latency_ms_p50": round(float(np.percentile(lat_ms, 50)), 4),
            "latency_ms_p99": round(float(np.percentile(lat_ms, 99)), 4),
            "inference_us_p50": round(float(np.percentile(inf_us, 50)), 2),
            "inference_us_p99": round(float(np.percentile(inf_us, 99)), 2),
            "episode_wall_s": round(self.episode_wall_s, 3),
            "guarded_actions": self.guarded_actions,
            "rejected_radio_reports": self.rejected_reports,
            "resumed_in_air": self.resumed,
            "interrupted": self.interrupted,
            "first_frame": self.first_frame,
            "decisions": self.decisions,
            "radio_frames_missed": self.frames_missed,
            "frames_before_first_decision": self.frames_before_first_decision,
            "stale_radio_reports": self.stale_reports,
            "offboard_reentries": self.offboard_reentries,
            "ended_by": self.ended_by,
            "completed": self.completed,
            "reason": self.reason or None,
        }


@dataclass
class VehicleRecord:
    """One vehicle's part of the flight, for the summary."""

    system_id: int | None
    decisions: int = 0
    holds: int = 0  # times it left OFFBOARD during the episode (a failsafe hold, say)
    offboard_reentries: int = 0
    released: str = ""  # why the loop stopped commanding it ("" while it flies)
    max_silence_s: float = 0.0

    def summary(self, link: VehicleLink) -> dict:
        st = link.status
        return {
            "system_id": self.system_id,
            "url": link.url,
            "decisions": self.decisions,
            "holds": self.holds,
            "offboard_reentries": self.offboard_reentries,
            "max_link_silence_s": round(self.max_silence_s, 2),
            "mode": mode_name(st),
            "released": self.released or None,
            "last_position_en_m": [round(st.east_m, 2), round(st.north_m, 2)],
            **link_fields(link),
        }


@dataclass
class FleetResult(FlightResult):
    vehicles: list[VehicleRecord] = field(default_factory=list)
    min_separation_flown_m: float = math.inf
    setpoint_min_separation_m: float = math.inf

    def fleet_summary(self, links: Sequence[VehicleLink]) -> dict:
        vehicles = self.vehicles or [VehicleRecord(link.target_system) for link in links]
        return {
            **self.summary(),
            "n_uavs": len(links),
            "min_separation_flown_m": round(self.min_separation_flown_m, 5),
            "min_separation_setpoints_m": round(self.setpoint_min_separation_m, 2),
            "vehicles": [v.summary(link) for v, link in zip(vehicles, links, strict=True)],
        }


class FrameStatusLine:
    """The live status line, one frame at a time, rewritten in place on stderr (the first UAV's
    target for a fleet); silent with --quiet or --json or when stderr is not a terminal."""

    def __init__(self, on: bool, frames: int) -> None:
        self.on, self.frames = on, frames

    def __call__(self, frame: int, target: np.ndarray, rate: float | None) -> None:
        if self.on:
            rate_text = f"{rate:5.2f} Mbps" if rate is not None else "  --- Mbps"
            print(
                f"\rframe {frame + 1:4d}/{self.frames}  target E {target[0]:7.1f} N {target[1]:7.1f} m  "
                f"{rate_text}",
                end="",
                file=sys.stderr,
                flush=True,
            )

    def end(self) -> None:
        if self.on:
            print(file=sys.stderr)


def link_fields(link) -> dict:
    """What a closed link refused, for the summary: signing's counts (None on an unsigned link) and
    unusable telemetry by kind; refused signed packets are also logged as a warning."""
    if link.signing is not None and link.signing.rejected_total:
        side = (  # no heartbeat accepted: the vehicle was never told apart
            "the vehicle's side"
            if link.target_system is None
            else f"system {link.target_system}'s side"
        )
        log.warning(
            "signing: refused %d packets from %s (%s)",
            link.signing.rejected_total,
            side,
            link.signing.stats(),
        )
    return {
        "signing": link.signing.stats() if link.signing else None,
        "link_rejected": link.rejects.as_dict(),
    }


class EndedBy:
    """Why a flight's loop ended: ``FlightResult.ended_by``, summary.json's ``ended_by``. Plain
    strings (not an Enum: Python 3.12 formats a str Enum by its name); an operator or failsafe
    ending it is ``vehicle in MODE``, whatever the mode."""

    EPISODE_DONE = "episode done"
    NO_RADIO_REPORTS = "no radio reports"
    LINK_LOST = "link lost"
    INTERRUPTED = "interrupted"
    EVERY_VEHICLE_RELEASED = "every vehicle released"  # a fleet's: every vehicle taken over


def judge(result: FlightResult, frames: int) -> None:
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
        why = (
            f"{where} radio reports from the vehicle's radio payload (component "
            f"{RADIO_COMPONENT_ID}) in OFFBOARD: run the vehicle with its radio payload (sitl_stub "
            "without --no-payload) and fly again"
        )
    elif first >= frames:
        why = (
            f"the vehicle's radio episode was already at frame {first}, past the {frames} frames "
            "to fly: restart the vehicle (a current sitl_stub begins an episode per arming)"
        )
    elif not result.resumed and not result.met_start:
        why = (
            f"the vehicle's radio episode was already running (frame {first}) before this flight "
            "took off, so its start was not flown: restart the vehicle and fly again"
        )
    elif result.ended_by != EndedBy.EPISODE_DONE:
        why = (
            f"the flight ended early, after frame {last}: {result.ended_by} (operator or "
            "failsafe); see the vehicle's log, then fly again"
        )
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
        return (
            "the vehicle does not sign its link: start it with the same --signing-key, or fly "
            "without one"
        )
    return ""


def episode_fields(
    options: FlownOptions, policy: str, cfg: EnvConfig, episode: dict[str, int], frames: int
) -> dict:
    """Which radio episode was flown, its scenario and how to replay it: the vehicle's payload names
    it (its UL_EP_SEED / UL_EPISODE messages); an embedded vehicle serves episode 0 of ``--seed``.
    ``mixed`` draws the episode's scenario from its seed, as the replay's evaluation does: the
    summary names the one flown. A lockstep flight (one UAV or a fleet) is replayed with the
    vehicles' motion (``uav_motion=px4``); a flight of the first ``frames`` of the episode, with an
    episode that long (none for a policy that plans over the episode's length: the model of the
    field's)."""
    seed = episode.get("seed", options.seed if options.connect is None else None)
    scenario = {"scenario": cfg.scenario}
    if cfg.scenario == MIXED and seed is not None:
        scenario = {"scenario": episode_scenario(cfg, seed), "scenario_drawn_from": MIXED}
    replay = None
    short = frames < cfg.episode_frames
    if seed is not None and not (short and cfg.place_model in FIELD_MODELS):
        words = [
            "uavlink",
            "evaluate",
            "--policy",
            policy,
            "--scenario",
            cfg.scenario,
            "--seed",
            str(seed),
            "--episodes",
            "1",
        ]
        if options.aoa_noise_deg is not None:
            words += ["--aoa-noise-deg", repr(float(options.aoa_noise_deg))]
        for pair in options.overrides:
            words += ["--set", pair]
        if options.lockstep and cfg.uav_motion != MOTION_PX4:
            words += ["--set", "uav_motion=px4"]
        if short:  # the episode's first frames are the same in a shorter episode
            words += ["--set", f"episode_frames={frames}"]
        replay = shlex.join(words)
    if replay is not None:
        why = None
    elif seed is None:
        why = "the vehicle did not name its radio episode (no UL_EP_SEED)"
    else:  # a model of the field plans over the episode's length: a shorter one decides otherwise
        why = (
            f"a policy with a model of the field plans over the whole episode, so its first {frames} "
            f"frames of {cfg.episode_frames} differ from an episode of {frames}; fly all "
            f"{cfg.episode_frames} to replay it"
        )
    return {
        **scenario,
        "seed": seed,
        "episode": {"seed": seed, "index": 0, "on_vehicle": episode.get("count")},
        "replay": replay,
        "no_replay_because": why,
    }


def flown_name(summary: dict) -> str:
    """The scenario flown, for the line after a flight: ``'hotspot' (drawn from mixed)``."""
    drawn = summary.get("scenario_drawn_from")
    return repr(summary["scenario"]) + (f" (drawn from {drawn})" if drawn else "")


def _count(n: int, noun: str) -> str:
    """``1 decision``, ``3 decisions``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def flown_line(summary: dict, out_dir: Path) -> str:
    """The line after a complete flight: what was flown, how well, where its files are."""
    if "vehicles" in summary:  # a fleet
        per = "; ".join(
            f"system {v['system_id']}: {_count(v['decisions'], 'decision')}, "
            f"{_count(v['holds'], 'hold')}"
            for v in summary["vehicles"]
        )
        how = (
            f" and {summary['n_uavs']} vehicles: mean UE throughput {summary['mean_rate_mbps']} "
            f"Mbps; min separation flown {summary['min_separation_flown_m']} m; {per}"
        )
    else:
        how = (
            f": mean UE throughput {summary['mean_rate_mbps']} Mbps; decision latency p50 "
            f"{summary['latency_ms_p50']} ms, p99 {summary['latency_ms_p99']} ms"
        )
    missed, before = summary.get("radio_frames_missed"), summary.get("frames_before_first_decision")
    if before:  # the figures are over the frames flown; say how many of them went undecided
        how += f"; the first {_count(before, 'frame')} went by before the first decision"
    if missed:
        how += (
            f"; {_count(missed, 'frame')} went by without a decision (the radio reports came "
            f"late or not at all)"
        )
    late = summary.get("lockstep_timeouts")
    if late:  # the replay no longer matches: say so where the figures are
        how += (
            f"; {late} frame(s) went on without a decision (a busy machine): the flight no longer "
            f"replays as its evaluation"
        )
    held = summary.get("offboard_reentries", 0)
    if held and str(summary.get("connect", "")).startswith("embedded"):
        # an embedded vehicle runs faster than real time: its offboard-loss timeout (COM_OF_LOSS_T,
        # 1 s of its time) is 1/speed s of ours, and a slow machine's decisions outlast it
        how += (
            f"; the vehicle(s) fell back to hold {held} time(s) waiting for setpoints (decision "
            f"latency p99 {summary['latency_ms_p99']} ms; at {summary['speed_factor']:g}x a "
            f"vehicle waits {1000 / summary['speed_factor']:.0f} ms): fly slower (--speed 5) or "
            f"in --lockstep"
        )
    line = (
        f"flew {summary['frames']} frames of {flown_name(summary)} with {summary['policy']}{how}; "
        f"log {summary['tlog']}, summary {out_dir / 'summary.json'}"
    )
    return line + (f", picture {summary['picture']}" if summary.get("picture") else "")


def record(summary: dict, out_dir: Path, picture: bool = True) -> dict:
    """Draw flight.png from the flight's tlog (unless ``picture`` is off; complete or not) and
    write summary.json; the summary, with the picture's fields."""
    if picture:
        summary.update(picture_after_flight(Path(summary["tlog"]), out_dir / "flight.png"))
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def report(summary: dict, as_json: bool, line: str) -> int:
    """Print the summary (``as_json``), then ``line`` (stdout) for a complete flight, one line on
    stderr for one that is not; then why there is no picture, if there is none (after: the flight's
    own outcome is the first thing to read). Returns the exit status."""
    if as_json:
        print(json.dumps(summary, indent=2))
    if summary["completed"]:
        if not as_json:
            print(line)
        status = EXIT_COMPLETE
    else:
        print(
            f"uavlink fly: flight incomplete ({summary['decisions']} decisions, {summary['frames']} "
            f"scored frames): {summary['reason']}",
            file=sys.stderr,
        )
        status = EXIT_INTERRUPTED if summary["interrupted"] else EXIT_INCOMPLETE
    if summary.get("picture_skipped"):
        print(f"uavlink fly: no flight picture: {summary['picture_skipped']}", file=sys.stderr)
    return status
