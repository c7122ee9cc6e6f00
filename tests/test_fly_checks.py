"""What a new user meets first in `uavlink fly`: bad numbers refused up front, the baselines that fly
named from one place, a vehicle that exits at start reported at once with its own error, a
`mixed` policy flying its seed's scenario, and a signed vehicle flown without the key said so."""

from __future__ import annotations

import contextlib
import io
import json
import shlex
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from support.cli import assert_user_error, cli_json, run_uavlink_in_process
from support.mavlink_gcs import FAST_TAKEOFF

from sitl_stub.launcher import VehicleExited, VehicleProcess, vehicle_process
from uavlink.cli import main
from uavlink.config import BASELINE_NAMES, EnvConfig
from uavlink.env.radio_world import episode_scenario
from uavlink.errors import UserError
from uavlink.flight.link import LinkError, VehicleLink
from uavlink.flight.loop import LoopConfig, timed_out
from uavlink.flight.result import EndedBy, FlightResult, judge, signing_hint
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.signing import SigningGuard, write_key
from uavlink.policies.registry import flying_baselines


# ------------------------------------------------------------------ numbers, refused up front (fast)
@pytest.mark.parametrize(
    "option,value,fragment",
    [
        ("--seed", "-1", "argument --seed: a seed must be an integer in 0..2147483647"),
        ("--seed", str(2**31), "argument --seed: a seed must be an integer in 0..2147483647"),
        ("--speed", "0", "--speed must be a number > 0"),
        ("--speed", "-3", "--speed must be a number > 0"),
        ("--speed", "nan", "--speed must be a number > 0"),
        ("--frames", "0", "--frames must be 1..128"),
        ("--frames", "-5", "--frames must be 1..128"),
        (
            "--frames",
            "129",
            "--frames must be 1..128",
        ),  # past the episode: the policy's clock and the replay end
    ],
)
def test_fly_refuses_bad_numbers_before_starting_or_writing_anything(
    tmp_path: Path, option: str, value: str, fragment: str
) -> None:
    out = tmp_path / "out"
    proc = run_uavlink_in_process("fly", "--policy", "aoa", option, value, "--out", str(out))
    assert_user_error(proc, "uavlink fly: error: ", fragment, value)
    assert not out.exists()  # made only once the checks pass, before the vehicle starts


