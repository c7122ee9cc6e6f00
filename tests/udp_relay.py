"""A test-only UDP relay on loopback that drops, delays, duplicates and reorders datagrams.

Topology: one endpoint sends to the relay's ``port`` (e.g. the vehicle with
``--connect udpout:127.0.0.1:PORT``); the relay forwards its datagrams to ``dest`` (e.g.
``uavlink fly --connect udpin:127.0.0.1:DEST``) from a second socket, and forwards what comes back
to that socket to the first endpoint's address. Each datagram (one MAVLink packet) meets the
current :class:`Faults` independently, in each direction, drawn from a seeded ``random.Random``:

- ``loss``: dropped with this probability;
- ``delay_s`` + uniform(0, ``jitter_s``): held this long before it is sent;
- ``duplicate``: sent twice (the copy ``dup_gap_s`` later);
- ``reorder``: held ``reorder_s`` longer than the datagrams around it, so it arrives after them.

The relay runs in a daemon thread, stops by itself after ``max_duration_s`` (wall), and always on
:meth:`UdpRelay.stop` / leaving its ``with`` block. :meth:`UdpRelay.set_faults` changes the faults
while it runs (e.g. a blackout, then a clear link). ``stats`` counts what it did per direction.
``tap(direction, datagram)``, when given, sees every datagram as it arrives (before any fault).

:func:`fly_through_relay` flies ``uavlink fly`` (a child process) against ``python -m sitl_stub``
(another) through a relay and returns fly's summary, the vehicle's exit stats (its own truth of
the episode's throughput, whatever the link lost, and its safety monitors) and the relay's counts.
``python tests/udp_relay.py`` runs benchmarks/link_faults.py (the throughput table).
"""

from __future__ import annotations

import heapq
import json
import os
import random
import select
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

MAX_DATAGRAM = 65535


@dataclass(frozen=True)
class Faults:
    loss: float = 0.0
    delay_s: float = 0.0
    jitter_s: float = 0.0
    duplicate: float = 0.0
    dup_gap_s: float = 0.002
    reorder: float = 0.0
    reorder_s: float = 0.03

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be a probability, got {getattr(self, name)}")
        for name in ("delay_s", "jitter_s", "dup_gap_s", "reorder_s"):
            if not 0.0 <= getattr(self, name) <= 10.0:
                raise ValueError(f"{name} must be in [0, 10] s, got {getattr(self, name)}")

    def describe(self) -> str:
        parts = [f"{self.loss:.0%} loss" if self.loss else "",
                 f"{self.delay_s * 1e3:.0f} ms delay" if self.delay_s else "",
                 f"{self.jitter_s * 1e3:.0f} ms jitter" if self.jitter_s else "",
                 f"{self.duplicate:.0%} duplicated" if self.duplicate else "",
                 f"{self.reorder:.0%} reordered" if self.reorder else ""]
        return ", ".join(p for p in parts if p) or "clean"


CLEAN = Faults()
BLACKOUT = Faults(loss=1.0)


