"""The radio episodes a long-lived vehicle serves: a new one per flight (an arming), in a documented
order of seeds, each the evaluation's episode 0 of its seed; and how `fly` judges a flight."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from sitl_stub.core.modes import FlightMode
from sitl_stub.flight.vehicle import Vehicle
from sitl_stub.sim.radio_episodes import RadioEpisodes
from uavlink.config import SEED_MAX, EnvConfig
from uavlink.env.radio_world import RadioWorld
from uavlink.flight.result import FlightResult, judge

CFG = EnvConfig().replace(scenario="straight").validate()
IDLE = Vehicle().state()  # disarmed on the ground, AUTO.LOITER


def _state(armings: int, armed: bool, mode: FlightMode = FlightMode.LOITER):
    return replace(IDLE, armings=armings, armed=armed, mode=mode)


def test_each_flight_after_a_started_episode_begins_the_next_seed() -> None:
    episodes = RadioEpisodes(CFG, 7)
    episodes.tick([IDLE])
    episodes.tick([_state(1, True)])  # the first flight arms: episode 0 of seed 7 is still waiting
    assert (episodes.seed, episodes.count, episodes.started) == (7, 0, False)
    episodes.tick([_state(1, True, FlightMode.OFFBOARD)])
    for _ in range(5):
        assert episodes.tick([_state(1, True, FlightMode.OFFBOARD)]) is not None
    assert episodes.world.frame == 5 and len(episodes.frame_rates_mbps) == 5
    episodes.tick([_state(1, False)])  # landed and disarmed: the episode is kept (no flight begun)
    assert episodes.seed == 7 and episodes.world.frame == 6
    episodes.tick([_state(2, True)])  # the next flight arms
    assert (episodes.seed, episodes.count, episodes.started, episodes.world.frame) == (
        8,
        1,
        False,
        0,
    )
    assert episodes.summary() == {
        "frames": 0,
        "frames_total": 0,
        "mean_rate_mbps": None,
        "episode_seed": 8,
        "episodes": 2,
        "scenario": "straight",
    }
    # what `uavlink evaluate --seed 8 --episodes 1` flies (tests/test_radio_world.py: RadioWorld is it)
    np.testing.assert_array_equal(
        episodes.world.readings().sinr_db, RadioWorld(CFG, 8).readings().sinr_db
    )


def test_an_arming_that_finds_the_episode_waiting_keeps_it() -> None:
    episodes = RadioEpisodes(CFG, 0)
    for armings in (1, 1, 2, 3):  # armed and disarmed without ever reaching OFFBOARD
        episodes.tick([_state(armings, armings % 2 == 1)])
    assert (episodes.seed, episodes.count) == (0, 0)


def test_a_rearm_within_one_frame_still_begins_a_flight() -> None:
    episodes = RadioEpisodes(CFG, 0)
    episodes.tick([_state(1, True, FlightMode.OFFBOARD)])
    episodes.tick([_state(1, True, FlightMode.OFFBOARD)])
    episodes.tick([_state(2, True)])  # disarmed and armed again between two ticks
    assert (episodes.seed, episodes.started) == (1, False)


def test_a_fleet_begins_an_episode_with_its_first_arming_only() -> None:
    cfg = CFG.replace(n_uavs=2).validate()
    episodes = RadioEpisodes(cfg, 0)
    offboard = _state(1, True, FlightMode.OFFBOARD)
    episodes.tick([offboard, offboard])
    episodes.tick([offboard, offboard])
    assert episodes.started and episodes.world.frame == 1
    episodes.tick(
        [offboard, _state(2, True)]
    )  # vehicle 2 re-armed while vehicle 1 flies: same episode
    assert episodes.seed == 0 and episodes.world.frame == 2
    episodes.tick([_state(1, False), _state(2, False)])
    episodes.tick([_state(2, True), _state(2, False)])  # a new team flight: vehicle 1 arms first
    assert (episodes.seed, episodes.started) == (1, False)
    episodes.tick([_state(2, True), _state(3, True)])  # vehicle 2 arms: no second new episode
    assert episodes.seed == 1
    episodes.tick([_state(2, True, FlightMode.OFFBOARD), _state(3, True, FlightMode.OFFBOARD)])
    assert episodes.started  # seed 1's episode runs
    episodes.tick([_state(2, False), _state(3, True)])  # vehicle 1 landed and disarmed, 2 landing
    assert episodes.seed == 1
    # vehicle 2 disarms and vehicle 1 arms within one frame (the ground saw the disarm, then armed)
    episodes.tick([_state(3, True), _state(3, False)])
    assert (episodes.seed, episodes.started) == (2, False)


def test_a_fleet_arming_together_begins_one_episode() -> None:
    episodes = RadioEpisodes(CFG.replace(n_uavs=2).validate(), 0)
    offboard = _state(1, True, FlightMode.OFFBOARD)
    episodes.tick([offboard, offboard])
    episodes.tick([_state(1, False), _state(1, False)])
    episodes.tick([_state(2, True), _state(2, True)])
    assert (episodes.seed, episodes.count) == (1, 1)


def test_episodes_in_the_summary_counts_those_begun_none_before_the_first_arming() -> None:
    """The exit stats' ``episodes``: 0 until a flight begins one (the waiting episode is only
    served, not flown), then one more per flight that begins an episode; ``UL_EPISODE`` (``count``,
    what `uavlink fly` copies) stays the current episode's index."""
    episodes = RadioEpisodes(CFG, 3)
    for _ in range(3):
        episodes.tick([IDLE])
    assert (episodes.summary()["episodes"], episodes.summary()["episode_seed"], episodes.count) == (
        0,
        3,
        0,
    )
    episodes.tick([_state(1, True)])  # the first flight arms: it begins episode 0 (seed 3)
    assert (episodes.summary()["episodes"], episodes.count) == (1, 0)
    episodes.tick([_state(1, True, FlightMode.OFFBOARD)])
    episodes.tick([_state(1, False)])
    episodes.tick([_state(2, True)])  # the second flight begins episode 1 (seed 4)
    assert (episodes.summary()["episodes"], episodes.summary()["episode_seed"], episodes.count) == (
        2,
        4,
        1,
    )
    resumed = RadioEpisodes(
        CFG, 0
    )  # flown in OFFBOARD without an arming it saw: begun all the same
    resumed.tick([_state(0, True, FlightMode.OFFBOARD)])
    assert resumed.summary()["episodes"] == 1