def test_fly_refuses_several_urls_for_one_vehicle(tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = run_uavlink_in_process(
        "fly",
        "--policy",
        "aoa",
        "--connect",
        "udpin:127.0.0.1:14550,udpin:127.0.0.1:14551",
        "--out",
        str(out),
    )
    assert_user_error(proc, "uavlink fly: error: ", "--connect with several URLs is for a fleet")
    assert not out.exists()


def test_fly_refuses_a_speed_for_a_vehicle_it_connects_to(tmp_path: Path) -> None:
    """--speed sets the embedded SITL's clock: with --connect it did nothing, and said nothing."""
    out = tmp_path / "out"
    proc = run_uavlink_in_process(
        "fly", "--policy", "aoa", "--speed", "5", "--connect", "udpout:127.0.0.1:9", "--out",
        str(out),
    )  # fmt: skip
    assert_user_error(proc, "uavlink fly: error: ", "--speed sets the embedded SITL's clock")
    assert not out.exists()
    # The Python API refuses it as the command does (it flew on, the speed ignored).
    from uavlink.flight import FlyOptions

    with pytest.raises(UserError, match="--speed sets the embedded SITL's clock"):
        FlyOptions(connect="udpout:127.0.0.1:9", speed=5.0).validate()
    assert FlyOptions().embedded_speed == 20.0 and FlyOptions(speed=5.0).embedded_speed == 5.0


# ------------------------------------------------------------------ which baselines fly (fast)
def test_the_baselines_that_fly_are_those_that_read_no_truth_in_help_and_refusals(
    tmp_path: Path,
) -> None:
    assert {"static", "aoa", "explore", "kriging"} <= set(flying_baselines()) <= set(BASELINE_NAMES)
    assert not {"oracle", "kmeans", "genie"} & set(flying_baselines())
    out = io.StringIO()
    with pytest.raises(SystemExit), contextlib.redirect_stdout(out):
        main(["fly", "--help"])
    help_text = " ".join(out.getvalue().split())
    assert "FILE.zip | FILE.onnx | " + " | ".join(flying_baselines()) in help_text
    for privileged in ("oracle", "kmeans", "genie"):
        proc = run_uavlink_in_process(
            "fly", "--policy", privileged, "--out", str(tmp_path / privileged)
        )
        assert_user_error(
            proc, "cannot fly", "use a policy file or one of " + ", ".join(flying_baselines())
        )
        assert not (tmp_path / privileged).exists()


# ------------------------------------------------------------------ the vehicle's start (fast units)
def _child(tmp_path: Path, script: str) -> VehicleProcess:
    """A stand-in vehicle: a shell that prints what ``script`` says, its output in a log file."""
    log = tmp_path / "vehicle.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen(["sh", "-c", script], stdout=out, stderr=subprocess.STDOUT)
    return VehicleProcess(proc, log)


def test_wait_started_reports_a_vehicle_that_exited_with_its_own_last_line(tmp_path: Path) -> None:
    child = _child(
        tmp_path,
        "echo 'usage: sitl-stub [-h] ...'; echo 'sitl-stub: error: argument --x: bad' >&2; exit 2",
    )
    started = time.monotonic()
    with pytest.raises(VehicleExited) as caught:
        child.wait_started(30.0)
    assert time.monotonic() - started < 5.0  # at once, not after the 30 s a heartbeat would take
    assert (
        caught.value.status == 2 and caught.value.last_line == "sitl-stub: error: argument --x: bad"
    )
    assert str(caught.value) == "exited with status 2: sitl-stub: error: argument --x: bad"


def test_wait_started_returns_at_the_ready_line_or_after_the_timeout(tmp_path: Path) -> None:
    ready = _child(
        tmp_path, "echo 'sitl-stub: vehicle 1 on udpout:127.0.0.1:1, 20x real time'; sleep 5"
    )
    try:
        assert ready.wait_started(10.0) is True
    finally:
        ready.stop()
    silent = _child(tmp_path, "sleep 5")  # still importing on a loaded machine: the caller goes on
    try:
        assert silent.wait_started(0.3) is False
    finally:
        silent.stop()


# ------------------------------------------------------------------ signing mismatch (fast units)
def _heard(vehicle_key: bytes | None, ground_key: bytes | None) -> SimpleNamespace:
    """A ground link (as ``signing_hint`` reads it) that parsed one heartbeat of a vehicle."""
    vehicle = mavlink.MAVLink(None, 1, 1)
    if vehicle_key is not None:
        SigningGuard(vehicle_key).attach(vehicle)
    packet = vehicle.heartbeat_encode(2, 12, 0, 0, 4).pack(vehicle)
    ground, guard = mavlink.MAVLink(None, 255, 191), None
    ground.robust_parsing = True
    if ground_key is not None:
        guard = SigningGuard(ground_key)
        guard.attach(ground)
    ground.parse_buffer(packet)
    link = SimpleNamespace(conn=SimpleNamespace(mav=ground), signing=guard)
    link.unsigned_to_a_signing_vehicle = VehicleLink.unsigned_to_a_signing_vehicle.fget(link)
    return link


def test_signing_hint_says_how_the_link_and_the_vehicle_disagree() -> None:
    key, other = bytes(range(32)), bytes(32)
    assert (
        signing_hint(_heard(key, None))
        == "the vehicle signs its link: pass --signing-key FILE (its key)"
    )
    assert "with another key" in signing_hint(_heard(other, key))
    assert "does not sign its link" in signing_hint(_heard(None, key))
    assert signing_hint(_heard(None, None)) == signing_hint(_heard(key, key)) == ""  # they agree


def test_judge_puts_the_fix_in_place_of_check_the_vehicle_is_running() -> None:
    result = FlightResult(
        failure="no ACK for MAV_CMD_COMPONENT_ARM_DISARM after 10 tries",
        fix="the vehicle signs its link: pass --signing-key FILE (its key)",
    )
    judge(result, 128)
    assert not result.completed and result.reason == (
        "no ACK for MAV_CMD_COMPONENT_ARM_DISARM after 10 tries; the vehicle signs its link: pass "
        "--signing-key FILE (its key), then fly again"
    )
    plain = FlightResult(failure="link lost")
    judge(plain, 128)
    assert "check the vehicle is running and reachable" in plain.reason


def test_a_loop_ends_on_radio_silence_and_fails_on_a_silent_link() -> None:
    """One rule for both loops (one vehicle, a fleet): radio silence ends the episode, a silent
    link raises LinkError (which the judged result turns into its failure); within both limits the
    loop goes on."""
    loop_cfg = LoopConfig(radio_timeout_s=10.0, link_timeout_s=20.0)
    going = FlightResult()
    assert not timed_out(loop_cfg, going, 9.9, 19.9) and going.ended_by == ""
    quiet = FlightResult()
    assert timed_out(loop_cfg, quiet, 10.1, 0.0) and quiet.ended_by == EndedBy.NO_RADIO_REPORTS
    lost = FlightResult()
    with pytest.raises(LinkError, match="no message from any vehicle for 20 s"):
        timed_out(loop_cfg, lost, 0.0, 20.1, "any vehicle")
    assert lost.ended_by == EndedBy.LINK_LOST


# ------------------------------------------------------------------ real vehicles (slow)
@pytest.mark.slow
@pytest.mark.timeout(60)
def test_fly_reports_an_embedded_vehicle_that_exits_at_start_at_once(
    tmp_path: Path, monkeypatch
) -> None:
    """A vehicle that refuses its arguments: fly ends within seconds with the vehicle's own line,
    not after 30 s of waiting for a heartbeat."""
    import uavlink.flight.vehicles as vehicles

    given = vehicles.vehicle_args
    monkeypatch.setattr(
        vehicles, "vehicle_args", lambda *a, **k: [*given(*a, **k), "--scenario", "nowhere"]
    )
    started = time.monotonic()
    proc = run_uavlink_in_process("fly", "--policy", "aoa", "--frames", "3", "--out", str(tmp_path))
    assert (
        time.monotonic() - started < 25.0
    )  # not the 30 s heartbeat wait (a child's start under load: seconds)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    [line] = proc.stderr.strip().splitlines()
    assert line.startswith(
        "uavlink fly: error: the embedded vehicle (sitl-stub) exited with status 2: "
        "sitl-stub: error: argument --scenario: invalid choice: 'nowhere'"
    ), line
    assert str(tmp_path / "sitl.log") in line and not (tmp_path / "flight.tlog").exists()


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_mixed_policy_flies_its_seeds_scenario_and_matches_its_replay(tmp_path: Path) -> None:
    """`fly` of a mixed policy: the vehicle draws the episode's scenario from the seed as the
    evaluation does; the summary names it, and a lockstep flight matches its replay (`uavlink
    evaluate --episodes 1 --seed S`, px4 motion)."""
    seed = 1
    flown = cli_json(
        "fly",
        "--policy",
        "policies/mixed.zip",
        "--seed",
        str(seed),
        "--lockstep",
        "--out",
        str(tmp_path),
        "--json",
        "--no-picture",
    )
    expected = episode_scenario(EnvConfig().replace(scenario="mixed"), seed)
    assert flown["scenario"] == expected and flown["scenario_drawn_from"] == "mixed", flown
    assert flown["completed"] and flown["frames"] == 128
    stats = json.loads((tmp_path / "sitl.log").read_text().split("sitl-stub: stats ")[-1])
    assert stats["payloads"]["158"]["scenario"] == expected  # the vehicle flew that one
    replay = shlex.split(flown["replay"])
    assert replay[replay.index("--scenario") + 1] == "mixed" and replay[
        replay.index("--seed") + 1
    ] == str(seed)
    evaluated = cli_json(*replay[1:], "--json")["mean_rate_mbps"]
    print(
        f"\nmixed seed {seed} ({expected}): flown {flown['mean_rate_mbps']:.6f}, replay {evaluated:.6f} Mbps"
    )
    assert abs(flown["mean_rate_mbps"] - evaluated) <= 0.02 * evaluated


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_flies_the_envs_episode_by_default_and_replays_what_it_flew(tmp_path: Path) -> None:
    """Without --frames, one episode of the env's own length (here --set episode_frames=6); with
    fewer, the episode's first frames; each replay evaluates the frames flown."""
    flown = cli_json(
        "fly",
        "--policy",
        "aoa",
        "--set",
        "episode_frames=6",
        "--lockstep",
        "--out",
        str(tmp_path),
        "--json",
        "--no-picture",
    )
    assert flown["completed"] and flown["frames"] == flown["decisions"] == 6, flown
    replay = shlex.split(flown["replay"])
    assert "episode_frames=6" in replay
    evaluated = cli_json(*replay[1:], "--json")["mean_rate_mbps"]
    assert (
        abs(flown["mean_rate_mbps"] - evaluated) <= 1e-4 * evaluated
    )  # lockstep: float32 positions apart
    # --frames 5 flies the first 5 frames of a 128-frame episode; its replay, an episode that long
    short = cli_json(
        "fly",
        "--policy",
        "aoa",
        "--frames",
        "5",
        "--lockstep",
        "--out",
        str(tmp_path / "short"),
        "--json",
        "--no-picture",
    )
    replay = shlex.split(short["replay"])
    assert short["completed"] and short["frames"] == 5 and "episode_frames=5" in replay, short
    evaluated = cli_json(*replay[1:], "--json")["mean_rate_mbps"]
    assert abs(short["mean_rate_mbps"] - evaluated) <= 1e-4 * evaluated


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_fly_without_the_key_against_a_signed_vehicle_says_to_pass_it(tmp_path: Path) -> None:
    keyfile = write_key(tmp_path / "key")
    port = free_udp_port()
    args = ["--scenario", "straight", "--signing-key", str(keyfile), *FAST_TAKEOFF]
    with vehicle_process(f"udpout:127.0.0.1:{port}", 20.0, args):
        proc = run_uavlink_in_process(
            "fly",
            "--connect",
            f"udpin:127.0.0.1:{port}",
            "--policy",
            "aoa",
            "--frames",
            "3",
            "--out",
            str(tmp_path / "fly"),
            "--no-picture",
        )
    assert proc.returncode == 1, proc.stderr
    reason = json.loads((tmp_path / "fly" / "summary.json").read_text())["reason"]
    assert "the vehicle signs its link: pass --signing-key FILE" in reason, reason
    assert "check the vehicle is running" not in reason and reason in proc.stderr
    # the unanswered fence upload ends it (not a warning, then ten arm tries)
    assert (
        "geofence not uploaded" in reason and "the vehicle ignores our unsigned packets" in reason
    )
    assert "flying on" not in proc.stderr


def test_the_flight_loop_freezes_the_heap_and_unfreezes_it_after() -> None:
    """A full collection over a loaded policy stalls 0.2-0.4 s, longer than a vehicle at 20x waits for
    setpoints; frozen, it scans only what the flight allocates (benchmarks/gc_pause.py)."""
    import gc

    from uavlink.flight.steady import steady_heap

    assert gc.get_freeze_count() == 0
    with steady_heap():
        assert gc.get_freeze_count() > 1000
    assert gc.get_freeze_count() == 0
