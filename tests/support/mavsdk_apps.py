"""Harness for the MAVSDK app tests: the SITL vehicle started as a user starts PX4 SITL, and
MAVSDK clients of both Python APIs connected to it as the MAVSDK-Python examples connect.

- :func:`sitl_vehicle` runs ``python -m sitl_stub --speed SPEED`` with no other flag: PX4's
  instance-0 ports, so the vehicle sends to 127.0.0.1:14540 and an unmodified example's
  ``udpin://0.0.0.0:14540`` hears it. A stub without PX4's ports (no ``--instance`` option)
  gets ``--connect udpout:127.0.0.1:PORT`` on a free port instead, and the apps listen there.
- :func:`grpc_drone` is the 3.x API (``mavsdk-grpc``, imported as ``mavsdk_grpc``): ``System``
  starts its bundled ``mavsdk_server`` on a free gRPC port, then waits for the connection as the
  examples do. :func:`mavsdk4_drone` is the 4.x ctypes API (``mavsdk``): ``Mavsdk`` as a ground
  station, ``add_any_connection``, ``first_autopilot``.
- :func:`run_app` runs one app (``async def app(address)``) under a wall-clock timeout and adds
  the vehicle's log to any failure, so a failing MAVSDK call says what the vehicle did meanwhile.

MAVSDK streams offboard setpoints at 20 Hz of wall time, so the vehicle runs at ``SPEED`` <= 5.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import math
import os
import socket
import subprocess
import sys
import tempfile
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sitl_stub.launcher import PACKAGE_ROOT, VehicleProcess
from uavlink.mavlink.connection import free_udp_port

SPEED = 4.0  # simulated seconds per wall second
# For apps that only command AUTO modes (goto, RTL, missions): no offboard stream at a wall-time
# rate and no wall-time pacing, and MAVSDK's and the mission protocol's timeouts are wall time,
# which a faster vehicle only loosens. Their long flights then take a fifth of the wall time.
AUTO_SPEED = 20.0
PX4_API_ADDRESS = "udpin://0.0.0.0:14540"  # what every MAVSDK-Python example connects to
HOME_LAT_DEG, HOME_LON_DEG, HOME_ALT_M = 47.397742, 8.545594, 488.0  # sitl_stub's default home
EARTH_RADIUS_M = 6_371_000.0
GOTO_LAT_DEG, GOTO_LON_DEG = 47.397606, 8.543060  # goto.py's target, ~190 m west of home
WAYPOINTS_DEG = (
    (47.398039859999997, 8.5455725400000002),
    (47.398036222362471, 8.5450146439425509),
    (47.397825620791885, 8.5450092830163271),
)  # mission.py's three waypoints
INT_FRAME = {0: 5, 3: 6}  # MAV_FRAME_GLOBAL(_RELATIVE_ALT) -> its _INT twin


@functools.cache
def stub_has_px4_ports() -> bool:
    """Whether ``python -m sitl_stub`` with no flags serves PX4's ports (it has ``--instance``)."""
    help_text = subprocess.run(
        [sys.executable, "-m", "sitl_stub", "--help"],
        capture_output=True,
        text=True,
        env=_child_env(),
        timeout=60,
    ).stdout
    return "--instance" in help_text


@dataclass
class Sitl:
    """A running vehicle and the MAVSDK connection URL its apps use."""

    process: VehicleProcess
    address: str

    def output(self) -> str:
        return self.process.output()

    def alive(self) -> bool:
        return self.process.proc.poll() is None


@contextlib.contextmanager
def sitl_vehicle(extra_args: Sequence[str] = (), speed: float = SPEED) -> Iterator[Sitl]:
    """``python -m sitl_stub --speed SPEED [extra_args]``, PX4's ports; stopped at the end."""
    if stub_has_px4_ports():
        connect_args, address = [], PX4_API_ADDRESS
    else:
        port = free_udp_port()
        connect_args, address = (
            ["--connect", f"udpout:127.0.0.1:{port}"],
            f"udpin://127.0.0.1:{port}",
        )
    fd, name = tempfile.mkstemp(prefix="sitl_stub_mavsdk_", suffix=".log")
    log_path = Path(name)
    with os.fdopen(fd, "wb") as log_file:
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "sitl_stub",
                "--speed",
                repr(float(speed)),
                *connect_args,
                *extra_args,
            ],
            stdout=log_file,
            stderr=subprocess.STDOUT,
            env=_child_env(),
        )
    vehicle = VehicleProcess(proc, log_path)
    try:
        yield Sitl(vehicle, address)
    finally:
        vehicle.stop()
        log_path.unlink(missing_ok=True)


def _child_env() -> dict[str, str]:
    python_path = os.pathsep.join(p for p in (str(PACKAGE_ROOT), os.environ.get("PYTHONPATH")) if p)
    return dict(os.environ, PYTHONUNBUFFERED="1", PYTHONPATH=python_path)


