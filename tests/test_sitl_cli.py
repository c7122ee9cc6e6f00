"""The sitl-stub command line as a user meets it: its help names every scenario it accepts, a
meaningless combination of flags is refused in one line, docs/guides/sitl.md's flag table and payload
hook match the code, and everything the vehicle prints (log lines included) starts with
``sitl-stub:`` while ``uavlink fly`` still finds its ready line."""

from __future__ import annotations

import dataclasses
import logging
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support.mavlink_gcs import Gcs, parse_vehicle_stats, wait_for_vehicle

from sitl_stub.__main__ import _LogFormat, build_parser, main
from sitl_stub.launcher import READY_LINE, VehicleProcess, vehicle_process
from sitl_stub.sim.payload import PayloadOptions
from uavlink.config import SCENARIO_NAMES
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavlink

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "guides" / "sitl.md").read_text()


def _one_line_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exited:
        main(argv)
    err = capsys.readouterr().err
    assert exited.value.code == 2 and "Traceback" not in err
    [line] = err.strip().splitlines()
    assert line.startswith("sitl-stub: error: "), line
    return line


def test_help_lists_every_scenario_the_cli_accepts(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["--help"])
    assert exited.value.code == 0
    shown = re.search(r"--scenario \{([^}]*)\}", capsys.readouterr().out)
    assert shown is not None
    assert shown.group(1).split(",") == list(SCENARIO_NAMES)  # uavlink.config's, in its order
    for scenario in SCENARIO_NAMES:
        assert build_parser().parse_args(["--scenario", scenario]).scenario == scenario


def test_version_is_the_distributions_as_uavlinks(capsys: pytest.CaptureFixture[str]) -> None:
    import uavlink

    with pytest.raises(SystemExit) as exited:
        main(["--version"])
    assert exited.value.code == 0
    assert capsys.readouterr().out == f"sitl-stub {uavlink.__version__}\n"


@pytest.mark.parametrize("extra", [[], ["--fleet", "2"]])
def test_lockstep_without_the_radio_payload_is_refused_in_one_line(capsys, extra) -> None:
    line = _one_line_error(capsys, ["--no-payload", "--lockstep", *extra])
    assert "--lockstep" in line and "--no-payload" in line


@pytest.mark.parametrize("extra", [["--no-payload"], ["--no-payload", "--fleet", "2"], []])
def test_a_bad_area_is_refused_with_or_without_the_payload(capsys, extra) -> None:
    # The vehicle's fence is the radio world's area: checked even when no payload uses the world.
    line = _one_line_error(capsys, [*extra, "--set", "area.half_width_m=-5"])
    assert "area.half_width_m must be positive" in line


def test_the_flag_table_documents_every_flag() -> None:
    first_cells = " ".join(
        row.split("|")[1]
        for row in DOC.splitlines()
        if row.startswith("| `-") or row.startswith("| (none)")
    )
    documented = set(re.findall(r"-{1,2}[a-z][a-z-]*", first_cells))
    for action in build_parser()._actions:
        if "-h" not in action.option_strings:
            assert documented & set(action.option_strings), f"{action.option_strings} has no row"
    assert "| `--lockstep` |" in DOC


def test_the_payload_options_sentence_names_the_class_fields() -> None:
    [named] = re.findall(r"`PayloadOptions\(([^)]*)\)`", DOC)
    assert named.split(", ") == [f.name for f in dataclasses.fields(PayloadOptions)]


def test_the_doc_names_every_kind_of_refused_mission_message() -> None:
    source = (ROOT / "sitl_stub" / "mavlink" / "mission_protocol.py").read_text()
    kinds = {f"mission_{m}_refused" for m in re.findall(r'self\._refuse\("(\w+)"', source)}
    assert kinds == {
        f"mission_{m}_refused" for m in ("count", "item", "request", "clear", "current")
    }
    stats_paragraph = DOC.split("Bad arguments print one line")[1].split("## Packages")[0]
    for kind in kinds:
        assert f"`{kind}`" in stats_paragraph


