"""Lockstep: the SITL's time waits at each radio frame for the flight computer's decision.

The vehicle side over real MAVLink on loopback (the server in this process, stepped by hand), and
whole flights of the shipped map policy through `uavlink fly --lockstep`.
"""

from __future__ import annotations

import json
import shlex
import time
from typing import Any

import pytest
from support.cli import ROOT, assert_user_error, cli_json, run_uavlink_in_process

import sitl_stub.sim.lockstep as lockstep
from sitl_stub import launcher
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import PayloadOptions
from sitl_stub.sim.radio_payload import RadioPayload
from uavlink.mavlink import radio_codec
from uavlink.mavlink.dialect import mavutil

mavlink = mavutil.mavlink
MAP_NO_MOVE = str(ROOT / "policies/map/no_move.zip")


def _offboard_server(in_lockstep: bool = True) -> tuple[SitlServer, RadioPayload, Any]:
    """A vehicle in OFFBOARD at t = 0 (its one setpoint lasts: COM_OF_LOSS_T 60 s) and a ground
    station that has spoken to it."""
    payload = RadioPayload(PayloadOptions(scenario="no_move", seed=3, lockstep=in_lockstep))
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", params={"COM_OF_LOSS_T": 60.0}), [payload]
    )
    server.open()
    host, port = server.address
    gcs = mavutil.mavlink_connection(
        f"udpout:{host}:{port}", source_system=255, source_component=190
    )
    gcs.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    _receive(server)
    v = server.vehicle
    v.offer_setpoint(0.0, 0.0, -10.0)
    assert v.arm().ok and v.start_offboard().ok
    return server, payload, gcs


def _receive(server: SitlServer) -> None:
    time.sleep(0.05)  # loopback delivery
    server.receive(server.clock.wall())


def _frame_messages(gcs: Any) -> list[Any]:
    out = []
    while (m := gcs.recv_match(blocking=True, timeout=0.2)) is not None:
        if m.get_type() in ("LOCAL_POSITION_NED", "DEBUG_FLOAT_ARRAY"):
            out.append(m)
    return out


def _is_readings(msg: Any) -> bool:
    name = msg.name.decode() if isinstance(msg.name, bytes) else msg.name
    return name == radio_codec.READINGS_NAME


def test_time_waits_at_each_frame_until_it_is_decided() -> None:
    server, payload, gcs = _offboard_server()
    try:
        v = server.vehicle
        assert server._advance_to(5.0)  # frame 0 ticked in OFFBOARD: the episode starts, and holds
        assert v.t == 0.0 and payload.episodes.started
        assert server._advance_to(5.0) and v.t == 0.0  # still held: no decision yet
        gcs.mav.command_long_send(
            1,
            radio_codec.RADIO_COMPONENT_ID,
            radio_codec.FRAME_DECIDED_COMMAND,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        )
        _receive(server)
        assert server._advance_to(5.0)  # on to frame 1, held there
        assert v.t == pytest.approx(1.0, abs=1e-9)
        # the vehicle's position at the frame's instant goes out just before the frame's readings
        messages = _frame_messages(gcs)
        first_readings = next(
            i
            for i, m in enumerate(messages)
            if m.get_type() == "DEBUG_FLOAT_ARRAY" and m.array_id == 1
        )
        before = messages[first_readings - 1]
        assert before.get_type() == "LOCAL_POSITION_NED" and before.time_boot_ms == 1000
        # the readings say the vehicle waits: the flight needs no prediction of where it flew on
        (report,) = [
            radio_codec.decode_readings(m, int(m.data[0]))
            for m in messages
            if m.get_type() == "DEBUG_FLOAT_ARRAY" and m.array_id == 1 and _is_readings(m)
        ][:1]
        assert report.running and report.waits
        # a decision for an older frame does not let frame 1 go
        gcs.mav.command_long_send(
            1,
            radio_codec.RADIO_COMPONENT_ID,
            radio_codec.FRAME_DECIDED_COMMAND,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        )
        _receive(server)
        assert server._advance_to(5.0) and v.t == pytest.approx(1.0, abs=1e-9)
        assert payload.hold.timeouts == 0
    finally:
        gcs.close()
        server.close()


def test_a_fleets_timeouts_count_once_though_each_vehicle_reports_them() -> None:
    """`sitl-stub --fleet`'s stats: every vehicle's payload repeats the shared world's count."""
    view = {"uav": 0, "episode": 0, "lockstep_timeouts": 3}
    stats = {
        "vehicles": {str(i): {"payloads": {"200": {**view, "uav": i}}} for i in (1, 2, 3)},
        "world": {"episode": 0, "lockstep_timeouts": 3},
    }
    assert launcher.lockstep_timeouts(stats) == 3
    assert launcher.lockstep_timeouts({"vehicles": {}}) is None  # not in lockstep


