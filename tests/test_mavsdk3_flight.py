"""MAVSDK-Python 3.x (gRPC, ``mavsdk-grpc``) apps that fly: action (goto.py with a return to
launch), offboard velocity in NED and body axes (offboard_velocity_ned.py / _body.py) and
failure injection in flight (failure_injection.py), against ``python -m sitl_stub`` with no flags.

The examples' fixed sleeps (wall time; the vehicle runs at --speed 4) became waits for what each
step should make the vehicle do; each app ends on the ground. One vehicle per app.
"""

from __future__ import annotations

import asyncio
import math

import pytest

pytest.importorskip("mavsdk_grpc", reason="the 3.x gRPC client: pip install mavsdk-grpc")
from mavsdk_grpc.failure import FailureType, FailureUnit  # noqa: E402
from mavsdk_grpc.offboard import VelocityBodyYawspeed, VelocityNedYaw  # noqa: E402
from mavsdk_grpc.telemetry import FlightMode  # noqa: E402
from support.cli import PX4_PORTS
from support.mavsdk_apps import (  # noqa: E402
    AUTO_SPEED,
    GOTO_LAT_DEG,
    GOTO_LON_DEG,
    first,
    ground_distance_m,
    grpc_drone,
    heading_error_deg,
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
        drone.telemetry.health(),
        lambda h: h.is_global_position_ok and h.is_home_position_ok,
        what="global position and home ok",
    )


async def land_and_disarm(drone) -> None:
    await drone.action.land()
    await first(drone.telemetry.in_air(), lambda a: not a, timeout=90.0, what="landed")
    await first(drone.telemetry.armed(), lambda a: not a, timeout=20.0, what="auto-disarm")


def test_action_arm_takeoff_goto_location_return_to_launch():
    """goto.py then RTL at AUTO_SPEED (~115 s of flight: 29 s of wall time at 4x, 6 s at 20x)."""

    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            await wait_healthy(drone)
            home = await first(drone.telemetry.home())
            await drone.action.set_return_to_launch_altitude(30.0)
            print("-- Arming")
            await drone.action.arm()
            print("-- Taking off")
            await drone.action.takeoff()
            await asyncio.sleep(1)
            flying_alt = home.absolute_altitude_m + 20.0
            await drone.action.goto_location(GOTO_LAT_DEG, GOTO_LON_DEG, flying_alt, 0)
            await first(
                drone.telemetry.position(),
                lambda p: (
                    ground_distance_m(p.latitude_deg, p.longitude_deg, GOTO_LAT_DEG, GOTO_LON_DEG)
                    < 2.0
                    and abs(p.absolute_altitude_m - flying_alt) < 1.0
                ),
                timeout=60.0,
                what="the goto target",
            )
            assert await first(drone.telemetry.flight_mode()) == FlightMode.HOLD  # as PX4

            print("-- Returning to launch")
            await drone.action.return_to_launch()
            await first(drone.telemetry.flight_mode(), lambda m: m == FlightMode.RETURN_TO_LAUNCH)
            await first(drone.telemetry.in_air(), lambda a: not a, timeout=120.0, what="landed")
            await first(drone.telemetry.armed(), lambda a: not a, timeout=20.0, what="disarm")
            p = await first(drone.telemetry.position())
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
        async with grpc_drone(address) as drone:
            tel, offboard = drone.telemetry, drone.offboard
            await wait_healthy(drone)
            await drone.action.arm()
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
            await offboard.start()
            assert await first(tel.flight_mode(), lambda m: m == FlightMode.OFFBOARD)

            print("-- Go up 2 m/s")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -2.0, 0.0))
            await first(tel.velocity_ned(), near_velocity(0.0, 0.0, -2.0), what="climb 2 m/s")
            await first(tel.position(), lambda p: p.relative_altitude_m > 10.0, what="10 m up")
            for north, east, yaw in (
                (2.0, 0.0, 90.0),
                (-2.0, 0.0, 270.0),
                (0.0, -2.0, 90.0),
                (0.0, 2.0, 90.0),
            ):
                print(f"-- Go {north} m/s north, {east} m/s east, face {yaw} deg")
                await offboard.set_velocity_ned(VelocityNedYaw(north, east, 0.0, yaw))
                await first(tel.velocity_ned(), near_velocity(north, east, 0.0))
                await first(
                    tel.heading(),
                    lambda h, y=yaw: heading_error_deg(h.heading_deg, y) < 5.0,
                    what=f"heading {yaw}",
                )
            print("-- Turn to face South")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 180.0))
            await first(tel.heading(), lambda h: heading_error_deg(h.heading_deg, 180.0) < 5.0)
            print("-- Go down 1 m/s, turn to face North")
            await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, 0.0))
            await first(tel.velocity_ned(), near_velocity(0.0, 0.0, 1.0), what="sink 1 m/s")
            await first(tel.heading(), lambda h: heading_error_deg(h.heading_deg, 0.0) < 5.0)

            print("-- Stopping offboard")
            await offboard.stop()
            await first(tel.flight_mode(), lambda m: m == FlightMode.HOLD)
            await land_and_disarm(drone)

    run_app(app, vehicle, timeout_s=200.0)


