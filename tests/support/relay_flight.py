"""Flights through the test relay: ``uavlink fly`` (a child process) against ``python -m sitl_stub``
(another) through a :class:`~udp_relay.UdpRelay` with given faults, and the table of results.

:func:`fly_through_relay` returns fly's summary, the vehicle's exit stats (its own truth of the
episode's throughput, whatever the link lost, and its safety monitors) and the relay's counts;
:func:`table_row` and :func:`format_table` make the fault table of ``research/link_faults.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from support.mavlink_gcs import FAST_TAKEOFF, parse_vehicle_stats
from support.udp_relay import Faults, UdpRelay

ROOT = Path(__file__).resolve().parents[2]


class ModeWatch:
    """A relay tap that decodes the vehicle's side (direction 'up') and records (wall time,
    custom_mode, armed) whenever the heartbeat changes, and the radio payload's frame numbers."""

    def __init__(self) -> None:
        from uavlink.mavlink.dialect import mavlink as common

        self._mav = common.MAVLink(None)
        self._mav.robust_parsing = True
        self.changes: list[tuple[float, int, bool]] = []
        self.frames: list[tuple[float, int]] = []

    def __call__(self, direction: str, data: bytes) -> None:
        if direction != "up":
            return
        try:
            msgs = self._mav.parse_buffer(data) or []
        except Exception:
            return
        for m in msgs:
            if m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1:
                armed = bool(m.base_mode & 128)
                if not self.changes or self.changes[-1][1:] != (m.custom_mode, armed):
                    self.changes.append((time.monotonic(), m.custom_mode, armed))
            elif m.get_type() == "DEBUG_FLOAT_ARRAY" and "UL_RADIO" in str(m.name):
                self.frames.append((time.monotonic(), int(m.array_id)))

    def first(self, custom_mode: int, after: float = 0.0) -> float | None:
        return next((t for t, mode, _ in self.changes if mode == custom_mode and t >= after), None)

    def frame_at(self, t: float) -> int:
        """The last radio frame the vehicle had sent by wall time ``t``."""
        return max((f for tf, f in self.frames if tf <= t), default=0)


def fly_through_relay(
    faults: Faults,
    *,
    policy: str = "aoa",
    scenario: str = "straight",
    seed: int = 0,
    frames: int = 128,
    speed: float = 20.0,
    relay_seed: int = 0,
    schedule: Sequence[tuple[float, Faults]] = (),
    timeout_s: float = 120.0,
    fly_args: Sequence[str] = (),
    vehicle_args: Sequence[str] = (),
    keep: Path | None = None,
) -> dict[str, Any]:
    """Fly one episode through a relay with ``faults``. ``schedule``: (seconds after the vehicle
    first reports OFFBOARD, new faults) pairs; ``keep``: a folder for fly's tlog and summary (else
    a temporary one). Returns {"fly", "vehicle", "relay", "modes", ...}."""
    from sitl_stub.launcher import vehicle_process
    from uavlink.mavlink.connection import free_udp_port

    fly_port = free_udp_port()
    watch = ModeWatch()
    offboard = 6 << 16
    with (
        tempfile.TemporaryDirectory(prefix="fly_relay_") as tmp,
        UdpRelay(
            ("127.0.0.1", fly_port),
            faults,
            seed=relay_seed,
            max_duration_s=timeout_s + 10,
            tap=watch,
        ) as relay,
        vehicle_process(
            f"udpout:127.0.0.1:{relay.port}",
            speed,
            ["--scenario", scenario, "--seed", str(seed), *FAST_TAKEOFF, *vehicle_args],
        ) as vehicle,
    ):
        out = str(keep) if keep is not None else tmp
        cmd = [
            sys.executable,
            "-m",
            "uavlink.cli",
            "fly",
            "--no-picture",
            "--connect",
            f"udpin:127.0.0.1:{fly_port}",
            "--policy",
            policy,
            "--scenario",
            scenario,
            "--seed",
            str(seed),
            "--frames",
            str(frames),
            "--out",
            out,
            "--json",
            *fly_args,
        ]
        err_path = Path(out) / "fly.stderr"
        with open(err_path, "wb") as err:
            fly = subprocess.Popen(
                cmd,
                stdout=subprocess.PIPE,
                stderr=err,
                cwd=ROOT,
                env=dict(os.environ, PYTHONUNBUFFERED="1"),
            )
        try:
            deadline = time.monotonic() + timeout_s
            pending = sorted(schedule, key=lambda p: p[0])
            applied: list[tuple[float, str]] = []
            while fly.poll() is None and time.monotonic() < deadline:
                start = watch.first(offboard)
                while pending and start is not None and time.monotonic() >= start + pending[0][0]:
                    relay.set_faults(pending[0][1])
                    applied.append((time.monotonic(), pending[0][1].describe()))
                    pending.pop(0)
                time.sleep(0.02)
            if fly.poll() is None:
                fly.kill()
                fly.wait(10)
                raise AssertionError(
                    f"fly did not finish within {timeout_s} s: "
                    f"{err_path.read_text(errors='replace')[-3000:]}"
                )
            stdout = fly.stdout.read().decode() if fly.stdout else ""
        finally:
            if fly.poll() is None:
                fly.kill()
                fly.wait(10)
            if fly.stdout:
                fly.stdout.close()
        stderr = err_path.read_text(errors="replace")
        vehicle.stop()
        vstats = parse_vehicle_stats(vehicle.output())
    if fly.returncode != 0:
        raise AssertionError(f"fly exited {fly.returncode}: {stderr[-3000:]}")
    return {
        "fly": json.loads(stdout),
        "fly_stderr": stderr,
        "vehicle": vstats,
        "relay": dict(relay.stats),
        "modes": watch.changes,
        "watch": watch,
        "applied": applied,
        "faults": faults.describe(),
        "speed": speed,
        "frames": frames,
    }


