"""Real MAVSDK (the ``mavsdk`` package's C++ core) flies the SITL vehicle, unchanged.

MAVSDK listens (``udpin://``) and the vehicle sends to it (``udpout:``), as PX4 SITL's API link
does. The vehicle runs with its default payload factory (the radio payload, when present), so
this also checks that a second component on the system does not confuse MAVSDK.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

mavsdk_asyncio = pytest.importorskip("mavsdk.asyncio")
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.offboard import OffboardAsync, PositionNedYaw  # noqa: E402
from mavsdk.asyncio.plugins.param import ParamAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import FlightMode, LandedState, TelemetryAsync  # noqa: E402

from sitl_stub.launcher import vehicle_process  # noqa: E402
from uavlink.mavlink.connection import free_udp_port  # noqa: E402

pytestmark = [pytest.mark.slow, pytest.mark.waits, pytest.mark.timeout(120)]

SPEED = 5.0  # MAVSDK streams offboard setpoints at 20 Hz of wall time: keep speed <= 5


async def first(
    gen: AsyncIterator[Any], pred: Callable[[Any], bool] = lambda x: True, timeout: float = 20.0
) -> Any:
    """First item of a MAVSDK subscription that satisfies ``pred``."""

    async def scan() -> Any:
        async for item in gen:
            if pred(item):
                return item
        raise AssertionError("subscription ended")

    try:
        return await asyncio.wait_for(scan(), timeout)
    finally:
        await gen.aclose()


class Recorder:
    """Records every distinct value of a subscription in the background, so that short-lived
    states (AUTO.TAKEOFF lasts ~1.3 s of wall time at --speed 5) are not missed under load."""

    def __init__(self, gen: AsyncIterator[Any]) -> None:
        self.seen: list[Any] = []
        self._gen = gen
        self._task = asyncio.ensure_future(self._run())

    async def _run(self) -> None:
        async for item in self._gen:
            if not self.seen or self.seen[-1] != item:
                self.seen.append(item)

    async def wait_for(self, value: Any, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while value not in self.seen:
            assert time.monotonic() < deadline, f"{value} never seen in {self.seen}"
            await asyncio.sleep(0.02)

    async def close(self) -> None:
        self._task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._task
        await self._gen.aclose()


async def fly(port: int, vehicle_output: Callable[[], str]) -> None:
    t0 = time.monotonic()
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as mavsdk:
        await mavsdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        drone = await mavsdk.first_autopilot(timeout_s=20.0)
        assert drone is not None, vehicle_output()
        tel, action = TelemetryAsync(drone), ActionAsync(drone)
        offboard, param = OffboardAsync(drone), ParamAsync(drone)

        health = await first(
            tel.subscribe_health(),
            lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
        )
        assert health.is_local_position_ok
        pos = await first(tel.subscribe_position())
        assert pos.latitude_deg == pytest.approx(47.397742, abs=1e-6)
        assert pos.longitude_deg == pytest.approx(8.545594, abs=1e-6)
        assert pos.absolute_altitude_m == pytest.approx(488.0, abs=0.01)
        assert pos.relative_altitude_m == pytest.approx(0.0, abs=0.01)
        assert not await first(tel.subscribe_armed())
        assert not await first(tel.subscribe_in_air())
        assert await first(tel.subscribe_flight_mode()) == FlightMode.HOLD

        # parameters: a float through set/get_takeoff_altitude, an INT32 bytewise
        await action.set_takeoff_altitude(10.0)
        assert await action.get_takeoff_altitude() == pytest.approx(10.0)
        assert await param.get_param_int("COM_OBL_ACT") == 1
        assert await param.get_param_float("COM_OF_LOSS_T") == pytest.approx(1.0)

        modes = Recorder(tel.subscribe_flight_mode())
        landed = Recorder(tel.subscribe_landed_state())
        try:
            await fly_vehicle(tel, action, offboard, modes, landed)
        finally:
            await modes.close()
            await landed.close()
        assert modes.seen[:6] == [
            FlightMode.HOLD,
            FlightMode.TAKEOFF,
            FlightMode.HOLD,
            FlightMode.OFFBOARD,
            FlightMode.HOLD,
            FlightMode.LAND,
        ]
        assert landed.seen[:4] == [
            LandedState.ON_GROUND,
            LandedState.TAKING_OFF,
            LandedState.IN_AIR,
            LandedState.LANDING,
        ]
        assert time.monotonic() - t0 < 60.0


async def fly_vehicle(
    tel: TelemetryAsync,
    action: ActionAsync,
    offboard: OffboardAsync,
    modes: Recorder,
    landed: Recorder,
) -> None:
    """Arm, take off, two offboard setpoints, stop offboard, land, disarm."""
    await action.arm()
    assert await first(tel.subscribe_armed(), bool)
    await action.takeoff()
    await modes.wait_for(FlightMode.TAKEOFF)
    await landed.wait_for(LandedState.TAKING_OFF)
    await first(tel.subscribe_in_air(), bool)
    await first(tel.subscribe_position(), lambda p: p.relative_altitude_m > 9.5)
    await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD)

    await offboard.set_position_ned(PositionNedYaw(0.0, 0.0, -10.0, 0.0))
    await offboard.start()
    await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.OFFBOARD)
    for target in ((25.0, -15.0, -12.0), (-10.0, 20.0, -10.0)):
        await offboard.set_position_ned(PositionNedYaw(*target, 0.0))
        pv = await first(
            tel.subscribe_position_velocity_ned(),
            lambda pv, t=target: (
                math.dist((pv.position.north_m, pv.position.east_m, pv.position.down_m), t) < 1.0
            ),
        )
        assert abs(pv.position.north_m) <= 200.0
    await offboard.stop()
    await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD)

    await action.land()
    await landed.wait_for(LandedState.LANDING)
    await first(tel.subscribe_in_air(), lambda a: not a, timeout=30.0)
    await first(tel.subscribe_armed(), lambda a: not a, timeout=10.0)
    await modes.wait_for(FlightMode.LAND)


def test_mavsdk_connects_arms_takes_off_flies_offboard_and_lands():
    port = free_udp_port()
    with vehicle_process(f"udpout:127.0.0.1:{port}", SPEED) as vehicle:
        asyncio.run(fly(port, vehicle.output))
        assert vehicle.proc.poll() is None, vehicle.output()
