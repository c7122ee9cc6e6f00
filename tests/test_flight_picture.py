"""Flight pictures: flight.png after `uavlink fly`, `uavlink plot FLIGHT.tlog [--gif]` on logs written
by fly, by MAVProxy, without radio messages and damaged; the UE truth (ADSB_VEHICLE) reaches the
ground but never the flight loop."""

from __future__ import annotations

import io
import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from support.cli import assert_user_error, cli_json, run_uavlink_in_process
from support.mavlink_gcs import FAST_CLIMB_PARAMS, FAST_TAKEOFF
from support.mavproxy_console import MAVPROXY, mavproxy

from sitl_stub.__main__ import build_parser
from sitl_stub.launcher import vehicle_process
from sitl_stub.mavlink.server import ServerConfig, SitlServer
from sitl_stub.sim.payload import PayloadOptions
from sitl_stub.sim.radio_payload import RadioPayload
from uavlink.config import EnvConfig
from uavlink.flight.link import VehicleLink
from uavlink.flight.loop import LoopConfig, PolicyPilot, fly_vehicle
from uavlink.flight.radio_source import MavlinkRadioSource
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink, mavutil
from uavlink.mavlink.geo import GeoOrigin
from uavlink.mavlink.radio_codec import RADIO_COMPONENT_ID
from uavlink.mavlink.ue_truth import decode_ue_fix
from uavlink.plot.tlog import _records, read_flight
from uavlink.policies.registry import make_baseline

PICTURE_PX = (760, 1040)