def test_an_unanswered_frame_is_let_go_after_the_wall_wait(monkeypatch) -> None:
    server, payload, gcs = _offboard_server()
    try:
        assert server._advance_to(2.5)
        monkeypatch.setattr(lockstep, "LOCKSTEP_WAIT_WALL_S", 0.2)
        time.sleep(0.3)
        assert server._advance_to(2.5)  # frame 0 let go; frame 1 held anew
        assert server.vehicle.t == pytest.approx(1.0, abs=1e-9)
        assert payload.hold.timeouts == 1
        assert (
            server.report()["payloads"][str(radio_codec.RADIO_COMPONENT_ID)]["lockstep_timeouts"]
            == 1
        )
        # what `uavlink fly` reads from the line the vehicle prints on exit
        printed = f"sitl-stub: other\nsitl-stub: stats {json.dumps(server.report())}\n"
        assert launcher.lockstep_timeouts(launcher.exit_stats(printed) or {}) == 1
        assert launcher.exit_stats("sitl-stub: killed before its stats\n") is None
    finally:
        gcs.close()
        server.close()


def test_a_vehicle_that_leaves_offboard_is_not_held() -> None:
    """The flight computer switches to hold or land at its flight's end: the frame it will not
    decide is let go at once, not after the wall wait."""
    server, payload, gcs = _offboard_server()
    try:
        assert server._advance_to(2.5)
        assert server.vehicle.hold().ok
        assert not server._advance_to(2.5)
        assert server.vehicle.t == pytest.approx(2.5) and payload.hold.timeouts == 0
    finally:
        gcs.close()
        server.close()


def test_a_vehicle_not_in_lockstep_never_holds() -> None:
    server, payload, gcs = _offboard_server(in_lockstep=False)
    try:
        assert not server._advance_to(2.5)
        assert (
            server.vehicle.t == pytest.approx(2.5) and "lockstep_timeouts" not in payload.summary()
        )
        readings = [m for m in _frame_messages(gcs) if m.get_type() == "DEBUG_FLOAT_ARRAY"]
        readings = [m for m in readings if _is_readings(m)]
        running = [
            radio_codec.decode_readings(m, int(m.data[0])) for m in readings if m.array_id > 0
        ]
        assert running and all(r.running and not r.waits for r in running)
    finally:
        gcs.close()
        server.close()


def test_a_fleet_frame_waits_for_each_vehicle_flying_it() -> None:
    hold = lockstep.FrameHold()
    decided = [
        mavlink.MAVLink_command_long_message(
            1,
            radio_codec.RADIO_COMPONENT_ID,
            radio_codec.FRAME_DECIDED_COMMAND,
            0,
            k,
            0,
            0,
            0,
            0,
            0,
            0,
        )
        for k in (2, 3)
    ]
    hold.hold(3, {0, 2})  # vehicle 1 is not in OFFBOARD: not waited for
    assert hold.on_command(decided[0], 0) is None and hold.holding()  # frame 2's answer: too old
    hold.on_command(decided[1], 0)
    assert hold.holding() and hold.waiting == {2}
    hold.on_command(decided[1], 2)
    assert not hold.holding() and hold.timeouts == 0
    other = mavlink.MAVLink_command_long_message(
        1, radio_codec.RADIO_COMPONENT_ID, mavlink.MAV_CMD_DO_SET_SERVO, 0, 1, 1500, 0, 0, 0, 0, 0
    )
    assert hold.on_command(other) == mavlink.MAV_RESULT_UNSUPPORTED


def test_fly_refuses_lockstep_with_connect() -> None:
    proc = run_uavlink_in_process(
        "fly", "--policy", "static", "--lockstep", "--connect", "udp:14550"
    )
    assert_user_error(proc, "--lockstep", "sitl-stub --lockstep")


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_short_flight_of_a_field_model_says_why_it_has_no_replay(tmp_path) -> None:
    """The kriging rule plans over the episode's length, so 4 frames of a 128-frame episode are not
    a 4-frame episode: no replay command, and the summary says why (before: a bare null)."""
    flown = cli_json(
        "fly", "--out", str(tmp_path), "--json", "--no-picture", "--lockstep", "--policy",
        "kriging", "--scenario", "no_move", "--frames", "4", "--set",
        "radio.shadowing_model=spatial",
    )  # fmt: skip
    assert flown["completed"] and flown["replay"] is None
    assert "model of the field plans over the whole episode" in flown["no_replay_because"]
    assert "fly all 128 to replay it" in flown["no_replay_because"]


