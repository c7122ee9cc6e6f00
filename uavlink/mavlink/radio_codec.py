"""How radio readings travel over MAVLink: two standard DEBUG_FLOAT_ARRAY (id 350) messages.

Any MAVLink tool decodes them with the stock common.xml. Both come from the radio payload's own
component (``RADIO_COMPONENT_ID``) every frame (UL_RADIO twice, as a copy against packet loss:
receivers keep the first of each frame); ``array_id`` is the frame index (0 until the episode
starts) and ``time_usec`` the simulated time.

``UL_RADIO`` (what the base station senses; the policy's input):
    data[0] = U (number of UEs), data[1 : 1+U] = effective SINR (dB),
    data[1+U : 1+2U] = measured AoA (deg from east, [-180, 180)),
    data[1+2U] = 1 while the episode runs, 2 while it runs with the vehicle's time held at each
    frame until FRAME_DECIDED (a lockstep vehicle, below), 0 while it waits for the mission to start,
    data[2+2U : 2+3U] (a fleet's UAV only) = +1 for each UE this UAV serves, -1 for the others
    (all 0, the padding, when not reported: one UAV serves every UE).
``UL_SCORE`` (the simulator's truth, for scoring and logs only; never fed to the policy):
    data[0] = U, data[1] = mean UE rate (Mbps), data[2] = R_fair, data[3 : 3+U] = rates (Mbps).

Which episode the world runs goes with every frame's readings, just before them, as two standard
NAMED_VALUE_INT (id 252) from the same component, so a tlog names the episode it flew:
``UL_EP_SEED`` is the seed S whose evaluation episode 0 it is (``uavlink evaluate --seed S
--episodes 1`` replays it); ``UL_EPISODE`` counts the vehicle's episodes since it started (0: the
first; each flight begins a new one, ``sitl_stub.sim.radio_episodes``).

Lockstep (a simulated vehicle started with ``--lockstep``): after deciding frame k (its setpoint
sent), the flight computer sends COMMAND_LONG ``FRAME_DECIDED_COMMAND`` (MAV_CMD_USER_1) to
``RADIO_COMPONENT_ID`` with param1 = k, fire-and-forget (no ACK: one a frame would only add
traffic). A lockstep vehicle holds simulated time at each frame of a running episode until that
command arrives, so a flight decides every frame at the instant the env does; any other vehicle
ignores it. param2 says whether the policy decided the frame for that vehicle (1) or the frame was
only let go (0: past the frames the flight set out to fly, e.g. the episode's last frame, whose
readings follow the last decision; in a fleet, also a vehicle the policy did not steer that frame),
so a log names the decision frames exactly (``uavlink plot``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RADIO_COMPONENT_ID = 158  # MAV_COMP_ID_PERIPHERAL: a payload on the vehicle's system
READINGS_NAME = "UL_RADIO"
SCORE_NAME = "UL_SCORE"
EPISODE_SEED_NAME = "UL_EP_SEED"  # NAMED_VALUE_INT names: at most 10 characters
EPISODE_COUNT_NAME = "UL_EPISODE"
FRAME_DECIDED_COMMAND = 31010  # MAV_CMD_USER_1: param1 = the frame, param2 = 1 decided / 0 let go
RUNNING = (1.0, 2.0)  # data[1+2U] while the episode runs: 2.0 when the vehicle's time waits
DATA_LEN = 58
MAX_UES = (DATA_LEN - 2) // 2


class RadioReportError(ValueError):
    """A radio message that cannot be used (wrong UE count, NaN, out of range)."""


@dataclass(frozen=True)
class RadioReport:
    frame: int
    time_s: float
    sinr_db: np.ndarray  # (U,)
    aoa_deg: np.ndarray  # (U,)
    running: bool = True
    # (U,) bool: the UEs in this UAV's cell (a fleet's); None: not reported.
    serves: np.ndarray | None = None
    waits: bool = False  # the vehicle's time waits for this frame's FRAME_DECIDED (lockstep)


@dataclass(frozen=True)
class ScoreReport:
    frame: int
    mean_rate_mbps: float
    fair_rate: float


def _pad(values: list[float]) -> list[float]:
    return values + [0.0] * (DATA_LEN - len(values))


def encode_readings(
    sinr_db: np.ndarray,
    aoa_deg: np.ndarray,
    running: bool,
    serves: np.ndarray | None = None,
    waits: bool = False,
) -> list[float]:
    n = len(sinr_db)
    cell = [] if serves is None else [1.0 if s else -1.0 for s in serves]
    if 2 + 2 * n + len(cell) > DATA_LEN or len(aoa_deg) != n or len(cell) not in (0, n):
        raise ValueError(
            f"cannot encode {n} UEs in one DEBUG_FLOAT_ARRAY (max {MAX_UES}, "
            f"{(DATA_LEN - 2) // 3} with a fleet's cell flags)"
        )
    state = (2.0 if waits else 1.0) if running else 0.0
    return _pad([float(n), *map(float, sinr_db), *map(float, aoa_deg), state, *cell])


def encode_score(rate_bps: np.ndarray, fair_rate: float) -> list[float]:
    n = len(rate_bps)
    return _pad(
        [
            float(n),
            float(np.mean(rate_bps)) * 1e-6,
            float(fair_rate),
            *(float(r) * 1e-6 for r in rate_bps[: DATA_LEN - 3]),
        ]
    )


def _name(msg) -> str:
    name = msg.name
    return name.decode(errors="replace") if isinstance(name, bytes) else str(name)


def decode_readings(msg, expected_ues: int) -> RadioReport:
    """Validate and decode a UL_RADIO message; raises RadioReportError with the reason."""
    data = list(msg.data)
    n = data[0]
    if n != expected_ues:
        raise RadioReportError(f"radio report has {n:g} UEs, policy expects {expected_ues}")
    sinr = np.asarray(data[1 : 1 + expected_ues], dtype=float)
    aoa = np.asarray(data[1 + expected_ues : 1 + 2 * expected_ues], dtype=float)
    if not (np.isfinite(sinr).all() and np.isfinite(aoa).all()):
        raise RadioReportError("radio report contains NaN or infinite values")
    if (np.abs(aoa) > 180.0).any() or (np.abs(sinr) > 200.0).any():
        raise RadioReportError("radio report values out of range")
    flags = np.asarray(data[2 + 2 * expected_ues : 2 + 3 * expected_ues], dtype=float)
    serves = flags > 0 if len(flags) == expected_ues and (flags != 0).any() else None
    return RadioReport(
        int(msg.array_id),
        msg.time_usec * 1e-6,
        sinr,
        aoa,
        running=data[1 + 2 * expected_ues] in RUNNING,
        serves=serves,
        waits=data[1 + 2 * expected_ues] == 2.0,
    )


def decode_score(msg) -> ScoreReport:
    """Decode a UL_SCORE message; RadioReportError when its rates are NaN, infinite or negative."""
    data = list(msg.data)
    mean, fair = float(data[1]), float(data[2])
    if not (np.isfinite(mean) and np.isfinite(fair)) or mean < 0 or fair < 0:
        raise RadioReportError(f"radio score with unusable rates (mean {mean}, fair {fair})")
    return ScoreReport(int(msg.array_id), mean, fair)


def send_frame_decided(mav, target_system: int, frame: int, decided: bool) -> None:
    """FRAME_DECIDED for ``frame`` to the radio payload of ``target_system`` (``mav``: a pymavlink
    ``MAVLink``): a lockstep vehicle lets simulated time go on; no ACK is awaited. ``decided``
    (param2): the policy decided this frame for this vehicle; False: only let go."""
    mav.command_long_send(
        target_system,
        RADIO_COMPONENT_ID,
        FRAME_DECIDED_COMMAND,
        0,
        float(frame),
        1.0 if decided else 0.0,
        *(float("nan"),) * 5,
    )


def decode_episode(msg) -> tuple[str, int] | None:
    """A NAMED_VALUE_INT naming the radio episode: ("seed" | "count", value); None for others."""
    name = _name(msg).rstrip("\x00")
    key = {EPISODE_SEED_NAME: "seed", EPISODE_COUNT_NAME: "count"}.get(name)
    return None if key is None else (key, int(msg.value))


def message_kind(msg) -> str | None:
    """'readings', 'score' or None for a DEBUG_FLOAT_ARRAY from anywhere."""
    if msg.get_type() != "DEBUG_FLOAT_ARRAY":
        return None
    name = _name(msg).rstrip("\x00")
    return {READINGS_NAME: "readings", SCORE_NAME: "score"}.get(name)