def png_pixels(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB"))


def plot_json(*args: str) -> dict:
    proc = run_uavlink_in_process("plot", *args, "--json")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


# ------------------------------------------------------------------ the truth's encoding (fast)
class _Recorder:
    """The payload's MAVLink sender, as real pymavlink encoders into one byte stream."""

    def __init__(self) -> None:
        self.buf = io.BytesIO()
        self.mav = mavlink.MAVLink(self.buf, srcSystem=1, srcComponent=RADIO_COMPONENT_ID)

    def __getattr__(self, name: str):
        return getattr(self.mav, name)

    def messages(self) -> list:
        parser = mavlink.MAVLink(None)
        return parser.parse_buffer(self.buf.getvalue()) or []


@pytest.mark.parametrize("truth", [True, False])
def test_radio_payload_sends_each_ue_as_adsb_vehicle_unless_switched_off(truth: bool) -> None:
    home = GeoOrigin(47.4, 8.5, 400.0)
    payload = RadioPayload(PayloadOptions("circular", 3, home=home, ue_truth=truth))
    state = SitlServer(ServerConfig(connect="udpin:127.0.0.1:0")).vehicle.state()
    out = _Recorder()
    payload.on_frame(0.0, state, out)
    fixes = [decode_ue_fix(m) for m in out.messages() if m.get_type() == "ADSB_VEHICLE"]
    if not truth:
        assert fixes == []
        return
    ue_xy = payload.episodes.world.ue_xy_m()
    assert [f.ue for f in fixes] == list(range(len(ue_xy))) == list(range(10))
    for fix, (east, north) in zip(fixes, ue_xy, strict=True):
        got_n, got_e = home.to_local(fix.lat_deg, fix.lon_deg)
        assert abs(got_e - east) < 0.02 and abs(got_n - north) < 0.02  # 1e-7 deg: about 1 cm


def test_sitl_stub_no_ue_truth_option_reaches_the_payload() -> None:
    assert build_parser().parse_args(["--no-ue-truth"]).no_ue_truth
    assert not build_parser().parse_args([]).no_ue_truth
    seen: list[PayloadOptions] = []
    from sitl_stub.__main__ import main

    for argv in (["--no-ue-truth"], []):
        main(
            [
                *argv,
                "--connect",
                f"udpout:127.0.0.1:{free_udp_port()}",
                "--duration-s",
                "0.01",
                "--speed",
                "100",
            ],
            payload_factory=lambda o: seen.append(o),
        )
    assert [o.ue_truth for o in seen] == [False, True]


def test_other_adsb_traffic_is_not_a_ue() -> None:
    plane = mavlink.MAVLink_adsb_vehicle_message(
        0xABCDEF, 473977420, 85455940, 1, 500000, 0, 0, 0, b"SWR123", 3, 0, 1 | 64, 0
    )  # an airliner
    assert decode_ue_fix(plane) is None


def test_a_log_cut_anywhere_reads_up_to_the_cut() -> None:
    """Two MAVLink 2 records, the second cut at every byte (a flight killed while writing, CI saw a
    cut inside a header): the first is read, the cut one is not, and nothing raises."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    packet = mav.local_position_ned_encode(1000, 1.0, 2.0, -95.0, 0.0, 0.0, 0.0).pack(mav)
    record = (123).to_bytes(8, "big") + packet
    for cut in range(len(record)):
        blob = record + record[:cut]
        got = list(_records(blob))
        assert [m.get_type() for m in got] == ["LOCAL_POSITION_NED"], cut
    assert len(list(_records(record + record))) == 2


def test_a_frame_is_a_decision_frame_when_offboard_shows_before_the_next_one(
    tmp_path: Path,
) -> None:
    """The heartbeat trails a mode change by up to its period: the first frame of the episode (in
    OFFBOARD on the vehicle, its heartbeat still LOITER in the log) is a decision frame; the frame
    after the vehicle was handed back is not (CI saw frame 0 dropped: 15 decision frames of 16)."""
    from uavlink.mavlink.px4_modes import (
        PX4_MAIN_AUTO,
        PX4_MAIN_OFFBOARD,
        PX4_SUB_AUTO_LOITER,
        encode_custom_mode,
    )
    from uavlink.mavlink.radio_codec import READINGS_NAME, encode_readings

    vehicle = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    radio = mavlink.MAVLink(None, srcSystem=1, srcComponent=RADIO_COMPONENT_ID)
    data = encode_readings(np.full(2, 10.0), np.zeros(2), running=True)

    def beat(main: int, sub: int = 0):
        return vehicle.heartbeat_encode(
            mavlink.MAV_TYPE_QUADROTOR,
            mavlink.MAV_AUTOPILOT_PX4,
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            encode_custom_mode(main, sub),
            4,
        )

    loiter, offboard = beat(PX4_MAIN_AUTO, PX4_SUB_AUTO_LOITER), beat(PX4_MAIN_OFFBOARD)
    log = [loiter]
    for frame, after in enumerate(
        [offboard, offboard, loiter, loiter]
    ):  # frames 0-3, then a heartbeat
        log += [
            vehicle.local_position_ned_encode(1000 * frame, 0.0, 0.0, -95.0, 0, 0, 0),
            radio.debug_float_array_encode(frame * 1_000_000, READINGS_NAME.encode(), frame, data),
            after,
        ]
    tlog = tmp_path / "flight.tlog"
    tlog.write_bytes(
        b"".join(
            (k).to_bytes(8, "big") + m.pack(vehicle if m.get_srcComponent() == 1 else radio)
            for k, m in enumerate(log)
        )
    )
    [track] = read_flight(tlog).vehicles
    assert track.frames[track.decided].tolist() == [0, 1]


def test_the_grounds_frame_decided_names_the_decision_frames_as_fly_counts_them(
    tmp_path: Path,
) -> None:
    """fly decides frames 0..N-1 and scores 1..N; frame N's readings arrive while the vehicle is
    still in OFFBOARD, but nobody decides them (FRAME_DECIDED param2 0): N decision frames, as fly's
    summary says (the OFFBOARD rule alone counted N + 1), drawn over frames 0..N with fly's mean."""
    from uavlink.mavlink.px4_modes import PX4_MAIN_OFFBOARD, encode_custom_mode
    from uavlink.mavlink.radio_codec import (
        READINGS_NAME,
        SCORE_NAME,
        encode_readings,
        encode_score,
        send_frame_decided,
    )

    n = 5
    vehicle = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    radio = mavlink.MAVLink(None, srcSystem=1, srcComponent=RADIO_COMPONENT_ID)
    ground = mavlink.MAVLink(io.BytesIO(), srcSystem=255, srcComponent=191)
    sent: list = []
    ground.set_send_callback(sent.append)
    data = encode_readings(np.full(2, 10.0), np.zeros(2), running=True)
    offboard = vehicle.heartbeat_encode(
        mavlink.MAV_TYPE_QUADROTOR,
        mavlink.MAV_AUTOPILOT_PX4,
        mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        encode_custom_mode(PX4_MAIN_OFFBOARD, 0),
        4,
    )
    records = [(vehicle, offboard)]
    for frame in range(n + 2):  # the vehicle stays in OFFBOARD two frames past the flight's
        records += [
            (vehicle, vehicle.local_position_ned_encode(1000 * frame, 0.0, 0.0, -95.0, 0, 0, 0)),
            (
                radio,
                radio.debug_float_array_encode(
                    frame * 1_000_000, READINGS_NAME.encode(), frame, data
                ),
            ),
        ]
        if frame:
            score = encode_score(np.full(2, frame * 1e6), 0.5)
            records.append(
                (
                    radio,
                    radio.debug_float_array_encode(
                        frame * 1_000_000, SCORE_NAME.encode(), frame, score
                    ),
                )
            )
        if frame <= n:
            send_frame_decided(ground, 1, frame, frame < n)
            records.append((None, sent[-1]))
        records.append((vehicle, offboard))
    tlog = tmp_path / "flight.tlog"
    tlog.write_bytes(
        b"".join(
            k.to_bytes(8, "big") + (bytes(m.get_msgbuf()) if mav is None else m.pack(mav))
            for k, (mav, m) in enumerate(records)
        )
    )
    data_read = read_flight(tlog)
    [track] = data_read.vehicles
    assert track.frames[track.decided].tolist() == list(range(n)) and data_read.decision_frames == n
    assert data_read.frames.tolist() == list(range(n + 1))  # the last decision's outcome, frame n
    assert np.nanmean(data_read.mean_rate_mbps) == pytest.approx(np.mean(range(1, n + 1)))


# ------------------------------------------------------------------ damaged, empty (fast)
def test_plot_refuses_empty_damaged_and_missing_logs(tmp_path: Path) -> None:
    empty = tmp_path / "empty.tlog"
    empty.write_bytes(b"")
    garbage = tmp_path / "garbage.tlog"
    garbage.write_bytes(np.random.default_rng(0).bytes(50_000))
    for path, fragment in (
        (empty, "empty file"),
        (garbage, "no MAVLink message could be read"),
        (tmp_path / "none.tlog", "no such file"),
    ):
        proc = run_uavlink_in_process("plot", str(path), "--out", str(tmp_path / "x.png"))
        assert_user_error(proc, str(path), fragment)
    assert not list(tmp_path.glob("*.png")) and not list(
        tmp_path.glob(".*")
    )  # nothing half-written


# ------------------------------------------------------------------ real flights (slow)
@pytest.mark.slow
@pytest.mark.timeout(240)
def test_fly_draws_its_picture_and_plot_draws_the_same(tmp_path: Path) -> None:
    # --lockstep: the vehicle waits for each frame's decision, so a loaded machine neither stalls the
    # offboard stream into HOLD nor hands the loop two frames at once (one observed, not decided)
    summary = cli_json(
        "fly", "--policy", "aoa", "--frames", "16", "--lockstep", "--out", str(tmp_path), "--json"
    )
    tlog, png = tmp_path / "flight.tlog", tmp_path / "flight.png"
    assert summary["picture"] == str(png) and summary["picture_s"] > 0
    drawn = plot_json(str(tlog), "--out", str(tmp_path / "again.png"))
    assert (drawn["width_px"], drawn["height_px"]) == PICTURE_PX
    assert drawn["tracks"] == 1 and drawn["ue_tracks"] == 10 and drawn["bearings"] == 10
    # the picture counts fly's decisions (frames 0-15), over frames 0-16 (the last one's outcome)
    assert drawn["decision_frames"] == summary["decisions"] == 16 and drawn["frame_span"] == [0, 16]
    assert drawn["frames"] == 17 and drawn["notes"] == []
    first, again = png_pixels(png), png_pixels(tmp_path / "again.png")
    assert first.shape == (PICTURE_PX[1], PICTURE_PX[0], 3) and np.array_equal(first, again)
    data = read_flight(tlog)  # what was drawn: the UEs in the area, the fence around it
    assert np.nanmax(np.abs(data.ue_east_m)) <= 200.0 and np.isfinite(data.ue_east_m).mean() > 0.9
    assert np.allclose(np.abs(data.fence_en_m), 202.0, atol=0.1)
    gif = plot_json(str(tlog), "--gif")
    assert gif["frames"] == drawn["decision_frames"] and gif["bytes"] < 400_000
    from PIL import Image

    with Image.open(tmp_path / "flight.gif") as im:
        assert im.format == "GIF" and im.n_frames == gif["frames"]


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_fleet_picture_one_colour_per_vehicle_ues_by_serving_uav(tmp_path: Path) -> None:
    # --speed 10: on a loaded machine two vehicles at 20x can miss their offboard streams
    summary = cli_json(
        "fly",
        "--policy",
        "aoa",
        "--set",
        "n_uavs=2",
        "--frames",
        "12",
        "--speed",
        "10",
        "--out",
        str(tmp_path),
        "--json",
    )
    assert summary["picture"] == str(tmp_path / "flight.png")
    data = read_flight(tmp_path / "flight.tlog")
    assert [v.system_id for v in data.vehicles] == [1, 2] and data.n_ues == 10
    serving = data.serving_uav()
    assert set(np.unique(serving)) <= {0, 1} and (serving >= 0).all()
    assert set(np.unique(serving)) == {0, 1}  # both cells hold UEs
    start = [np.hypot(v.east_m[0], v.north_m[0]) for v in data.vehicles]
    assert all(abs(r - EnvConfig().fleet_start_radius_m) < 5.0 for r in start)  # their spawn points
    drawn = plot_json(str(tmp_path / "flight.tlog"), "--out", str(tmp_path / "again.png"))
    assert drawn["tracks"] == 2 and drawn["ue_tracks"] == 10
    assert np.array_equal(png_pixels(tmp_path / "flight.png"), png_pixels(tmp_path / "again.png"))


class _SpySource(MavlinkRadioSource):
    """The flight loop's radio source, recording every message the link hands it."""

    def __init__(self, n_ues: int) -> None:
        super().__init__(n_ues)
        self.fed: list[str] = []

    def feed(self, msg) -> None:
        self.fed.append(
            f"{msg.get_type()}:{msg.name}"
            if msg.get_type() == "DEBUG_FLOAT_ARRAY"
            else msg.get_type()
        )
        super().feed(msg)


@pytest.mark.slow
@pytest.mark.timeout(90)
def test_flight_loop_never_receives_the_ue_truth(tmp_path: Path) -> None:
    """Over a real flight, the vehicle sends every UE as ADSB_VEHICLE from the radio payload's own
    component, and the observation builder still only ever gets UL_RADIO readings."""
    cfg = EnvConfig().replace(scenario="straight").validate()
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", speed=20.0, params=FAST_CLIMB_PARAMS),
        [RadioPayload(PayloadOptions("straight", 0))],
    ).start()
    pilot = PolicyPilot(make_baseline("aoa", cfg), cfg)
    observed: list[tuple] = []
    observe = pilot.observe
    pilot.observe = lambda report, *a: observed.append(type(report).__name__) or observe(report, *a)
    source = _SpySource(cfg.n_ues)
    link = None
    try:
        host, port = server.address
        link = VehicleLink(f"udpout:{host}:{port}", tlog=tmp_path / "flight.tlog")
        done: dict = {}
        t = threading.Thread(
            target=lambda: done.setdefault(
                "r",
                fly_vehicle(link, pilot, cfg, LoopConfig(frames=8, land=False), radio=source),
            ),
            daemon=True,
        )
        t.start()
        t.join(60)
        assert "r" in done, "the flight did not finish"
    finally:
        if link is not None:
            link.close()
        server.stop()
    log = mavutil.mavlogfile(str(tmp_path / "flight.tlog"))
    truth = 0
    while (m := log.recv_match(type="ADSB_VEHICLE")) is not None:
        truth += m.get_srcComponent() == RADIO_COMPONENT_ID and decode_ue_fix(m) is not None
    log.close()
    assert truth >= 8 * cfg.n_ues  # the link heard the truth, every frame
    assert source.fed and set(source.fed) == {"DEBUG_FLOAT_ARRAY:UL_RADIO"}
    assert len(observed) >= 8  # every frame reached the builder, and only through that source