def run_app(app: Callable[[str], Awaitable[None]], vehicle: Sitl, timeout_s: float = 120.0) -> None:
    """Run ``app(vehicle.address)`` to the end within ``timeout_s`` of wall time; a failure
    carries the vehicle's last log lines. The vehicle must still be running afterwards."""

    async def app_while_vehicle_runs() -> None:
        task = asyncio.ensure_future(asyncio.wait_for(app(vehicle.address), timeout_s))
        while not task.done():  # a vehicle that died fails the app now, not at its timeout
            if not vehicle.alive():
                task.cancel()
                raise AssertionError(f"sitl_stub exited with status {vehicle.process.proc.poll()}")
            await asyncio.wait([task], timeout=0.5)
        task.result()

    try:
        asyncio.run(app_while_vehicle_runs())
    except BaseException as exc:  # TimeoutError, MAVSDK errors, assertions: all get the log
        tail = "\n".join(vehicle.output().splitlines()[-40:])
        raise AssertionError(
            f"{type(exc).__name__}: {exc}\n--- sitl_stub log (tail) ---\n{tail}"
        ) from exc
    assert vehicle.alive(), vehicle.output()


def free_tcp_port() -> int:
    """A TCP port free on 127.0.0.1 now (for mavsdk_server's gRPC endpoint)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextlib.asynccontextmanager
async def grpc_drone(address: str) -> AsyncIterator[Any]:
    """MAVSDK-Python 3.x's ``System``, connected as the examples connect; its mavsdk_server is
    killed at the end."""
    from mavsdk_grpc import System

    drone = System(port=free_tcp_port())
    await drone.connect(system_address=address)
    try:
        async for state in drone.core.connection_state():
            if state.is_connected:
                break
        yield drone
    finally:
        drone._stop_mavsdk_server()  # what System.__del__ does; deterministic here


@contextlib.asynccontextmanager
async def mavsdk4_drone(address: str) -> AsyncIterator[Any]:
    """MAVSDK 4.x's first autopilot on ``address``, MAVSDK running as a ground station."""
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk

    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as mavsdk:
        await mavsdk.add_any_connection(address)
        drone = await mavsdk.first_autopilot(timeout_s=30.0)
        assert drone is not None, f"no autopilot heard on {address} within 30 s"
        yield drone


async def first(
    gen: AsyncIterator[Any],
    pred: Callable[[Any], bool] = lambda x: True,
    timeout: float = 30.0,
    what: str = "",
) -> Any:
    """The first item of a MAVSDK subscription that satisfies ``pred`` (either API)."""
    last: list[Any] = []

    async def scan() -> Any:
        async for item in gen:
            last[:] = [item]
            if pred(item):
                return item
        raise AssertionError("subscription ended")

    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise AssertionError(
            f"waited {timeout} s for {what or 'a matching item'}; "
            f"last seen: {last[0] if last else 'nothing'}"
        ) from None
    finally:
        await gen.aclose()


def ground_distance_m(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Horizontal distance between two nearby points (equirectangular; metres)."""
    north_m = math.radians(lat2_deg - lat1_deg) * EARTH_RADIUS_M
    east_m = math.radians(lon2_deg - lon1_deg) * EARTH_RADIUS_M * math.cos(math.radians(lat1_deg))
    return math.hypot(north_m, east_m)


def heading_error_deg(heading_deg: float, target_deg: float) -> float:
    """Absolute difference of two compass headings, 0..180 degrees."""
    return abs((heading_deg - target_deg + 180.0) % 360.0 - 180.0)


def near_velocity(
    north_m_s: float,
    east_m_s: float,
    down_m_s: float,
    tol_m_s: float = 0.3,
) -> Callable[[Any], bool]:
    """Predicate on a MAVSDK VelocityNed: within ``tol_m_s`` of the given NED velocity."""

    def pred(v: Any) -> bool:
        return (
            abs(v.north_m_s - north_m_s) < tol_m_s
            and abs(v.east_m_s - east_m_s) < tol_m_s
            and abs(v.down_m_s - down_m_s) < tol_m_s
        )

    return pred


def assert_same_raw_items(got: Sequence[Any], sent: Sequence[Any]) -> None:
    """Same mission_raw items (either API); PX4 answers MISSION_ITEM_INT downloads in the _INT
    frames (0 -> 5, 3 -> 6)."""

    def key(i: Any) -> tuple:
        return (i.seq, INT_FRAME.get(i.frame, i.frame), i.command, i.x, i.y, i.mission_type)

    assert [key(i) for i in got] == [key(i) for i in sent]
    for g, s in zip(got, sent, strict=True):
        assert math.isclose(g.z, s.z, abs_tol=1e-4) and math.isclose(
            g.param2, s.param2, abs_tol=1e-4
        )
