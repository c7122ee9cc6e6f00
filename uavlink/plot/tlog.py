"""A flight as arrays, read from a MAVLink telemetry log (.tlog): what ``uavlink plot`` draws.

Any .tlog works (8-byte big-endian microsecond timestamp + raw packet per record): the one
``uavlink fly`` writes, MAVProxy's ``mav.tlog``, QGroundControl's telemetry logs. What it holds:

- vehicles: every system whose autopilot sent a HEARTBEAT (autopilot not INVALID) and positions
  (LOCAL_POSITION_NED; GLOBAL_POSITION_INT through the local origin when it sends none);
- radio frames: each vehicle's UL_RADIO readings (:mod:`uavlink.mavlink.radio_codec`) of the running
  episode (SINR and sensed AoA per UE, its cell in a fleet), the vehicle's position at each frame
  interpolated at the frame's simulated time; the team's UL_SCORE (mean UE rate) per frame;
- decision frames: the frames the policy steered a vehicle in OFFBOARD (a heartbeat shows
  OFFBOARD at or after the frame's readings, before the next frame's: the heartbeat trails a mode
  change by up to its period). A log with the ground's FRAME_DECIDED commands (``uavlink fly``'s
  own) names the frames the policy decided (:mod:`uavlink.mavlink.radio_codec`, param2), so the
  count is ``fly``'s: an episode of N frames has N decisions (frames 0..N-1) and N scores (1..N);
  the readings of frame N follow the last decision but nobody decides them, although the vehicle
  is still in OFFBOARD then. Without those commands (another ground's log), a frame flown in
  OFFBOARD from its readings to the next frame's counts. When there are any, the picture keeps
  the frames from the first decision to the last one's outcome (its frame's successor, with the
  score of the last move; take-off and landing leave the radio payload counting frames that no
  policy decided); without, every running frame;
- UEs: the simulation's truth (ADSB_VEHICLE, :mod:`uavlink.mavlink.ue_truth`), each fix tagged with
  the frame of its sender's latest readings, placed through the local origin (HOME_POSITION);
- the fence: the inclusion polygon uploaded over the mission protocol (MISSION_ITEM_INT, FENCE).

A log of several flights (a ground station's session with a vehicle that starts a new radio episode
per flight) gives the radio frames of the last one; the tracks are the whole log's.

A log that is empty, or where no MAVLink message or no vehicle position can be read, raises
:class:`~uavlink.errors.UserError`. A log cut short (a flight killed while writing) reads up to the
cut.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from uavlink.errors import UserError
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.frames import e7_to_deg
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD, decode_custom_mode
from uavlink.mavlink.radio_codec import (
    FRAME_DECIDED_COMMAND,
    MAX_UES,
    RADIO_COMPONENT_ID,
    RUNNING,
    message_kind,
)
from uavlink.mavlink.ue_truth import decode_ue_fix

WANTED = [
    "HEARTBEAT",
    "LOCAL_POSITION_NED",
    "GLOBAL_POSITION_INT",
    "HOME_POSITION",
    "DEBUG_FLOAT_ARRAY",
    "ADSB_VEHICLE",
    "MISSION_ITEM_INT",
    "COMMAND_LONG",
]
RESTART_FRAMES = 3  # a running frame this far below the newest: a new episode, not a late copy
FENCE_MISSION_TYPE = mavlink.MAV_MISSION_TYPE_FENCE
FENCE_VERTEX = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION


@dataclass
class VehicleTrack:
    """One vehicle: its whole track and its radio frames."""

    system_id: int
    time_s: np.ndarray  # (T,) vehicle time since boot
    east_m: np.ndarray  # (T,)
    north_m: np.ndarray  # (T,)
    frames: np.ndarray  # (F,) radio frame indices drawn, ascending
    frame_time_s: np.ndarray  # (F,) each frame's vehicle time (simulated, since boot)
    frame_east_m: np.ndarray  # (F,) the vehicle's position at each frame
    frame_north_m: np.ndarray  # (F,)
    sinr_db: np.ndarray  # (F, U) what its base station sensed
    aoa_deg: np.ndarray  # (F, U) sensed angle of arrival, deg from east
    serves: np.ndarray | None  # (F, U) bool: its cell (a fleet's), None when not reported
    decided: np.ndarray  # (F,) bool: flew that frame in OFFBOARD (a decision frame)


@dataclass
class FlightData:
    """Everything a flight picture shows, in the local frame (metres east and north of the origin)."""

    source: str
    vehicles: list[VehicleTrack]
    n_ues: int  # 0 without radio messages
    frames: np.ndarray  # (K,) the frames drawn (union over vehicles)
    ue_east_m: np.ndarray  # (K, U_truth) NaN where no fix (U_truth 0 without ADSB truth)
    ue_north_m: np.ndarray
    mean_rate_mbps: np.ndarray  # (K,) the team's mean UE rate, NaN where no score
    fence_en_m: np.ndarray | None  # (P, 2) east, north of the fence polygon's vertices
    notes: list[str] = field(default_factory=list)  # what the log lacked, said in the picture

    @property
    def decision_frames(self) -> int:
        """Frames in which some UAV decided (was in OFFBOARD)."""
        return len(set().union(*(v.frames[v.decided].tolist() for v in self.vehicles)))

    def serving_uav(self) -> np.ndarray:
        """(K, U) index into ``vehicles`` of each UE's serving UAV per frame (-1: unknown);
        every UE is served by the only UAV when there is one."""
        serving = np.full((len(self.frames), self.n_ues), -1, dtype=int)
        for d, v in enumerate(self.vehicles):
            rows = np.searchsorted(self.frames, v.frames)
            if v.serves is None:
                if len(self.vehicles) == 1:
                    serving[rows] = d
            else:
                cell = v.serves
                serving[rows] = np.where(cell, d, serving[rows])
        return serving


class _Reader:
    """State while reading one log, in log order."""

    def __init__(self) -> None:
        self.autopilots: set[int] = set()
        self.local: dict[int, list[tuple[float, float, float]]] = {}
        self.glob: dict[int, list[tuple[float, float, float]]] = {}
        self.home: dict[int, GeoOrigin] = {}
        self.offboard: dict[int, bool] = {}
        self.readings: dict[int, dict[int, tuple]] = {}
        self.last_frame: dict[int, int] = {}
        self.fixes: dict[int, dict[int, tuple[float, float]]] = {}
        self.scores: dict[int, float] = {}
        self.fence: dict[int, tuple[float, float]] = {}
        self.decisions: dict[int, set[int]] = {}  # per system: frames the ground said it decided
        self.messages = 0

    def take(self, msg) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        self.messages += 1
        sys_id, comp = msg.get_srcSystem(), msg.get_srcComponent()
        if kind == "HEARTBEAT":
            if msg.autopilot != mavlink.MAV_AUTOPILOT_INVALID:
                self.autopilots.add(sys_id)
                offboard = decode_custom_mode(msg.custom_mode)[0] == PX4_MAIN_OFFBOARD
                self.offboard[sys_id] = offboard
                got, frame = self.readings.get(sys_id, {}), self.last_frame.get(sys_id)
                if (
                    offboard and frame in got
                ):  # the heartbeat lags a mode change by up to its period:
                    got[frame] = (
                        *got[frame][:2],
                        True,
                    )  # a frame is OFFBOARD if it shows before the next
        elif kind == "LOCAL_POSITION_NED":
            if math.isfinite(msg.x) and math.isfinite(msg.y):
                self.local.setdefault(sys_id, []).append((msg.time_boot_ms * 1e-3, msg.y, msg.x))
        elif kind == "GLOBAL_POSITION_INT":
            self.glob.setdefault(sys_id, []).append(
                (msg.time_boot_ms * 1e-3, e7_to_deg(msg.lat), e7_to_deg(msg.lon))
            )
        elif kind == "HOME_POSITION":
            home = GeoOrigin(e7_to_deg(msg.latitude), e7_to_deg(msg.longitude))
            lat, lon = home.to_global(-msg.x, -msg.y)  # the local origin, as the fence upload does
            self.home[sys_id] = GeoOrigin(lat, lon)
        elif kind == "DEBUG_FLOAT_ARRAY" and comp == RADIO_COMPONENT_ID:
            which = message_kind(msg)
            data = msg.data
            if which == "readings":
                self.last_frame[sys_id] = msg.array_id
                n = int(data[0])
                if 0 < n <= MAX_UES and data[1 + 2 * n] in RUNNING:
                    got = self.readings.setdefault(sys_id, {})
                    if got and msg.array_id < max(got) - RESTART_FRAMES:
                        got.clear()  # the payload started a new episode: draw the latest flight
                        self.decisions.pop(sys_id, None)
                    got.setdefault(
                        msg.array_id,
                        (
                            msg.time_usec * 1e-6,
                            tuple(data[: 2 + 3 * n]),
                            self.offboard.get(sys_id, False),
                        ),
                    )
            elif which == "score":
                self.scores[msg.array_id] = float(data[1])
        elif kind == "ADSB_VEHICLE":
            fix = decode_ue_fix(msg)
            if fix is not None and sys_id in self.last_frame:
                self.fixes.setdefault(self.last_frame[sys_id], {})[fix.ue] = (
                    fix.lat_deg,
                    fix.lon_deg,
                )
        elif (
            kind == "COMMAND_LONG"
            and msg.command == FRAME_DECIDED_COMMAND
            and msg.target_component == RADIO_COMPONENT_ID
            and msg.param2 in (0.0, 1.0)
        ):
            decided = self.decisions.setdefault(msg.target_system, set())  # (NaN: an older fly's)
            if msg.param2 == 1.0:
                decided.add(int(msg.param1))
        elif (
            kind == "MISSION_ITEM_INT"
            and msg.mission_type == FENCE_MISSION_TYPE
            and msg.command == FENCE_VERTEX
        ):
            self.fence[msg.seq] = (e7_to_deg(msg.x), e7_to_deg(msg.y))


def read_flight(path: Path) -> FlightData:
    """Read a .tlog into :class:`FlightData`; UserError for an empty or unreadable log."""
    path = Path(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror or exc}") from None
    if size == 0:
        raise UserError(f"{path}: empty file, not a flight log")
    reader = _Reader()
    for msg in _records(path.read_bytes()):
        reader.take(msg)
    return _assemble(reader, str(path))


_WANTED_IDS = frozenset(getattr(mavlink, f"MAVLINK_MSG_ID_{name}") for name in WANTED)
_V2, _V1 = 0xFD, 0xFE


def _records(blob: bytes) -> Iterator:
    """The wanted messages of a tlog's records (timestamp + packet), each checked by its CRC.

    Only the wanted message ids are decoded (the bulk of a log is attitude, status and setpoints
    that no picture shows: skipping them makes reading 3-5x faster than pymavlink's ``recv_match``,
    research/log/flight.md).
    A record that does not parse (a bad start byte, a CRC error, a cut) resyncs at the next byte
    that starts a record whose packet decodes: damage costs the damaged records only."""
    mav = mavlink.MAVLink(None)
    i, end = 0, len(blob)
    while i + 8 + 8 <= end:
        start = i + 8
        magic = blob[start]
        if magic == _V2:
            if start + 10 > end:
                return  # cut inside the header: the log ends here
            size = 12 + blob[start + 1] + (13 if blob[start + 2] & 1 else 0)
            msg_id = blob[start + 7] | blob[start + 8] << 8 | blob[start + 9] << 16
        elif magic == _V1:
            size, msg_id = 8 + blob[start + 1], blob[start + 5]
        else:
            i += 1  # not a record start: resync
            continue
        if start + size > end:
            return  # cut short: the log ends here
        if msg_id not in _WANTED_IDS:
            i = start + size
            continue
        try:
            msg = mav.decode(bytearray(blob[start : start + size]))
        except Exception:  # CRC or length error: a damaged record, or not a record start
            i += 1
            continue
        i = start + size
        yield msg


def _assemble(r: _Reader, source: str) -> FlightData:
    if r.messages == 0:
        raise UserError(f"{source}: no MAVLink message could be read (damaged, or not a .tlog)")
    notes: list[str] = []
    origin = next(iter(r.home.values()), None)
    systems = sorted(s for s in r.autopilots if s in r.local or s in r.glob)
    if not systems:
        raise UserError(
            f"{source}: no vehicle position in the log (no LOCAL_POSITION_NED or "
            "GLOBAL_POSITION_INT from an autopilot)"
        )
    if origin is None:
        first = r.glob.get(systems[0])
        if first:  # no HOME_POSITION: the first fix stands for the origin of a local frame
            origin = GeoOrigin(first[0][1], first[0][2])
            notes.append("no HOME_POSITION: origin at the first position fix")
    n_ues = (
        max((len(d[1]) - 2) // 3 for rs in r.readings.values() for d in rs.values())
        if any(r.readings.values())
        else 0
    )
    vehicles = [_track(s, r, origin, n_ues) for s in systems]
    decided = [v.frames[v.decided] for v in vehicles if v.decided.any()]
    all_frames = np.unique(np.concatenate([v.frames for v in vehicles] + [np.zeros(0, int)]))
    if decided:
        lo, hi = min(int(f.min()) for f in decided), max(int(f.max()) for f in decided)
        if any(v.system_id in r.decisions for v in vehicles):
            hi += 1  # the last decision's outcome: its successor's readings and score (fly's mean has it)
        all_frames = all_frames[(all_frames >= lo) & (all_frames <= hi)]
        for v in vehicles:
            _keep(v, (v.frames >= lo) & (v.frames <= hi))
    if not r.readings:
        notes.append("no radio messages (UL_RADIO): tracks only")
    n_truth = 1 + max((ue for fx in r.fixes.values() for ue in fx), default=-1)
    ue_e = np.full((len(all_frames), n_truth), np.nan)
    ue_n = np.full((len(all_frames), n_truth), np.nan)
    if n_truth and origin is not None:
        for row, f in enumerate(all_frames):
            for ue, (lat, lon) in r.fixes.get(int(f), {}).items():
                ue_n[row, ue], ue_e[row, ue] = origin.to_local(lat, lon)
    elif n_ues and not n_truth:
        notes.append("no UE positions (ADSB_VEHICLE truth) in the log")
    rates = np.array([r.scores.get(int(f), np.nan) for f in all_frames])
    fence = None
    if r.fence and origin is not None:
        fence = np.array([origin.to_local(*r.fence[k])[::-1] for k in sorted(r.fence)])
    elif not r.fence:
        notes.append("no fence upload in the log")
    return FlightData(source, vehicles, n_ues, all_frames, ue_e, ue_n, rates, fence, notes=notes)


def _track(system: int, r: _Reader, origin: GeoOrigin | None, n_ues: int) -> VehicleTrack:
    if system in r.local:
        t, east, north = (np.array(c) for c in zip(*r.local[system], strict=True))
    else:
        rows = r.glob[system]
        t = np.array([row[0] for row in rows])
        ne = (
            np.array([origin.to_local(lat, lon) for _, lat, lon in rows])
            if origin
            else np.zeros((len(rows), 2))
        )
        north, east = ne[:, 0], ne[:, 1]
    order = np.argsort(t, kind="stable")
    t, east, north = t[order], east[order], north[order]
    got = r.readings.get(system, {})
    frames = np.array(sorted(got), dtype=int)
    u = n_ues
    sinr = np.full((len(frames), u), np.nan)
    aoa = np.full((len(frames), u), np.nan)
    flags = np.zeros((len(frames), u))
    decided = np.zeros(len(frames), dtype=bool)
    frame_t = np.zeros(len(frames))
    for row, f in enumerate(frames):
        time_s, data, offboard = got[int(f)]
        n = int(data[0])
        sinr[row, :n], aoa[row, :n] = data[1 : 1 + n], data[1 + n : 1 + 2 * n]
        flags[row, :n] = data[2 + 2 * n : 2 + 3 * n]
        decided[row], frame_t[row] = offboard, time_s
    if system in r.decisions:  # the ground named its decisions (fly's log): exactly fly's count
        decided &= np.isin(frames, sorted(r.decisions[system]))
    else:  # flown under OFFBOARD from its readings to the next frame's (the frame after the last
        # decision arrives in OFFBOARD too, but then the loop hands the vehicle back)
        decided &= np.append(decided[1:], r.offboard.get(system, False))
    serves = flags > 0 if (flags != 0).any() else None
    fe = np.interp(frame_t, t, east) if len(t) else np.full(len(frames), np.nan)
    fn = np.interp(frame_t, t, north) if len(t) else np.full(len(frames), np.nan)
    return VehicleTrack(system, t, east, north, frames, frame_t, fe, fn, sinr, aoa, serves, decided)


def _keep(v: VehicleTrack, mask: np.ndarray) -> None:
    """Keep the frames in ``mask`` (the track stays whole: take-off and landing are vertical)."""
    v.frames, v.frame_time_s = v.frames[mask], v.frame_time_s[mask]
    v.frame_east_m, v.frame_north_m = v.frame_east_m[mask], v.frame_north_m[mask]
    v.sinr_db, v.aoa_deg, v.decided = v.sinr_db[mask], v.aoa_deg[mask], v.decided[mask]
    if v.serves is not None:
        v.serves = v.serves[mask]