@pytest.mark.slow
@pytest.mark.timeout(90)
def test_plot_a_log_without_radio_messages_gives_the_tracks(tmp_path: Path, monkeypatch) -> None:
    """A vehicle without the radio payload, armed and taken off over a real link: tracks only; the
    same log cut mid-record still plots; without matplotlib fly would say how to get pictures."""
    server = SitlServer(
        ServerConfig(connect="udpin:127.0.0.1:0", speed=20.0, params=FAST_CLIMB_PARAMS)
    ).start()
    tlog = tmp_path / "flight.tlog"
    link = None
    try:
        host, port = server.address
        link = VehicleLink(f"udpout:{host}:{port}", tlog=tlog)
        link.wait_vehicle()
        link.arm()
        link.takeoff(10.0)
        link.wait_wall(lambda: False, 1.0)
    finally:
        if link is not None:
            link.close()
        server.stop()
    drawn = plot_json(str(tlog))
    assert drawn["tracks"] == 1 and drawn["ue_tracks"] == 0 and drawn["frames"] == 0
    assert any("no radio messages" in n for n in drawn["notes"])
    assert png_pixels(tmp_path / "flight.png").shape == (PICTURE_PX[1], PICTURE_PX[0], 3)
    cut = tmp_path / "cut.tlog"
    blob = tlog.read_bytes()
    cut.write_bytes(blob[: len(blob) // 2 + 7])  # a flight killed while writing
    assert plot_json(str(cut))["tracks"] == 1
    from uavlink.plot.command import picture_after_flight

    for name in ("matplotlib.figure", "matplotlib.backends.backend_agg"):
        monkeypatch.setitem(__import__("sys").modules, name, None)
    skipped = picture_after_flight(tlog, tmp_path / "none.png")
    assert (
        skipped["picture"] is None and "pip install 'uavlink[plot]'" in skipped["picture_skipped"]
    )


@pytest.mark.slow
@pytest.mark.timeout(240)
@pytest.mark.skipif(MAVPROXY is None, reason="mavproxy.py not installed")
def test_plot_a_mavproxy_session_log(tmp_path: Path) -> None:
    """The vehicle talks to MAVProxy, `uavlink fly` flies through MAVProxy's output; MAVProxy's own
    mav.tlog gives the picture: track, UEs, readings, fence."""
    p_master, p_out = free_udp_port(), free_udp_port()
    with (
        mavproxy(
            [
                f"--master=udp:127.0.0.1:{p_master}",
                f"--out=udpout:127.0.0.1:{p_out}",
                "--non-interactive",
            ],
            tmp_path,
            tmp_path / "mavproxy.out",
            typed=False,
        ),
        vehicle_process(
            f"udpout:127.0.0.1:{p_master}",
            10.0,
            list(FAST_TAKEOFF),
        ),
    ):
        flown = cli_json(
            "fly",
            "--connect",
            f"udpin:127.0.0.1:{p_out}",
            "--policy",
            "aoa",
            "--frames",
            "12",
            "--out",
            str(tmp_path / "fly"),
            "--no-picture",
            "--json",
        )
        time.sleep(1.0)  # MAVProxy writes its log behind the link
    assert flown["frames"] >= 10
    drawn = plot_json(str(tmp_path / "mav.tlog"), "--out", str(tmp_path / "mavproxy.png"))
    assert drawn["tracks"] == 1 and drawn["ue_tracks"] == 10 and drawn["frames"] >= 10
    assert drawn["decision_frames"] >= 6  # (a failsafe hold on a loaded machine costs a few)
    assert png_pixels(tmp_path / "mavproxy.png").shape == (PICTURE_PX[1], PICTURE_PX[0], 3)