def test_log_lines_carry_the_programs_prefix() -> None:
    fmt = _LogFormat()

    def line(name: str, text: str) -> str:
        return fmt.format(logging.LogRecord(name, logging.WARNING, __file__, 1, text, (), None))

    assert line("sitl_stub", "rejected input: x") == "sitl-stub: rejected input: x"
    assert line("sitl_stub.sim.lockstep", "lockstep: frame 3") == "sitl-stub: lockstep: frame 3"
    assert line("pymavlink", "odd") == "sitl-stub: pymavlink: odd"
    try:
        raise ValueError("boom")
    except ValueError:
        record = logging.LogRecord(
            "sitl_stub", logging.ERROR, __file__, 1, "failed", (), sys.exc_info()
        )
    text = fmt.format(record)
    assert text.startswith("sitl-stub: failed\nTraceback") and "ValueError: boom" in text
    assert not READY_LINE.match(line("sitl_stub", "vehicle 1 armed"))


def test_a_log_line_before_the_ready_line_is_not_taken_for_it(tmp_path: Path) -> None:
    log, go = tmp_path / "vehicle.log", tmp_path / "go"
    # the ready line only once the test says so (the flag file): no race with a loaded machine
    script = (
        "echo 'sitl-stub: rejected input: bad MAVLink data (counted as bad_data; logged once)'; "
        f"while [ ! -e {go} ]; do sleep 0.05; done; echo 'sitl-stub: fleet of 2 vehicles (one shared "
        "radio world) on udpout:127.0.0.1:1, udpout:127.0.0.1:2, 20x real time, 1 payload(s), "
        "signing off'; sleep 5"
    )
    with open(log, "wb") as out:
        proc = subprocess.Popen(["sh", "-c", script], stdout=out, stderr=subprocess.STDOUT)
    child = VehicleProcess(proc, log)
    try:
        deadline = time.monotonic() + 10.0
        while "rejected input" not in log.read_text() and time.monotonic() < deadline:
            time.sleep(0.02)
        assert "rejected input" in log.read_text()
        assert child.wait_started(0.2) is False  # the log line is there, the ready line not yet
        go.touch()
        assert child.wait_started(10.0) is True
    finally:
        child.stop()


@pytest.mark.slow
@pytest.mark.timeout(90)
def test_a_refused_mission_item_is_logged_and_counted_and_every_line_has_one_prefix() -> None:
    """RTL in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: MISSION_ACK UNSUPPORTED as PX4 answers, one
    ``sitl-stub: rejected input`` line and a count in the exit stats; nothing has armed, so the
    radio payload has begun no episode."""
    port = free_udp_port()
    with vehicle_process(f"udp:127.0.0.1:{port}", 5.0) as vehicle:
        assert vehicle.wait_started(60.0), vehicle.output()
        gcs = Gcs(port)
        try:
            wait_for_vehicle(gcs, vehicle, 30.0)
            gcs.mav.mission_count_send(1, 1, 1, mavlink.MAV_MISSION_TYPE_MISSION)
            gcs.wait_message("MISSION_REQUEST_INT")
            gcs.mav.mission_item_int_send(
                1,
                1,
                0,
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH,
                0,
                1,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
                mavlink.MAV_MISSION_TYPE_MISSION,
            )
            ack = gcs.wait_message("MISSION_ACK")
            assert ack.type == mavlink.MAV_MISSION_UNSUPPORTED
        finally:
            gcs.close()
        assert vehicle.stop() == 0
        output = vehicle.output()
    lines = [ln for ln in output.splitlines() if ln.strip()]
    assert all(ln.startswith("sitl-stub: ") for ln in lines), output
    assert any(
        ln.startswith(
            "sitl-stub: rejected input: MISSION_ITEM_INT 0: "
            "MAV_CMD_NAV_RETURN_TO_LAUNCH in frame MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: "
            "MAV_MISSION_UNSUPPORTED"
        )
        for ln in lines
    ), output
    stats = parse_vehicle_stats(output)
    assert stats["rejected"] == {"mission_item_refused": 1}, stats["rejected"]
    assert stats["payloads"]["158"]["episodes"] == 0, stats["payloads"]
