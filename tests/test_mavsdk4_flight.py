"""MAVSDK 4.x (the ``mavsdk`` package's ctypes API) apps that fly: action (goto.py with a return to
launch), offboard velocity in NED and body axes (offboard_velocity_ned.py / _body.py) and
failure injection in flight (failure_injection.py), against ``python -m sitl_stub`` with no flags.

The same apps as tests/test_mavsdk3_flight.py, written the 4.x way. The examples' fixed sleeps (wall time; the vehicle runs at --speed 4) became waits for what each
step should make the vehicle do; each app ends on the ground. One vehicle per app.
"""

from __future__ import annotations

import asyncio
import math

import pytest

pytest.importorskip("mavsdk.asyncio", reason="MAVSDK 4.x: pip install 'mavsdk>=4.1'")
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.failure import FailureAsync, FailureType, FailureUnit  # noqa: E402
from mavsdk.asyncio.plugins.offboard import (  # noqa: E402
    OffboardAsync,
    VelocityBodyYawspeed,
    VelocityNedYaw,
)
from mavsdk.asyncio.plugins.param import ParamAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import FlightMode, TelemetryAsync  # noqa: E402
from support.cli import PX4_PORTS  # noqa: E402
from support.mavsdk_apps import (  # noqa: E402
    AUTO_SPEED,
    GOTO_LAT_DEG,
    GOTO_LON_DEG,
    first,
    ground_distance_m,
    heading_error_deg,
    mavsdk4_drone,
    near_velocity,
    run_app,
    sitl_vehicle,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300), PX4_PORTS]


@pytest.fixture
def vehicle():
    with sitl_vehicle() as v:
        yield v


async def wait_healthy(drone) -> None:
    await first(
        TelemetryAsync(drone).subscribe_health(),
        lambda h: h.is_global_position_ok and h.is_home_position_ok,
        what="global position and home ok",
    )


async def land_and_disarm(drone) -> None:
    tel = TelemetryAsync(drone)
    await ActionAsync(drone).land()
    await first(tel.subscribe_in_air(), lambda a: not a, timeout=90.0, what="landed")
    await first(tel.subscribe_armed(), lambda a: not a, timeout=20.0, what="auto-disarm")


def test_action_arm_takeoff_goto_location_return_to_launch():
    """goto.py then RTL at AUTO_SPEED (~115 s of flight: 29 s of wall time at 4x, 6 s at 20x)."""

    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            tel, action = TelemetryAsync(drone), ActionAsync(drone)
            await wait_healthy(drone)
            home = await first(tel.subscribe_home())
            await action.set_return_to_launch_altitude(30.0)
            print("-- Arming")
            await action.arm()
            print("-- Taking off")
            await action.takeoff()
            await asyncio.sleep(1)
            flying_alt = home.absolute_altitude_m + 20.0
            await action.goto_location(GOTO_LAT_DEG, GOTO_LON_DEG, flying_alt, 0)
            await first(
                tel.subscribe_position(),
                lambda p: (
                    ground_distance_m(p.latitude_deg, p.longitude_deg, GOTO_LAT_DEG, GOTO_LON_DEG)
                    < 2.0
                    and abs(p.absolute_altitude_m - flying_alt) < 1.0
                ),
                timeout=60.0,
                what="the goto target",
            )
            assert await first(tel.subscribe_flight_mode()) == FlightMode.HOLD  # as PX4

            print("-- Returning to launch")
            await action.return_to_launch()
            await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.RETURN_TO_LAUNCH)
            await first(tel.subscribe_in_air(), lambda a: not a, timeout=120.0, what="landed")
            await first(tel.subscribe_armed(), lambda a: not a, timeout=20.0, what="disarm")
            p = await first(tel.subscribe_position())
            assert (
                ground_distance_m(
                    p.latitude_deg, p.longitude_deg, home.latitude_deg, home.longitude_deg
                )
                < 2.0
            ), p

    with sitl_vehicle(speed=AUTO_SPEED) as vehicle:
        run_app(app, vehicle, timeout_s=200.0)