class UdpRelay:
    """Relay between whoever sends to ``port`` and ``dest``; see the module docstring."""

    def __init__(self, dest: tuple[str, int], faults: Faults = CLEAN, seed: int = 0,
                 max_duration_s: float = 120.0, host: str = "127.0.0.1",
                 tap: Callable[[str, bytes], None] | None = None) -> None:
        if host not in ("127.0.0.1", "localhost"):
            raise ValueError("the test relay stays on loopback")
        self.dest = dest
        self.faults = faults
        self.max_duration_s = max_duration_s
        self.tap = tap
        self.stats: Counter[str] = Counter()
        self._rng = {"up": random.Random(f"{seed}-up"), "down": random.Random(f"{seed}-down")}
        self._front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._front.bind((host, 0))
        self._back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._back.bind((host, 0))
        self._client: tuple[str, int] | None = None
        self._queue: list[tuple[float, int, str, bytes]] = []
        self._n = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    @property
    def port(self) -> int:
        """Where the first endpoint sends."""
        return int(self._front.getsockname()[1])

    def set_faults(self, faults: Faults) -> None:
        self.faults = faults

    # ---------------------------------------------------------------- lifecycle
    def start(self) -> UdpRelay:
        self._thread = threading.Thread(target=self._run, name="udp_relay", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
        self._front.close()
        self._back.close()

    def __enter__(self) -> UdpRelay:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # --------------------------------------------------------------------- loop
    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # reported to the test
            self.error = exc

    def _loop(self) -> None:
        ends = time.monotonic() + self.max_duration_s
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= ends:
                self.stats["expired"] += 1
                return
            self._release(now)
            wait = 0.05 if not self._queue else max(0.0, min(0.05, self._queue[0][0] - now))
            readable, _, _ = select.select([self._front, self._back], [], [], wait)
            for sock in readable:
                try:
                    data, addr = sock.recvfrom(MAX_DATAGRAM)
                except OSError:  # e.g. ICMP port unreachable from a peer that went away
                    continue
                if sock is self._front:
                    self._client = addr
                    self._admit("up", data)
                else:
                    self._admit("down", data)

    def _admit(self, direction: str, data: bytes) -> None:
        f, rng = self.faults, self._rng[direction]
        self.stats[f"{direction}_in"] += 1
        if self.tap is not None:
            self.tap(direction, data)
        if f.loss and rng.random() < f.loss:
            self.stats[f"{direction}_dropped"] += 1
            return
        at = time.monotonic() + f.delay_s + (rng.uniform(0.0, f.jitter_s) if f.jitter_s else 0.0)
        if f.reorder and rng.random() < f.reorder:
            at += f.reorder_s
            self.stats[f"{direction}_reordered"] += 1
        self._schedule(at, direction, data)
        if f.duplicate and rng.random() < f.duplicate:
            self.stats[f"{direction}_duplicated"] += 1
            self._schedule(at + f.dup_gap_s, direction, data)

    def _schedule(self, at: float, direction: str, data: bytes) -> None:
        self._n += 1
        heapq.heappush(self._queue, (at, self._n, direction, data))

    def _release(self, now: float) -> None:
        while self._queue and self._queue[0][0] <= now:
            _, _, direction, data = heapq.heappop(self._queue)
            try:
                if direction == "up":
                    self._back.sendto(data, self.dest)
                elif self._client is not None:
                    self._front.sendto(data, self._client)
                self.stats[f"{direction}_out"] += 1
            except OSError:
                self.stats[f"{direction}_send_errors"] += 1


# ----------------------------------------------------------------- a ground station for tests
class Gcs:
    """A pymavlink ground station on ``udpout`` to a listening vehicle, optionally signing with
    pymavlink's own ``setup_signing`` (a stock client). It records the autopilot's heartbeats
    (wall time, custom_mode, armed) and every COMMAND_ACK addressed to it."""

    def __init__(self, port: int, system_id: int = 245, component_id: int = 190,
                 key: bytes | None = None) -> None:
        from uavlink.mavlink.dialect import mavutil

        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=system_id,
                                               source_component=component_id, dialect="common")
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.mav = self.conn.mav
        self.id = (system_id, component_id)
        self.modes: list[tuple[float, int, bool]] = []
        self.acks: list[Any] = []
        self.texts: list[str] = []
        self.last: dict[str, Any] = {}
        self._hb = 0.0

    def close(self) -> None:
        self.conn.close()

    def pump(self, timeout: float = 0.02) -> None:
        """Send our heartbeat (twice a second) and handle what arrived within ``timeout``."""
        now = time.monotonic()
        if now - self._hb >= 0.5:
            self._hb = now
            self.mav.heartbeat_send(6, 8, 0, 0, 4)  # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, ACTIVE
        m = self.conn.recv_match(blocking=True, timeout=timeout)
        while m is not None:
            self._record(m)
            m = self.conn.recv_match(blocking=False)

    def _record(self, m: Any) -> None:
        kind = m.get_type()
        if kind == "BAD_DATA" or m.get_srcSystem() != 1:
            return
        self.last[kind] = m
        if kind == "HEARTBEAT" and m.get_srcComponent() == 1:
            armed = bool(m.base_mode & 128)
            if not self.modes or self.modes[-1][1:] != (m.custom_mode, armed):
                self.modes.append((time.monotonic(), m.custom_mode, armed))
        elif kind == "COMMAND_ACK" and (m.target_system, m.target_component) == self.id:
            self.acks.append(m)
        elif kind == "STATUSTEXT":
            self.texts.append(m.text)

    def wait(self, condition: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout} s waiting for {what}")
            self.pump()

    def wait_message(self, kind: str, timeout: float = 10.0,
                     pred: Callable[[Any], bool] = lambda m: True) -> Any:
        self.last.pop(kind, None)
        self.wait(lambda: kind in self.last and pred(self.last[kind]), timeout, kind)
        return self.last[kind]

    @property
    def mode(self) -> tuple[int, bool] | None:
        return self.modes[-1][1:] if self.modes else None

    def command(self, cmd: int, *params: float, wait_s: float = 3.0) -> int | None:
        """COMMAND_LONG (target component 0, like pymavlink GCSs); the ACK result or None."""
        p = list(params) + [0.0] * (7 - len(params))
        before = len(self.acks)
        self.mav.command_long_send(1, 0, cmd, 0, *p)
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            self.pump()
            for ack in self.acks[before:]:
                if ack.command == cmd:
                    return int(ack.result)
        return None

    def acks_for(self, cmd: int) -> list[Any]:
        return [a for a in self.acks if a.command == cmd]