@pytest.mark.slow
@pytest.mark.timeout(240)
@pytest.mark.parametrize(("policy", "seed"), [(MAP_NO_MOVE, 0), ("kriging", 0)])
def test_a_lockstep_flight_replays_and_matches_the_px4_motion_evaluation(
    tmp_path, policy: str, seed: int
) -> None:
    """A searching flight (the map policy's; the kriging rule's, with the model of the field built in
    flight from LOCAL_POSITION_NED), twice at the same seed: the same throughput, equal to the
    summary's six decimals to `uavlink evaluate --episodes 1 --set uav_motion=px4` (the env moves
    the UAV as the vehicle does, to the bit, and rounds what the policy reads and the vehicle
    receives to float32 as MAVLink does; the map policy's target is 5 %)."""
    spatial = [] if policy == MAP_NO_MOVE else ["--set", "radio.shadowing_model=spatial"]
    flights = [
        cli_json(
            "fly",
            "--out",
            str(tmp_path / str(k)),
            "--json",
            "--no-picture",
            "--lockstep",
            "--policy",
            policy,
            "--scenario",
            "no_move",
            "--seed",
            str(seed),
            *spatial,
        )
        for k in range(2)
    ]
    replay = shlex.split(flights[0]["replay"])  # the command the flight's summary gives
    assert replay[:2] == ["uavlink", "evaluate"] and replay[-2:] == ["--set", "uav_motion=px4"]
    evaluated = cli_json(*replay[1:], "--json")["mean_rate_mbps"]
    flown = [f["mean_rate_mbps"] for f in flights]
    print(
        f"\n{policy} on no_move seed {seed}: flown in lockstep {flown} Mbps, evaluated (px4 motion) {evaluated:.6f}"
    )
    assert all(f["frames"] == 128 and f["decisions"] == 128 and f["completed"] for f in flights)
    # the vehicle waited for every decision (a timeout would part the two runs)
    assert [f["lockstep_timeouts"] for f in flights] == [0, 0]
    assert flown[0] == flown[1]
    assert abs(flown[0] - evaluated) <= 1e-6


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_fleet_flies_in_lockstep_and_replays(tmp_path) -> None:
    """Two vehicles of `sitl_stub --fleet 2 --lockstep`: every frame waits for both decisions, none
    times out, and the same seed flies the same throughput twice."""
    flights = [
        cli_json(
            "fly",
            "--out",
            str(tmp_path / str(k)),
            "--json",
            "--no-picture",
            "--lockstep",
            "--policy",
            "aoa",
            "--set",
            "n_uavs=2",
            "--scenario",
            "circular",
            "--frames",
            "30",
        )
        for k in range(2)
    ]
    assert all(f["frames"] == 30 and f["completed"] for f in flights)
    assert all(v["decisions"] == 30 for f in flights for v in f["vehicles"]), [
        f["vehicles"] for f in flights
    ]
    assert flights[0]["mean_rate_mbps"] == flights[1]["mean_rate_mbps"]
    # the vehicles' world waited for each decision; none timed out
    assert [f["lockstep_timeouts"] for f in flights] == [0, 0]


@pytest.mark.parametrize("late", [0, 2])
def test_the_line_after_a_flight_says_when_lockstep_did_not_hold(tmp_path, late: int) -> None:
    from uavlink.flight.result import flown_line

    summary = {
        "frames": 128,
        "scenario": "no_move",
        "policy": "aoa",
        "mean_rate_mbps": 8.1,
        "latency_ms_p50": 1.0,
        "latency_ms_p99": 2.0,
        "tlog": "flight.tlog",
        "lockstep_timeouts": late,
    }
    line = flown_line(summary, tmp_path)
    assert ("2 frame(s) went on without a decision" in line) == (late == 2), line
    assert "mean UE throughput 8.1 Mbps" in line


@pytest.mark.parametrize(
    ("connect", "held", "hint"),
    [
        ("embedded sitl_stub", 3, True),
        ("embedded sitl_stub", 0, False),
        ("udpin:0.0.0.0:14540", 3, False),
    ],
)
def test_the_line_after_a_flight_says_when_an_embedded_vehicle_could_not_wait(
    tmp_path, connect: str, held: int, hint: bool
) -> None:
    """An embedded vehicle that fell back to hold waiting for setpoints (a machine too slow for the
    speed factor) gets the fix in the line: fly slower or in lockstep; a vehicle you connect to (in
    real time, where a hold is the operator's or a link's) does not."""
    from uavlink.flight.result import flown_line

    summary = {
        "frames": 128,
        "scenario": "no_move",
        "policy": "aoa",
        "mean_rate_mbps": 8.1,
        "latency_ms_p50": 40.0,
        "latency_ms_p99": 56.0,
        "tlog": "flight.tlog",
        "connect": connect,
        "speed_factor": 20.0,
        "offboard_reentries": held,
    }
    line = flown_line(summary, tmp_path)
    assert ("fell back to hold 3 time(s)" in line) == hint, line
    assert ("a vehicle waits 50 ms): fly slower (--speed 5) or in --lockstep" in line) == hint, line
