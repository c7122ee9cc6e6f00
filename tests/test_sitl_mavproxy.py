"""MAVProxy (the ``mavproxy`` package) connects to the SITL vehicle and shows mode and position.

MAVProxy listens on ``udp:127.0.0.1:P1`` (the vehicle sends there, like PX4 SITL's GCS link) and
forwards to ``udpout:127.0.0.1:P2``, where a pymavlink client commands arm and takeoff *through*
MAVProxy. The test reads MAVProxy's console output and its telemetry log.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from support.mavproxy_console import MAVPROXY, mavproxy

from sitl_stub.core.params import PARAM_DEFS
from sitl_stub.launcher import vehicle_process
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.dialect import mavutil

pytestmark = [pytest.mark.slow, pytest.mark.timeout(90)]

mavlink = mavutil.mavlink


def _wait_text(path: Path, text: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while text not in path.read_text(errors="replace"):
        assert time.monotonic() < deadline, f"{text!r} not in MAVProxy output:\n{path.read_text()}"
        time.sleep(0.1)


def _logged_altitudes(tlog_path: Path) -> list[float]:
    """The vehicle's GLOBAL_POSITION_INT relative altitudes (m) in MAVProxy's telemetry log, checking
    each fix is at the SITL's home."""
    tlog = mavutil.mavlink_connection(str(tlog_path))
    alts = []
    while (m := tlog.recv_match(type="GLOBAL_POSITION_INT")) is not None:
        if m.get_srcSystem() == 1:
            assert abs(m.lat - 473977420) < 10 and abs(m.lon - 85455940) < 10
            alts.append(m.relative_alt / 1000.0)
    tlog.close()
    return alts


@pytest.mark.skipif(MAVPROXY is None, reason="mavproxy.py not installed")
def test_mavproxy_shows_mode_and_position(tmp_path: Path):
    p_master, p_out = free_udp_port(), free_udp_port()
    out_path = tmp_path / "mavproxy.out"
    client = None
    try:
        with (
            mavproxy(
                [
                    f"--master=udp:127.0.0.1:{p_master}",
                    f"--out=udpout:127.0.0.1:{p_out}",
                    "--non-interactive",
                ],
                tmp_path,
                out_path,
                typed=False,
            ),
            vehicle_process(
                f"udpout:127.0.0.1:{p_master}", 5.0, ["--param", "MIS_TAKEOFF_ALT=10"]
            ) as vehicle,
        ):
            _wait_text(out_path, "Detected vehicle 1:1", 20.0)
            _wait_text(out_path, "Mode LOITER", 10.0)
            _wait_text(out_path, "GPS lock at 488 meters", 10.0)
            _wait_text(out_path, f"Received {len(PARAM_DEFS)} parameters", 15.0)

            client = mavutil.mavlink_connection(
                f"udpin:127.0.0.1:{p_out}", source_system=250, source_component=190
            )
            assert client.wait_heartbeat(timeout=10.0) is not None
            client.mav.command_long_send(
                1, 0, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
            )
            _wait_text(out_path, "ARMED", 10.0)
            client.mav.command_long_send(1, 0, mavlink.MAV_CMD_NAV_TAKEOFF, 0, *[math.nan] * 7)
            _wait_text(out_path, "Mode TAKEOFF", 10.0)
            _wait_text(out_path, "Takeoff complete", 15.0)
            # MAVProxy writes its log behind its console: on a loaded machine the position at the
            # end of the climb can still be on its way when the console says "Takeoff complete".
            deadline = time.monotonic() + 10.0
            while (
                max(_logged_altitudes(tmp_path / "mav.tlog"), default=0.0) <= 9.0
                and time.monotonic() < deadline
            ):
                time.sleep(0.2)
            assert vehicle.proc.poll() is None, vehicle.output()
    finally:
        if client is not None:
            client.close()
    text = out_path.read_text(errors="replace")
    assert "fence breach" not in text
    assert "UNKNOWN" not in text

    # MAVProxy logged the vehicle's positions: the takeoff climbed over home
    alts = _logged_altitudes(tmp_path / "mav.tlog")
    assert alts and max(alts) > 9.0