def wait_for_vehicle(gcs: Gcs, vehicle: Any, timeout: float = 20.0) -> None:
    """Pump ``gcs`` until the vehicle's heartbeat arrives (fails early if the process died)."""
    deadline = time.monotonic() + timeout
    while gcs.mode is None:
        assert vehicle.proc.poll() is None, vehicle.output()
        assert time.monotonic() < deadline, "the vehicle never answered"
        gcs.pump(0.1)


# ------------------------------------------------------------------- flights through the relay
FAST_TAKEOFF = ("--param", "MPC_TKO_SPEED=5", "--param", "MPC_Z_VEL_MAX_UP=5")  # 95 m in ~20 s sim


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


def parse_vehicle_stats(output: str) -> dict[str, Any]:
    for line in reversed(output.splitlines()):
        if line.startswith("sitl-stub: stats "):
            return json.loads(line.split(" ", 2)[2])
    raise AssertionError(f"no stats line in the vehicle's output:\n{output[-2000:]}")


def fly_through_relay(faults: Faults, *, policy: str = "aoa", scenario: str = "straight",
                      seed: int = 0, frames: int = 128, speed: float = 20.0, relay_seed: int = 0,
                      schedule: Sequence[tuple[float, Faults]] = (), timeout_s: float = 120.0,
                      fly_args: Sequence[str] = (), vehicle_args: Sequence[str] = (),
                      keep: Path | None = None) -> dict[str, Any]:
    """Fly one episode through a relay with ``faults``. ``schedule``: (seconds after the vehicle
    first reports OFFBOARD, new faults) pairs; ``keep``: a folder for fly's tlog and summary (else
    a temporary one). Returns {"fly", "vehicle", "relay", "modes", ...}."""
    from sitl_stub.launcher import vehicle_process
    from uavlink.mavlink.connection import free_udp_port

    fly_port = free_udp_port()
    watch = ModeWatch()
    offboard = 6 << 16
    with tempfile.TemporaryDirectory(prefix="fly_relay_") as tmp, \
            UdpRelay(("127.0.0.1", fly_port), faults, seed=relay_seed, max_duration_s=timeout_s + 10,
                     tap=watch) as relay, \
            vehicle_process(f"udpout:127.0.0.1:{relay.port}", speed,
                            ["--scenario", scenario, "--seed", str(seed), *FAST_TAKEOFF,
                             *vehicle_args]) as vehicle:
        out = str(keep) if keep is not None else tmp
        cmd = [sys.executable, "-m", "uavlink.cli", "fly", "--connect", f"udpin:127.0.0.1:{fly_port}",
               "--policy", policy, "--scenario", scenario, "--seed", str(seed), "--frames",
               str(frames), "--out", out, "--json", *fly_args]
        err_path = Path(out) / "fly.stderr"
        with open(err_path, "wb") as err:
            fly = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, cwd=ROOT,
                                   env=dict(os.environ, PYTHONUNBUFFERED="1"))
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
                raise AssertionError(f"fly did not finish within {timeout_s} s: "
                                     f"{err_path.read_text(errors='replace')[-3000:]}")
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
    return {"fly": json.loads(stdout), "fly_stderr": stderr, "vehicle": vstats,
            "relay": dict(relay.stats), "modes": watch.changes, "watch": watch, "applied": applied,
            "faults": faults.describe(), "speed": speed, "frames": frames}


