"""The radio episodes a vehicle (or a fleet's shared world) serves: a fresh one for every flight.

A flight begins when the vehicle arms, as in PX4 (its logger's default SDLOG_MODE 0 writes one log
from arming to disarming; the battery simulator starts draining at arming). An arming that finds
the current episode started (its frames already flown) begins the next episode; one that finds it
still waiting keeps it, so a flight that armed but never reached OFFBOARD costs no episode. A fleet
begins a new episode when one of its vehicles arms while all the others are disarmed (or arm in
the same frame): the first vehicle of a new team flight, never one re-armed while the rest fly on.

Order: the vehicle started with ``--seed S`` serves episode 0 of seed S first (what
``uavlink evaluate --seed S --episodes 1`` flies), then episode 0 of seeds S+1, S+2, ...: the k-th
episode (from 0) is ``uavlink evaluate --seed S+k --episodes 1``. The evaluation stream's later
episodes cannot be replayed one at a time (the envs of a chunk are stepped together and share its
generators), episode 0 of a seed can.

The episode starts at the first frame tick that finds every vehicle in OFFBOARD (the mission): that
tick's readings are frame 0 and each later tick moves the UEs one frame. Until then the UEs wait at
their start and frame 0's readings are repeated, flagged as waiting, so arming and take-off take no
frames from the episode and draw nothing from its random streams.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from sitl_stub.core.modes import FlightMode
from sitl_stub.core.vehicle_state import VehicleState
from uavlink.config import SEED_MAX, EnvConfig, check_seed
from uavlink.env.radio_world import FrameScore, RadioWorld
from uavlink.mavlink.radio_codec import EPISODE_COUNT_NAME, EPISODE_SEED_NAME


class RadioEpisodes:
    """One episode of ``cfg`` (its ``n_uavs`` UAVs) at a time, the next begun by each flight."""

    def __init__(self, cfg: EnvConfig, seed: int) -> None:
        check_seed(seed)
        self.cfg, self.first_seed = cfg, seed
        self.count = 0  # episodes begun before this one
        self.world = RadioWorld(cfg, seed)
        self.begun = False  # this episode has been begun by an arming (or is flown without one)
        self.started = False
        self.frame_rates_mbps: list[float] = []  # this episode's truth per scored frame 1, 2, ...
        self._armings: list[int] | None = None

    @property
    def seed(self) -> int:
        """The evaluation seed whose episode 0 this episode is."""
        return self.first_seed + self.count

    def tick(self, states: Sequence[VehicleState]) -> FrameScore | None:
        """One frame with every UAV's vehicle state: begin a new episode when a flight begins,
        advance a running episode (its score), or start it when every vehicle is in OFFBOARD."""
        begins = self._flight_begins(states)
        if begins and self.started and self.seed < SEED_MAX:
            self.count += 1
            self.world = RadioWorld(self.cfg, self.seed)
            self.started, self.frame_rates_mbps = False, []
        self.begun = self.begun or begins
        if self.started:
            score = self.world.advance([[s.x_east_m, s.y_north_m] for s in states])
            self.frame_rates_mbps.append(score.mean_rate_mbps)
            return score
        self.started = all(s.mode is FlightMode.OFFBOARD for s in states)
        self.begun = self.begun or self.started
        return None

    def awaits_decision(self, states: Sequence[VehicleState]) -> bool:
        """The frame just ticked is one a flight computer decides: the episode runs, has frames
        left, and a vehicle flies it in OFFBOARD (what a lockstep world holds for)."""
        return (
            self.started
            and self.world.frame < self.cfg.episode_frames
            and any(s.mode is FlightMode.OFFBOARD for s in states)
        )

    def _flight_begins(self, states: Sequence[VehicleState]) -> bool:
        """A vehicle armed since the last tick, and every vehicle armed now armed since then: the
        first arming(s) of a flight, never a vehicle re-armed while others fly on."""
        armings = [s.armings for s in states]
        before, self._armings = self._armings or armings, armings
        rose = [now > then for now, then in zip(armings, before, strict=True)]
        return any(rose) and all(r or not s.armed for r, s in zip(rose, states, strict=True))

    def send_episode(self, mav: Any, sim_time_s: float) -> None:
        """The episode's two NAMED_VALUE_INT (``uavlink.mavlink.radio_codec``)."""
        ms = int(sim_time_s * 1e3) & 0xFFFFFFFF
        mav.named_value_int_send(ms, EPISODE_SEED_NAME.encode(), self.seed)
        mav.named_value_int_send(ms, EPISODE_COUNT_NAME.encode(), self.count)

    def summary(self) -> dict[str, Any]:
        """Vehicle-side truth of the current episode (whatever the link lost): mean UE rate over
        its first ``episode_frames`` frames, which episode it is and its scenario (``mixed``
        draws one per episode), and ``episodes``: how many flights have begun one since start (0
        before the first arming; the episode then waiting is ``episode_seed``'s, the next flight's).
        ``UL_EPISODE`` (``count``) is the current episode's index, what ``uavlink fly`` reads."""
        rates = self.frame_rates_mbps[: self.cfg.episode_frames]
        return {
            "frames": len(rates),
            "frames_total": len(self.frame_rates_mbps),
            "mean_rate_mbps": round(sum(rates) / len(rates), 6) if rates else None,
            "episode_seed": self.seed,
            "episodes": self.count + int(self.begun),
            "scenario": self.world.scenario,
        }
