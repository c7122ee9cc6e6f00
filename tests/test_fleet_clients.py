"""Ground stations and apps see a fleet as PX4 multi-vehicle SITL shows one: ``python -m sitl_stub
--fleet 2`` with no port flags is instances 0 and 1, systems 1 and 2 (PX4
Tools/simulation/sitl_multiple_run.sh: ``px4 -i N``, MAV_SYS_ID = N+1), API links to 14540 / 14541
and both GCS links to 14550.

- MAVSDK 4.x, one ``Mavsdk`` with ``udpin://0.0.0.0:14540`` and ``udpin://0.0.0.0:14541`` (as
  MAVSDK's multiple-drones example adds one connection per instance), sees two autopilots and
  commands each: vehicle 2 arms and takes off while vehicle 1 stays on the ground, and a parameter
  set on vehicle 1 is not vehicle 2's.
- MAVProxy on 14550 detects both systems; ``vehicle 2`` makes system 2 the target of its commands
  (``arm throttle``, ``takeoff``), ``vehicle 1`` then system 1 (MAVProxy docs, "Multiple Vehicles
  with MAVProxy").
- ``uavlink fly --connect udp:14550``, one URL carrying both systems, flies both to the end.

These need PX4's ports free on 127.0.0.1 and skip, naming the taken ports, when they are not.
"""

from __future__ import annotations

import asyncio
import json
import math
import subprocess
import time
from pathlib import Path

import pytest
from support.cli import PX4_PORTS, ROOT, UAVLINK, require_free_ports
from support.mavlink_gcs import FAST_TAKEOFF
from support.mavproxy_console import MAVPROXY, mavproxy
from support.mavsdk_apps import first, run_app, sitl_vehicle, stub_has_px4_ports

from uavlink.mavlink.dialect import mavutil

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300), PX4_PORTS]

VEHICLE_PORTS = (14580, 14581, 18570, 18571)  # what the two vehicles bind (PX4 instances 0, 1)
ARMED = mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def _require_free(*ports: int) -> None:
    if not stub_has_px4_ports():
        pytest.skip("this sitl_stub has no PX4 ports (--instance)")
    require_free_ports(*VEHICLE_PORTS, *ports)


def test_mavsdk4_sees_two_vehicles_and_commands_each() -> None:
    pytest.importorskip("mavsdk.asyncio", reason="MAVSDK 4.x: pip install 'mavsdk>=4.1'")
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.param import ParamAsync
    from mavsdk.asyncio.plugins.telemetry import TelemetryAsync

    _require_free(14540, 14541)

    async def app(_address: str) -> None:
        config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
        async with Mavsdk(config) as mavsdk:
            for port in (14540, 14541):
                await mavsdk.add_any_connection(f"udpin://0.0.0.0:{port}")
            drones: dict[int, object] = {}
            while len(drones) < 2:
                for system in await mavsdk.get_systems():
                    if await system.has_autopilot():
                        drones[await system.get_system_id()] = system
                await asyncio.sleep(0.2)
            assert sorted(drones) == [1, 2]
            one, two = drones[1], drones[2]
            for drone in (one, two):
                await first(
                    TelemetryAsync(drone).subscribe_health(),
                    lambda h: h.is_global_position_ok and h.is_home_position_ok,
                    what="global position and home ok",
                )
            await ActionAsync(two).arm()
            await ActionAsync(two).takeoff()
            await first(
                TelemetryAsync(two).subscribe_position(),
                lambda p: p.relative_altitude_m > 5.0,
                timeout=60.0,
                what="vehicle 2 above 5 m",
            )
            assert not await first(TelemetryAsync(one).subscribe_armed()), "vehicle 1 armed too"
            ground = await first(TelemetryAsync(one).subscribe_position())
            assert abs(ground.relative_altitude_m) < 0.5, ground
            await ParamAsync(one).set_param_float("MPC_XY_CRUISE", 7.5)
            assert await ParamAsync(one).get_param_float("MPC_XY_CRUISE") == pytest.approx(7.5)
            assert await ParamAsync(two).get_param_float("MPC_XY_CRUISE") == pytest.approx(5.0)

    with sitl_vehicle(["--fleet", "2"]) as vehicle:
        run_app(app, vehicle, timeout_s=150.0)