def table_row(name: str, runs: dict[str, Any] | Sequence[dict[str, Any]],
              clean_mbps: float | None) -> dict[str, Any]:
    """One row of the fault table from one or more :func:`fly_through_relay` results (the same
    condition, different relay seeds): means, and the worst of the safety monitors."""
    runs = [runs] if isinstance(runs, dict) else list(runs)
    truths = [r["vehicle"]["payloads"]["158"]["mean_rate_mbps"] for r in runs]
    flys, vehs = [r["fly"] for r in runs], [r["vehicle"]["vehicle"] for r in runs]

    def pct(x: float) -> float | None:
        return None if not clean_mbps else round(100.0 * (x / clean_mbps - 1.0), 2)

    return {
        "condition": name, "speed": runs[0]["speed"], "frames": runs[0]["frames"], "runs": len(runs),
        "mean_rate_mbps": round(sum(truths) / len(truths), 6), "rates_mbps": truths,
        "vs_clean_pct": pct(sum(truths) / len(truths)),
        "vs_clean_range_pct": None if not clean_mbps else [pct(min(truths)), pct(max(truths))],
        "fly_seen_mbps": [f["mean_rate_mbps"] for f in flys],
        "decisions": round(sum(f["decisions"] for f in flys) / len(flys), 1),
        "radio_frames_missed": [f["radio_frames_missed"] for f in flys],
        "stale_radio_reports": [f.get("stale_radio_reports") for f in flys],
        "offboard_failsafes": sum(v["offboard_failsafes"] for v in vehs),
        "offboard_reentries": sum(f["offboard_reentries"] for f in flys),
        "max_setpoint_age_s": max(v["max_offboard_setpoint_age_s"] for v in vehs),
        "max_abs_xy_m": max(v["max_abs_xy_m"] for v in vehs), "fence_m": vehs[0]["fence_m"],
        "episode_wall_s": [f["episode_wall_s"] for f in flys],
        "relay": [r["relay"] for r in runs],
    }


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    head = ("| condition | --speed | runs | mean UE throughput, Mbps (vehicle truth) | vs clean (range) | "
            "decisions per run | offboard failsafes | re-entries | max setpoint age (s) | "
            "max abs x/y (m) |")
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        vs = ""
        if r["vs_clean_pct"] is not None:
            lo, hi = r["vs_clean_range_pct"]
            vs = f"{r['vs_clean_pct']:+.1f} %" + (f" ({lo:+.1f} .. {hi:+.1f})" if r["runs"] > 1 else "")
        lines.append(f"| {r['condition']} | {r['speed']:g} | {r['runs']} | {r['mean_rate_mbps']:.3f} | "
                     f"{vs} | {r['decisions']:g}/{r['frames']} | {r['offboard_failsafes']} | "
                     f"{r['offboard_reentries']} | {r['max_setpoint_age_s']:.2f} | "
                     f"{r['max_abs_xy_m']:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - convenience entry point
    import runpy
    import sys
    from pathlib import Path

    sys.argv[0] = str(Path(__file__).resolve().parents[1] / "benchmarks" / "link_faults.py")
    runpy.run_path(sys.argv[0], run_name="__main__")