def test_offboard_velocity_ned(vehicle):
    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            tel, action, offboard = TelemetryAsync(drone), ActionAsync(drone), OffboardAsync(drone)
            await wait_healthy(drone)
            await action.arm()
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
            await offboard.start()
            assert await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.OFFBOARD)

            print("-- Go up 2 m/s")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -2.0, 0.0))
            await first(
                tel.subscribe_velocity_ned(), near_velocity(0.0, 0.0, -2.0), what="climb 2 m/s"
            )
            await first(
                tel.subscribe_position(), lambda p: p.relative_altitude_m > 10.0, what="10 m up"
            )
            for north, east, yaw in (
                (2.0, 0.0, 90.0),
                (-2.0, 0.0, 270.0),
                (0.0, -2.0, 90.0),
                (0.0, 2.0, 90.0),
            ):
                print(f"-- Go {north} m/s north, {east} m/s east, face {yaw} deg")
                await offboard.set_velocity_ned(VelocityNedYaw(north, east, 0.0, yaw))
                await first(tel.subscribe_velocity_ned(), near_velocity(north, east, 0.0))
                await first(
                    tel.subscribe_heading(),
                    lambda h, y=yaw: heading_error_deg(h.heading_deg, y) < 5.0,
                    what=f"heading {yaw}",
                )
            print("-- Turn to face South")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 180.0))
            await first(
                tel.subscribe_heading(), lambda h: heading_error_deg(h.heading_deg, 180.0) < 5.0
            )
            print("-- Go down 1 m/s, turn to face North")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, 0.0))
            await first(
                tel.subscribe_velocity_ned(), near_velocity(0.0, 0.0, 1.0), what="sink 1 m/s"
            )
            await first(
                tel.subscribe_heading(), lambda h: heading_error_deg(h.heading_deg, 0.0) < 5.0
            )

            print("-- Stopping offboard")
            await offboard.stop()
            await first(tel.subscribe_flight_mode(), lambda m: m == FlightMode.HOLD)
            await land_and_disarm(drone)

    run_app(app, vehicle, timeout_s=200.0)


def test_offboard_velocity_body(vehicle):
    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            tel, action, offboard = TelemetryAsync(drone), ActionAsync(drone), OffboardAsync(drone)
            await wait_healthy(drone)
            await action.arm()
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
            await offboard.start()

            print("-- Turn clock-wise and climb")
            h0 = (await first(tel.subscribe_heading())).heading_deg
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, -1.0, 60.0))
            await first(
                tel.subscribe_velocity_ned(), near_velocity(0.0, 0.0, -1.0), what="climb 1 m/s"
            )
            await first(
                tel.subscribe_heading(),
                lambda h: 30.0 < (h.heading_deg - h0) % 360.0 < 180.0,
                what="a clockwise turn",
            )
            await first(
                tel.subscribe_position(), lambda p: p.relative_altitude_m > 5.0, what="5 m up"
            )

            print("-- Turn back anti-clockwise")
            h1 = (await first(tel.subscribe_heading())).heading_deg
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, -60.0))
            await first(
                tel.subscribe_heading(),
                lambda h: 30.0 < (h1 - h.heading_deg) % 360.0 < 180.0,
                what="an anti-clockwise turn",
            )

            for forward, right, course in ((5.0, 0.0, 0.0), (0.0, -5.0, -90.0)):
                print(f"-- Fly a circle, {forward} m/s forward, {right} m/s right")
                await offboard.set_velocity_body(VelocityBodyYawspeed(forward, right, 0.0, 30.0))

                async def on_course(course_deg: float = course) -> bool:
                    v = await first(tel.subscribe_velocity_ned())
                    h = await first(tel.subscribe_heading())
                    track_deg = math.degrees(math.atan2(v.east_m_s, v.north_m_s))
                    return (
                        abs(math.hypot(v.north_m_s, v.east_m_s) - 5.0) < 0.5
                        and heading_error_deg(track_deg, h.heading_deg + course_deg) < 20.0
                    )

                for _ in range(200):
                    if await on_course():
                        break
                else:
                    raise AssertionError(f"never flew 5 m/s at {course} deg from the nose")

            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
            await first(tel.subscribe_velocity_ned(), near_velocity(0.0, 0.0, 0.0), what="a stop")
            await offboard.stop()
            await land_and_disarm(drone)

    run_app(app, vehicle, timeout_s=200.0)


def test_failure_injection_in_flight():
    """failure_injection.py: take off, climb, GPS off and on, land, at AUTO_SPEED."""

    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            tel, action = TelemetryAsync(drone), ActionAsync(drone)
            await wait_healthy(drone)
            print("-- Enabling failure injection")
            param = ParamAsync(drone)
            await param.set_param_int("SYS_FAILURE_EN", 1)
            # MAVSDK 4.1's failure plugin reads SYS_FAILURE_EN once, when it is created: after the set
            failure = FailureAsync(drone)
            await action.set_takeoff_altitude(10.0)
            await action.arm()
            await action.takeoff()
            p = await first(tel.subscribe_position(), lambda p: p.relative_altitude_m > 5.0)
            print("-- Flying up")
            await action.goto_location(
                p.latitude_deg, p.longitude_deg, p.absolute_altitude_m + 20.0, 0
            )
            await first(tel.subscribe_position(), lambda q: q.relative_altitude_m > 15.0)

            print("-- Injecting GPS failure")
            await failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
            await first(
                tel.subscribe_health(),
                lambda h: not h.is_global_position_ok,
                what="global position lost after GPS off",
            )
            await failure.inject(FailureUnit.SENSOR_GPS, FailureType.OK, 0)
            await wait_healthy(drone)
            await param.set_param_int("SYS_FAILURE_EN", 0)
            await land_and_disarm(drone)

    with sitl_vehicle(speed=AUTO_SPEED) as vehicle:
        run_app(app, vehicle, timeout_s=200.0)
