"""MAVLink 2 signing end to end: the key file, the verifier, the vehicle, and a signed flight.

The vehicle (``python -m sitl_stub --signing-key``) must ignore, without an ACK, every packet that
is unsigned, signed with another key, replayed, or forged with a future timestamp, and count them;
a stock pymavlink ground station with the key (``setup_signing``) must still command it.
"""

from __future__ import annotations

import itertools
import json
import os
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.cli import run_uavlink_in_process
from support.mavlink_gcs import (
    FAST_TAKEOFF,
    Gcs,
    param_args,
    parse_vehicle_stats,
    wait_for_vehicle,
)

from sitl_stub.launcher import vehicle_process
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink
from uavlink.mavlink.signing import (
    NEW_STREAM_WINDOW_TICKS,
    TICKS_PER_S,
    SigningGuard,
    load_key,
    packet_timestamp,
    signing_timestamp,
    write_key,
)

ROOT = Path(__file__).resolve().parents[1]
UAVLINK = [sys.executable, "-m", "uavlink.cli"]
ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
SET_MODE = mavlink.MAV_CMD_DO_SET_MODE
ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
LOITER = 4 << 16 | 3 << 24
TAKEOFF = 4 << 16 | 2 << 24
LAND = 4 << 16 | 6 << 24
OFFBOARD = 6 << 16
FORCE = 21196
# The operator takes over while the vehicle is still landing after the flight: fly writes its report
# before it exits, which on a loaded machine outlasted the default landing from 95 m (about 70 s
# sim, 3.5 s wall at 20x). This one lasts 340 s sim, 17 s wall.
SLOW_LANDING = param_args({"MPC_Z_VEL_MAX_DN": 0.5, "MPC_LAND_ALT2": 50, "MPC_LAND_SPEED": 0.2})


class _Wire:
    """A file-like sink for pymavlink's encoder."""

    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def write(self, buf: bytes) -> None:
        self.packets.append(bytes(buf))


def _endpoint(key: bytes | None, sysid: int, compid: int, clock=time.time):
    mav = mavlink.MAVLink(_Wire(), sysid, compid)
    mav.robust_parsing = True
    guard = None
    if key is not None:
        guard = SigningGuard(key, clock=clock)
        guard.attach(mav)
    return mav, guard