def test_seeds_travel_as_int32() -> None:
    with pytest.raises(ValueError, match="0..2147483647"):
        RadioEpisodes(CFG, SEED_MAX + 1)


@pytest.mark.parametrize(
    "result,fragment",
    [
        (
            FlightResult(ended_by="episode done", first_frame=0, last_frame=130, met_start=True),
            None,
        ),
        (
            FlightResult(ended_by="episode done", first_frame=40, last_frame=130, resumed=True),
            None,
        ),
        (FlightResult(ended_by="no radio reports"), "no radio reports"),
        (
            FlightResult(ended_by="episode done", first_frame=217, last_frame=219),
            "already at frame 217",
        ),
        (
            FlightResult(ended_by="episode done", first_frame=3, last_frame=130),
            "already running (frame 3)",
        ),
        (
            FlightResult(
                ended_by="vehicle in AUTO.RTL", first_frame=0, last_frame=50, met_start=True
            ),
            "ended early, after frame 50: vehicle in AUTO.RTL",
        ),
        (
            FlightResult(failure="could not enter OFFBOARD within 20 s: refused"),
            "could not enter OFFBOARD",
        ),
        (FlightResult(interrupted=True, ended_by="interrupted"), "Ctrl-C"),
    ],
)
def test_a_flight_is_complete_only_when_it_flew_the_frames_it_set_out_to(result, fragment) -> None:
    judge(result, 128)
    assert result.completed is (fragment is None)
    assert (fragment or "") in result.reason and (result.reason == "") is result.completed
    assert "\n" not in result.reason