def test_offboard_velocity_body(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            tel, offboard = drone.telemetry, drone.offboard
            await wait_healthy(drone)
            await drone.action.arm()
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
            await offboard.start()

            print("-- Turn clock-wise and climb")
            h0 = (await first(tel.heading())).heading_deg
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, -1.0, 60.0))
            await first(tel.velocity_ned(), near_velocity(0.0, 0.0, -1.0), what="climb 1 m/s")
            await first(
                tel.heading(),
                lambda h: 30.0 < (h.heading_deg - h0) % 360.0 < 180.0,
                what="a clockwise turn",
            )
            await first(tel.position(), lambda p: p.relative_altitude_m > 5.0, what="5 m up")

            print("-- Turn back anti-clockwise")
            h1 = (await first(tel.heading())).heading_deg
            await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, -60.0))
            await first(
                tel.heading(),
                lambda h: 30.0 < (h1 - h.heading_deg) % 360.0 < 180.0,
                what="an anti-clockwise turn",
            )

            for forward, right, course in ((5.0, 0.0, 0.0), (0.0, -5.0, -90.0)):
                print(f"-- Fly a circle, {forward} m/s forward, {right} m/s right")
                await offboard.set_velocity_body(VelocityBodyYawspeed(forward, right, 0.0, 30.0))

                async def on_course(course_deg: float = course) -> bool:
                    v = await first(tel.velocity_ned())
                    h = await first(tel.heading())
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
            await first(tel.velocity_ned(), near_velocity(0.0, 0.0, 0.0), what="a stop")
            await offboard.stop()
            await land_and_disarm(drone)

    run_app(app, vehicle, timeout_s=200.0)


def test_failure_injection_in_flight():
    """failure_injection.py: take off, climb, GPS off and on, land, at AUTO_SPEED."""

    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            await wait_healthy(drone)
            print("-- Enabling failure injection")
            await drone.param.set_param_int("SYS_FAILURE_EN", 1)
            await drone.action.set_takeoff_altitude(10.0)
            await drone.action.arm()
            await drone.action.takeoff()
            p = await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 5.0)
            print("-- Flying up")
            await drone.action.goto_location(
                p.latitude_deg, p.longitude_deg, p.absolute_altitude_m + 20.0, 0
            )
            await first(drone.telemetry.position(), lambda q: q.relative_altitude_m > 15.0)

            print("-- Injecting GPS failure")
            await drone.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, instance=0)
            await first(
                drone.telemetry.health(),
                lambda h: not h.is_global_position_ok,
                what="global position lost after GPS off",
            )
            await drone.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OK, instance=0)
            await wait_healthy(drone)
            await drone.param.set_param_int("SYS_FAILURE_EN", 0)
            await land_and_disarm(drone)

    with sitl_vehicle(speed=AUTO_SPEED) as vehicle:
        run_app(app, vehicle, timeout_s=200.0)