def _tlog_by_system(path: Path) -> dict[int, dict[str, float]]:
    """Per autopilot system in MAVProxy's telemetry log: ever armed, highest relative altitude (m)."""
    seen: dict[int, dict[str, float]] = {}
    log = mavutil.mavlink_connection(str(path))
    while (m := log.recv_match(type=["HEARTBEAT", "GLOBAL_POSITION_INT"])) is not None:
        if m.get_srcComponent() != 1:
            continue
        s = seen.setdefault(m.get_srcSystem(), {"armed": 0.0, "alt_m": -math.inf})
        if m.get_type() == "HEARTBEAT":
            s["armed"] = max(s["armed"], float(bool(m.base_mode & ARMED)))
        else:
            s["alt_m"] = max(s["alt_m"], m.relative_alt / 1000.0)
    log.close()
    return seen


@pytest.mark.skipif(MAVPROXY is None, reason="mavproxy.py not installed")
def test_mavproxy_sees_two_vehicles_and_commands_each(tmp_path: Path) -> None:
    _require_free(14550)
    out_path, tlog = tmp_path / "mavproxy.out", tmp_path / "mav.tlog"

    def wait(what: str, pred, timeout: float = 30.0) -> dict[int, dict[str, float]]:
        deadline = time.monotonic() + timeout
        while True:
            text = out_path.read_text(errors="replace")
            systems = _tlog_by_system(tlog) if tlog.exists() else {}
            if pred(text, systems):
                return systems
            assert time.monotonic() < deadline, f"waited {timeout} s for {what}:\n{text[-3000:]}"
            time.sleep(0.2)

    with (
        mavproxy(["--master=udp:127.0.0.1:14550"], tmp_path, out_path) as type_in,
        sitl_vehicle(["--fleet", "2"], speed=5.0) as vehicle,
    ):
        wait(
            "both vehicles",
            lambda t, _: "Detected vehicle 1:1" in t and "Detected vehicle 2:1" in t,
        )
        type_in("vehicle 2")
        wait("vehicle 2 selected", lambda t, _: "Set vehicle 2" in t)
        type_in("arm throttle")
        wait("vehicle 2 armed", lambda _, s: s.get(2, {}).get("armed"))
        type_in("takeoff 10")
        got = wait("vehicle 2 climbing", lambda _, s: s.get(2, {}).get("alt_m", 0) > 5.0, 60.0)
        assert not got[1]["armed"] and got[1]["alt_m"] < 0.5, got  # vehicle 1 stayed down
        type_in("vehicle 1")
        wait("vehicle 1 selected", lambda t, _: "Set vehicle 1" in t)
        type_in("arm throttle")
        wait("vehicle 1 armed", lambda _, s: s.get(1, {}).get("armed"))
        assert vehicle.alive(), vehicle.output()


def test_fly_one_url_carrying_both_systems(tmp_path: Path) -> None:
    """``uavlink fly --connect udp:14550`` against ``sitl_stub --fleet 2``: both vehicles, found on
    the one GCS port in system id order, fly the fleet aoa rule to the end."""
    _require_free(14550)
    frames = 40
    # FAST_TAKEOFF: 95 m at 5 m/s, not 1.5 (6 s of wall time at 10x)
    with sitl_vehicle(
        ["--fleet", "2", "--scenario", "straight_180", *FAST_TAKEOFF], speed=10.0
    ) as vehicle:
        proc = subprocess.run(
            [
                *UAVLINK,
                "fly",
                "--no-picture",
                "--policy",
                "aoa",
                "--set",
                "n_uavs=2",
                "--scenario",
                "straight_180",
                "--connect",
                "udp:14550",
                "--frames",
                str(frames),
                "--out",
                str(tmp_path),
                "--json",
            ],
            capture_output=True,
            text=True,
            timeout=240,
            cwd=ROOT,
        )
        assert proc.returncode == 0, proc.stderr[-3000:] + vehicle.output()[-2000:]
    flown = json.loads(proc.stdout)
    assert flown["frames"] == frames and flown["ended_by"] == "episode done", flown
    assert [v["system_id"] for v in flown["vehicles"]] == [1, 2]
    assert all(
        v["decisions"] >= frames - 3 and v["holds"] == 0 and v["url"] == "udpin:0.0.0.0:14550"
        for v in flown["vehicles"]
    ), flown["vehicles"]
    assert flown["min_separation_flown_m"] >= 20.0
    assert set(_tlog_by_system(tmp_path / "flight.tlog")) == {1, 2}  # one tlog, both systems
