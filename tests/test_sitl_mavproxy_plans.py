"""MAVProxy's ``wp``, ``fence`` and ``rally`` modules round-trip a plan through the SITL vehicle.

MAVProxy (the ``mavproxy`` package) listens where the vehicle sends, as with PX4 SITL's GCS link,
and takes its commands on stdin as a user types them: ``wp load`` a QGC WPL 110 file, ``wp list``
(which saves what it downloaded), then the same for a fence polygon and a rally point. What MAVProxy
saved must be the plan it loaded (PX4 answers global items in the int frames MAVProxy asked with:
GLOBAL -> GLOBAL_INT, GLOBAL_RELATIVE_ALT -> GLOBAL_RELATIVE_ALT_INT).
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from support.mavproxy_console import MAVPROXY, mavproxy

from sitl_stub.core.params import PARAM_DEFS
from sitl_stub.launcher import vehicle_process
from uavlink.mavlink.connection import free_udp_port
from uavlink.mavlink.frames import TO_INT_FRAME

pytestmark = [pytest.mark.slow, pytest.mark.timeout(120)]

HOME = "47.3977420\t8.5455940"
PLANS = {  # module: (file to load, rows: seq current frame command p1-p4 lat lon alt autocontinue)
    "wp": (
        "mission.txt",
        [
            f"0\t0\t0\t16\t0\t0\t0\t0\t{HOME}\t488.0\t1",
            f"1\t0\t3\t22\t0\t0\t0\t0\t{HOME}\t20.0\t1",
            "2\t0\t3\t16\t1\t2\t0\t0\t47.3978420\t8.5456940\t20.0\t1",
            f"3\t0\t3\t21\t0\t0\t0\t0\t{HOME}\t0.0\t1",
        ],
    ),
    "fence": (
        "fence.txt",
        [
            f"{i}\t0\t0\t5001\t4\t0\t0\t0\t{lat}\t{lon}\t0\t1"
            for i, (lat, lon) in enumerate(
                [
                    (47.3997420, 8.5475940),
                    (47.3957420, 8.5475940),
                    (47.3957420, 8.5435940),
                    (47.3997420, 8.5435940),
                ]
            )
        ],
    ),
    "rally": ("rally.txt", ["0\t0\t3\t5100\t0\t0\t0\t0\t47.3980000\t8.5450000\t30.0\t1"]),
}
SAVED = {"wp": "way.txt", "fence": "fence-items.txt", "rally": "rally-items.txt"}


def _wait_text(path: Path, text: str, timeout: float, after: int = 0) -> int:
    """Wait for ``text`` in MAVProxy's output past offset ``after``; returns where it ends."""
    deadline = time.monotonic() + timeout
    while (at := path.read_text(errors="replace").find(text, after)) < 0:
        assert time.monotonic() < deadline, f"{text!r} not in MAVProxy output:\n{path.read_text()}"
        time.sleep(0.1)
    return at + len(text)


def _rows(path: Path) -> list[list[float]]:
    lines = path.read_text().splitlines()
    assert lines[0] == "QGC WPL 110"
    return [[float(v) for v in line.split()] for line in lines[1:] if line.strip()]


@pytest.mark.skipif(MAVPROXY is None, reason="mavproxy.py not installed")
def test_mavproxy_round_trips_mission_fence_and_rally(tmp_path: Path):
    for file, rows in PLANS.values():
        (tmp_path / file).write_text("QGC WPL 110\n" + "\n".join(rows) + "\n")
    port = free_udp_port()
    out_path = tmp_path / "mavproxy.out"
    with (
        mavproxy([f"--master=udp:127.0.0.1:{port}"], tmp_path, out_path) as type_in,
        vehicle_process(f"udpout:127.0.0.1:{port}", 1.0, []) as vehicle,
    ):
        at = _wait_text(out_path, f"Received {len(PARAM_DEFS)} parameters", 30.0)
        for module, (file, rows) in PLANS.items():
            type_in(f"{module} load {file}")
            at = _wait_text(out_path, "Got MISSION_ACK: TYPE_", 15.0, at)
            assert out_path.read_text(errors="replace")[at:].startswith(
                f"{'MISSION' if module == 'wp' else module.upper()}: ACCEPTED"
            )
            type_in(f"{module} list")
            at = _wait_text(out_path, f"Saved {len(rows)} ", 15.0, at)
        assert vehicle.proc.poll() is None, vehicle.output()
    text = out_path.read_text(errors="replace")
    assert "Busy" not in text and "ERROR" not in text
    for module, (file, _) in PLANS.items():
        loaded, saved = _rows(tmp_path / file), _rows(tmp_path / SAVED[module])
        assert len(saved) == len(loaded)
        for want, got in zip(loaded, saved, strict=True):
            assert got[2] == TO_INT_FRAME.get(int(want[2]), want[2])
            assert got[3:8] == want[3:8]  # command, params
            assert got[8:10] == pytest.approx(want[8:10], abs=2e-7)  # latitude, longitude
            assert got[10:] == want[10:]  # altitude, autocontinue