def _arm_packet(mav) -> bytes:
    mav.command_long_send(1, 1, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
    return mav.file.packets[-1]


# ------------------------------------------------------------------------------- unit level
@pytest.mark.slow
def test_keygen_writes_a_private_32_byte_key_and_never_overwrites(tmp_path: Path) -> None:
    out = tmp_path / "vehicle.key"
    r = subprocess.run(
        [*UAVLINK, "keygen", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stderr
    assert len(out.read_bytes()) == 32 and stat.S_IMODE(out.stat().st_mode) == 0o600
    key = out.read_bytes()
    again = subprocess.run(
        [*UAVLINK, "keygen", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )
    assert again.returncode == 2 and "refusing to overwrite" in again.stderr
    assert out.read_bytes() == key
    nowhere = subprocess.run(
        [*UAVLINK, "keygen", "--out", str(tmp_path / "none" / "k.key")],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
    )
    assert nowhere.returncode == 2 and "does not exist (create it first)" in nowhere.stderr
    assert "Traceback" not in nowhere.stderr and not (tmp_path / "none").exists()
    assert write_key(tmp_path / "other.key").read_bytes() != key  # os.urandom, not a constant
    short = tmp_path / "short.key"
    short.write_bytes(b"x" * 16)
    with pytest.raises(ValueError, match="16 bytes"):
        load_key(short)
    for cmd in (
        [sys.executable, "-m", "sitl_stub", "--signing-key", str(short)],
        [*UAVLINK, "fly", "--signing-key", str(short), "--policy", "static"],
    ):
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=60, cwd=ROOT)
        assert r.returncode == 2 and "32 raw bytes" in r.stderr and "Traceback" not in r.stderr


def test_an_empty_key_name_is_refused_on_both_ends_not_read_as_no_key() -> None:
    """`--signing-key "$KEY"` with KEY unset: before, both ends flew an unsigned link and said
    nothing; now each refuses in one line before anything starts."""
    fly = run_uavlink_in_process("fly", "--policy", "static", "--frames", "1", "--signing-key", "")
    assert fly.returncode == 2 and "--signing-key: an empty file name" in fly.stderr
    assert len(fly.stderr.strip().splitlines()) == 1 and "Traceback" not in fly.stderr
    vehicle = subprocess.run(
        [sys.executable, "-m", "sitl_stub", "--signing-key", "", "--duration-s", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert vehicle.returncode == 2 and "--signing-key: an empty file name" in vehicle.stderr
    assert len(vehicle.stderr.strip().splitlines()) == 1 and vehicle.stdout == ""


def test_verifier_refuses_unsigned_wrong_key_replay_and_stale_streams() -> None:
    key = os.urandom(32)
    rx, guard = _endpoint(key, 1, 1)
    tx, _ = _endpoint(key, 245, 190)
    pkt = _arm_packet(tx)
    assert rx.parse_char(pkt).get_type() == "COMMAND_LONG"
    assert rx.parse_char(pkt).get_type() == "BAD_DATA"  # the same packet again: a replay
    plain, _ = _endpoint(None, 245, 190)
    assert rx.parse_char(_arm_packet(plain)).get_type() == "BAD_DATA"
    other, _ = _endpoint(os.urandom(32), 245, 191)
    assert rx.parse_char(_arm_packet(other)).get_type() == "BAD_DATA"
    # a new stream (component 192) signed with the key but 2 minutes old: an old capture
    old, _ = _endpoint(key, 245, 192, clock=lambda: time.time() - 120)
    assert rx.parse_char(_arm_packet(old)).get_type() == "BAD_DATA"
    # ... while one 30 s old is accepted (MAVLink's 60 s window for new streams)
    recent, _ = _endpoint(key, 245, 193, clock=lambda: time.time() - 30)
    assert rx.parse_char(_arm_packet(recent)).get_type() == "COMMAND_LONG"
    assert guard.stats() == {
        "accepted": 2,
        "rejected_unsigned": 1,
        "rejected_bad_signature": 1,
        "rejected_replay": 1,
        "rejected_stale_stream": 1,
    }


def test_forged_future_timestamp_does_not_block_the_stream() -> None:
    """pymavlink records a stream's timestamp before checking the signature, so one forged
    packet blocks the genuine sender; our verifier checks first."""
    key = os.urandom(32)
    tx, _ = _endpoint(key, 245, 190)
    first = _arm_packet(tx)
    forged = bytearray(first)
    forged[-12:-6] = (packet_timestamp(first) + 3600 * TICKS_PER_S).to_bytes(6, "little")

    stock = mavlink.MAVLink(_Wire(), 1, 1)  # pymavlink's own verification
    stock.robust_parsing = True
    stock.signing.secret_key = key
    stock.signing.timestamp = signing_timestamp()
    ours, guard = _endpoint(key, 1, 1)
    for rx in (stock, ours):
        assert rx.parse_char(first).get_type() == "COMMAND_LONG"
        assert rx.parse_char(bytes(forged)).get_type() == "BAD_DATA"
    genuine = _arm_packet(tx)
    assert stock.parse_char(genuine).get_type() == "BAD_DATA", "pymavlink's flaw is gone?"
    assert ours.parse_char(genuine).get_type() == "COMMAND_LONG"
    assert guard.rejected["bad_signature"] == 1 and guard.rejected["replay"] == 0


def test_signing_clock_tracks_wall_time() -> None:
    now = [1.7e9]
    tx, _ = _endpoint(os.urandom(32), 245, 190, clock=lambda: now[0])
    a = packet_timestamp(_arm_packet(tx))
    b = packet_timestamp(_arm_packet(tx))
    assert a == signing_timestamp(now[0]) and b == a + 1  # strictly rising within a burst
    now[0] += 600.0  # ten minutes later: pymavlink alone would still be at a + 2
    c = packet_timestamp(_arm_packet(tx))
    assert c == signing_timestamp(now[0]) and c - a > NEW_STREAM_WINDOW_TICKS


# ---------------------------------------------------------------------------- the vehicle
@pytest.mark.slow
@pytest.mark.timeout(60)
def test_vehicle_obeys_only_fresh_packets_signed_with_its_key(tmp_path: Path) -> None:
    keyfile = write_key(tmp_path / "k")
    key = keyfile.read_bytes()
    port = free_udp_port()
    args = ["--no-payload", "--signing-key", str(keyfile), "--param", "MIS_TAKEOFF_ALT=5"]
    with vehicle_process(f"udp:127.0.0.1:{port}", 10.0, args) as vehicle:
        good = Gcs(port, 245, 190, key=key)
        unsigned = Gcs(port, 246, 190)
        wrong = Gcs(port, 247, 190, key=os.urandom(32))
        try:
            wait_for_vehicle(good, vehicle)
            unsigned.pump(0.2)
            wrong.pump(0.2)
            # without the key: no ACK and no effect, for arm, mode, parameters
            for gcs in (unsigned, wrong):
                assert gcs.command(ARM, 1, wait_s=0.8) is None
                assert gcs.command(SET_MODE, 1, 4, 2, wait_s=0.5) is None
                gcs.mav.param_set_send(1, 0, b"COM_OF_LOSS_T", 30.0, mavlink.MAV_PARAM_TYPE_REAL32)
            good.pump(0.3)
            assert good.mode == (LOITER, False)
            good.mav.param_request_read_send(1, 0, b"COM_OF_LOSS_T", -1)
            assert good.wait_message("PARAM_VALUE").param_value == pytest.approx(1.0)
            assert any("Signing: rejected" in t for t in good.texts)

            # with the key: arm (captured for a replay), mode change, disarm
            msg = good.mav.command_long_encode(1, 0, ARM, 0, 1, 0, 0, 0, 0, 0, 0)
            captured = msg.pack(good.mav)
            good.conn.write(captured)
            good.wait(lambda: good.acks_for(ARM), 3.0, "ACK of the signed arm")
            assert good.acks_for(ARM)[-1].result == ACCEPTED
            good.wait(lambda: good.mode == (LOITER, True), 3.0, "armed heartbeat")
            assert good.command(ARM, 0) == ACCEPTED
            good.wait(lambda: good.mode == (LOITER, False), 3.0, "disarmed heartbeat")

            # a replay of the captured, correctly signed arm is refused
            good.acks.clear()
            good.conn.write(captured)
            good.pump(0.8)
            assert good.acks_for(ARM) == [] and good.mode == (LOITER, False)

            # a forged packet on our stream with a future timestamp does not block it
            forged = bytearray(captured)
            forged[-12:-6] = (packet_timestamp(captured) + 3600 * TICKS_PER_S).to_bytes(6, "little")
            good.conn.write(bytes(forged))
            good.pump(0.3)
            assert good.command(ARM, 1) == ACCEPTED
            assert good.command(SET_MODE, 129, 4, 2) == ACCEPTED  # AUTO.TAKEOFF
            good.wait(lambda: (TAKEOFF, True) in [m[1:] for m in good.modes], 3.0, "takeoff mode")
            assert unsigned.command(ARM, 0, FORCE, wait_s=0.5) is None  # no kill from outside
            assert good.command(mavlink.MAV_CMD_NAV_LAND) == ACCEPTED
            good.wait(lambda: (LAND, True) in [m[1:] for m in good.modes], 3.0, "land mode")
            assert unsigned.acks == [] and wrong.acks == []
        finally:
            for gcs in (good, unsigned, wrong):
                gcs.close()
        vehicle.stop()
        output = vehicle.output()
    signing = parse_vehicle_stats(output)["signing"]
    assert signing["rejected_unsigned"] >= 3 and signing["rejected_bad_signature"] >= 4
    assert signing["rejected_replay"] >= 1 and signing["accepted"] >= 6
    assert output.count("signing: refused unsigned packet") == 1  # counted always, logged once


# ------------------------------------------------------------------------ a signed flight
@pytest.mark.slow
@pytest.mark.timeout(90)
def test_signed_flight_ignores_ground_stations_without_the_key(tmp_path: Path) -> None:
    keyfile = write_key(tmp_path / "k")
    key = keyfile.read_bytes()
    port = free_udp_port()
    frames = 40
    args = [
        *("--scenario", "straight", "--seed", "2", "--signing-key", str(keyfile)),
        *FAST_TAKEOFF,
        *SLOW_LANDING,
    ]
    with vehicle_process(f"udp:127.0.0.1:{port}", 20.0, args) as vehicle:
        attackers = [Gcs(port, 246, 190), Gcs(port, 247, 190, key=os.urandom(32))]
        fly = subprocess.Popen(
            [
                *UAVLINK,
                "fly",
                "--no-picture",
                "--connect",
                f"udpout:127.0.0.1:{port}",
                "--signing-key",
                str(keyfile),
                "--policy",
                "aoa",
                "--scenario",
                "straight",
                "--seed",
                "2",
                "--frames",
                str(frames),
                "--out",
                str(tmp_path / "fly"),
                "--json",
                "--quiet",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
        )
        low_in_offboard, attacks, last = [], 0, 0.0
        try:
            deadline = time.monotonic() + 60
            while fly.poll() is None and time.monotonic() < deadline:
                for a in attackers:
                    a.pump(0.005)
                spy = attackers[0]
                if spy.mode == (OFFBOARD, True) and time.monotonic() - last > 0.1:
                    last = time.monotonic()
                    attacks += 1
                    for a in attackers:  # disarm (forced), land, dive to a corner, retune
                        a.mav.command_long_send(1, 0, ARM, 0, 0, FORCE, 0, 0, 0, 0, 0)
                        a.mav.command_long_send(1, 0, SET_MODE, 0, 129, 4, 6, 0, 0, 0, 0)
                        a.mav.set_position_target_local_ned_send(
                            0,
                            1,
                            0,
                            mavlink.MAV_FRAME_LOCAL_NED,
                            0xDF8,
                            -195,
                            -195,
                            -5,
                            0,
                            0,
                            0,
                            0,
                            0,
                            0,
                            0,
                            0,
                        )
                        a.mav.param_set_send(
                            1, 0, b"MPC_XY_VEL_MAX", 0.5, mavlink.MAV_PARAM_TYPE_REAL32
                        )
                    pos = spy.last.get("LOCAL_POSITION_NED")
                    if pos is not None:
                        low_in_offboard.append(-pos.z)
            out, err = fly.communicate(timeout=30)
            for _ in range(10):
                for a in attackers:
                    a.pump(0.02)
        finally:
            if fly.poll() is None:
                fly.kill()
                fly.wait(10)
        assert fly.returncode == 0, err
        summary = json.loads(out)
        # the flight went on as if nobody else was there: every frame's report arrived and was
        # decided, except that on a loaded machine a frame can reach the loop in a backlog with the
        # next (then only the newest is decided; the other is undecided, counted as missed and as
        # stale, and goes into the memory): no report was lost
        missed = summary["radio_frames_missed"]
        assert summary["frames"] == frames and missed == summary["stale_radio_reports"], summary
        assert summary["decisions"] + summary["stale_radio_reports"] == frames, summary
        assert summary["decisions"] >= 0.9 * frames, summary
        assert (
            summary["ended_by"] == "episode done"
            and summary["signing"]["rejected_bad_signature"] == 0
        )
        assert attacks >= 10 and min(low_in_offboard) > 90.0
        offboard_at = next(t for t, mode, _ in attackers[0].modes if mode == OFFBOARD)
        during = [(mode, armed) for t, mode, armed in attackers[0].modes if t >= offboard_at]
        # OFFBOARD until fly itself ends the episode (hold, then land), armed all along; disarmed
        # only once landed (a slow test loop can hear the landed vehicle's disarm and hold)
        flown = list(itertools.takewhile(lambda mode_armed: mode_armed[1], during))
        assert flown[0] == (OFFBOARD, True) and flown[-1] == (LAND, True), during
        assert all(mode in (OFFBOARD, LOITER, LAND) for mode, _ in flown), during
        assert all(a.acks == [] for a in attackers)

        # the operator with the key can take over the (landing) vehicle; the others still cannot
        good = Gcs(port, 245, 190, key=key)
        try:
            wait_for_vehicle(good, vehicle)
            assert good.mode == (LAND, True)
            good.mav.param_request_read_send(1, 0, b"MPC_XY_VEL_MAX", -1)
            assert good.wait_message("PARAM_VALUE").param_value == pytest.approx(12.0)
            assert good.command(SET_MODE, 129, 4, 3) == ACCEPTED  # AUTO.LOITER
            good.wait(lambda: good.mode == (LOITER, True), 3.0, "hold on the operator's command")
            assert attackers[0].command(SET_MODE, 129, 4, 6, wait_s=0.5) is None
            good.pump(0.3)
            assert good.mode == (LOITER, True)
            assert good.command(mavlink.MAV_CMD_NAV_LAND) == ACCEPTED
        finally:
            good.close()
            for a in attackers:
                a.close()
        vehicle.stop()
        stats = parse_vehicle_stats(vehicle.output())
    assert stats["signing"]["rejected_unsigned"] >= attacks * 4
    assert stats["signing"]["rejected_bad_signature"] >= attacks * 4
    assert stats["vehicle"]["offboard_failsafes"] == 0


@pytest.mark.slow
@pytest.mark.timeout(60)
def test_a_flight_with_another_key_than_the_vehicles_fails_at_once(tmp_path: Path) -> None:
    """Every packet of a vehicle signing with another key fails its check: `fly` says so within
    seconds (it waited out the 30 s heartbeat wait before), with what to do."""
    ours, theirs = write_key(tmp_path / "ours"), write_key(tmp_path / "theirs")
    port = free_udp_port()
    with vehicle_process(f"udpout:127.0.0.1:{port}", 10.0, ["--signing-key", str(theirs)]):
        started = time.monotonic()
        proc = run_uavlink_in_process(
            "fly",
            "--no-picture",
            "--policy",
            "aoa",
            "--connect",
            f"udpin:127.0.0.1:{port}",
            "--signing-key",
            str(ours),
            "--frames",
            "3",
            "--out",
            str(tmp_path / "fly"),
        )
        elapsed = time.monotonic() - started
    assert proc.returncode == 1 and elapsed < 15.0, (elapsed, proc.stderr)
    assert "no heartbeat accepted from" in proc.stderr and "signed with another key" in proc.stderr
    assert "pass the key it was started with" in proc.stderr


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_a_signed_fleet_flight_reports_each_links_signing(tmp_path: Path) -> None:
    """`fly` of a fleet with a key (the embedded `sitl_stub --fleet 2` signs too): each vehicle's part
    of the summary says what its link accepted and refused, as one vehicle's summary does."""
    from support.cli import cli_json

    key = write_key(tmp_path / "fleet.key")
    flown = cli_json(
        "fly",
        "--policy",
        "aoa",
        "--set",
        "n_uavs=2",
        "--frames",
        "4",
        "--lockstep",
        "--signing-key",
        str(key),
        "--out",
        str(tmp_path / "fly"),
        "--json",
        "--no-picture",
    )
    assert flown["completed"] and [v["system_id"] for v in flown["vehicles"]] == [1, 2], flown
    for vehicle in flown["vehicles"]:
        assert vehicle["signing"]["accepted"] > 100 and vehicle["link_rejected"] == {}, vehicle
        assert not any(n for k, n in vehicle["signing"].items() if k.startswith("rejected_")), (
            vehicle
        )