def table_row(
    name: str, runs: dict[str, Any] | Sequence[dict[str, Any]], clean_mbps: float | None
) -> dict[str, Any]:
    """One row of the fault table from one or more :func:`fly_through_relay` results (the same
    condition, different relay seeds): means, and the worst of the safety monitors."""
    runs = [runs] if isinstance(runs, dict) else list(runs)
    truths = [r["vehicle"]["payloads"]["158"]["mean_rate_mbps"] for r in runs]
    flys, vehs = [r["fly"] for r in runs], [r["vehicle"]["vehicle"] for r in runs]

    def pct(x: float) -> float | None:
        return None if not clean_mbps else round(100.0 * (x / clean_mbps - 1.0), 2)

    return {
        "condition": name,
        "speed": runs[0]["speed"],
        "frames": runs[0]["frames"],
        "runs": len(runs),
        "mean_rate_mbps": round(sum(truths) / len(truths), 6),
        "rates_mbps": truths,
        "vs_clean_pct": pct(sum(truths) / len(truths)),
        "vs_clean_range_pct": None if not clean_mbps else [pct(min(truths)), pct(max(truths))],
        "fly_seen_mbps": [f["mean_rate_mbps"] for f in flys],
        "decisions": round(sum(f["decisions"] for f in flys) / len(flys), 1),
        "radio_frames_missed": [f["radio_frames_missed"] for f in flys],
        "stale_radio_reports": [f.get("stale_radio_reports") for f in flys],
        "offboard_failsafes": sum(v["offboard_failsafes"] for v in vehs),
        "offboard_reentries": sum(f["offboard_reentries"] for f in flys),
        "max_setpoint_age_s": max(v["max_offboard_setpoint_age_s"] for v in vehs),
        "max_abs_xy_m": max(v["max_abs_xy_m"] for v in vehs),
        "fence_m": vehs[0]["fence_m"],
        "episode_wall_s": [f["episode_wall_s"] for f in flys],
        "relay": [r["relay"] for r in runs],
    }


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    head = (
        "| condition | --speed | runs | mean UE throughput, Mbps (vehicle truth) | vs clean (range) | "
        "decisions per run | offboard failsafes | re-entries | max setpoint age (s) | "
        "max abs x/y (m) |"
    )
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        vs = ""
        if r["vs_clean_pct"] is not None:
            lo, hi = r["vs_clean_range_pct"]
            vs = f"{r['vs_clean_pct']:+.1f} %" + (
                f" ({lo:+.1f} .. {hi:+.1f})" if r["runs"] > 1 else ""
            )
        lines.append(
            f"| {r['condition']} | {r['speed']:g} | {r['runs']} | {r['mean_rate_mbps']:.3f} | "
            f"{vs} | {r['decisions']:g}/{r['frames']} | {r['offboard_failsafes']} | "
            f"{r['offboard_reentries']} | {r['max_setpoint_age_s']:.2f} | "
            f"{r['max_abs_xy_m']:.1f} |"
        )
    return "\n".join(lines)
