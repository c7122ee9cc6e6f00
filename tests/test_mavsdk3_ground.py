"""MAVSDK-Python 3.x (gRPC, ``mavsdk-grpc``) apps that stay on the ground: info, param, telemetry
and failure injection's guard, against ``python -m sitl_stub`` started with no flags.

Each test is a MAVSDK-Python example (firmware_version.py, telemetry.py, failure_injection.py's
first half; param has no example: the plugin's four calls) with asserts where the example prints.
One vehicle serves the module: none of these apps arms it.
"""

from __future__ import annotations

import pytest

pytest.importorskip("mavsdk_grpc", reason="the 3.x gRPC client: pip install mavsdk-grpc")
from mavsdk_grpc.failure import FailureError, FailureResult, FailureType, FailureUnit  # noqa: E402
from mavsdk_grpc.param import ParamError  # noqa: E402
from mavsdk_grpc.telemetry import FixType, FlightMode  # noqa: E402
from support.cli import PX4_PORTS
from support.mavsdk_apps import (  # noqa: E402
    HOME_ALT_M,
    HOME_LAT_DEG,
    HOME_LON_DEG,
    first,
    grpc_drone,
    run_app,
    sitl_vehicle,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300), PX4_PORTS]


@pytest.fixture(scope="module")
def vehicle():
    with sitl_vehicle() as v:
        yield v


def test_info_firmware_version_and_identification(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            info = await drone.info.get_version()
            print(info)
            assert info.flight_sw_major == 1 and info.flight_sw_minor >= 14, info  # PX4 v1.x
            ident = await drone.info.get_identification()
            assert ident.hardware_uid.strip("0"), ident  # AUTOPILOT_VERSION.uid2/uid, not blank

    run_app(app, vehicle)


def test_param_get_set_int_and_float(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            assert await drone.param.get_param_int("COM_OBL_ACT") == 1
            await drone.param.set_param_int("COM_OBL_ACT", 2)
            assert await drone.param.get_param_int("COM_OBL_ACT") == 2
            await drone.param.set_param_int("COM_OBL_ACT", 1)

            assert await drone.param.get_param_float("MPC_XY_CRUISE") == pytest.approx(5.0)
            await drone.param.set_param_float("MPC_XY_CRUISE", 7.5)
            assert await drone.param.get_param_float("MPC_XY_CRUISE") == pytest.approx(7.5)
            await drone.param.set_param_float("MPC_XY_CRUISE", 5.0)

            all_params = await drone.param.get_all_params()
            ints = {p.name: p.value for p in all_params.int_params}
            floats = {p.name: p.value for p in all_params.float_params}
            assert ints["COM_OBL_ACT"] == 1 and floats["MPC_XY_CRUISE"] == pytest.approx(5.0)
            with pytest.raises(ParamError):
                await drone.param.get_param_float("NO_SUCH_PARAM")

    run_app(app, vehicle)


def test_telemetry_position_battery_gps_armed_in_air_mode_health_home(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            tel = drone.telemetry
            battery = await first(tel.battery(), what="BATTERY_STATUS")
            print(f"Battery: {battery.remaining_percent}")
            assert 50.0 < battery.remaining_percent <= 100.0 and battery.voltage_v > 10.0, battery
            gps_info = await first(tel.gps_info(), what="GPS_RAW_INT")
            assert gps_info.fix_type == FixType.FIX_3D and gps_info.num_satellites >= 6, gps_info
            assert not await first(tel.in_air())
            assert not await first(tel.armed())
            assert await first(tel.flight_mode()) == FlightMode.HOLD
            position = await first(tel.position())
            print(position)
            assert position.latitude_deg == pytest.approx(HOME_LAT_DEG, abs=1e-6)
            assert position.longitude_deg == pytest.approx(HOME_LON_DEG, abs=1e-6)
            assert position.absolute_altitude_m == pytest.approx(HOME_ALT_M, abs=0.1)
            home = await first(tel.home(), what="HOME_POSITION")
            assert home.latitude_deg == pytest.approx(HOME_LAT_DEG, abs=1e-6)
            assert home.absolute_altitude_m == pytest.approx(HOME_ALT_M, abs=0.1)
            health = await first(tel.health(), lambda h: h.is_armable, what="armable")
            assert all(vars(health).values()), health  # every check ok, as on a calibrated PX4
            assert await first(tel.health_all_ok(), bool, what="health_all_ok")
            # MAVSDK passes on new messages only: HOME_POSITION must keep coming (~0.5 Hz)
            await first(tel.home(), timeout=10.0, what="a second HOME_POSITION")
            # Streams off by default that an app turns on, as on PX4 (SET_MESSAGE_INTERVAL).
            await tel.set_rate_odometry(10.0)
            odometry = await first(tel.odometry(), what="ODOMETRY")
            assert odometry.position_body.z_m == pytest.approx(0.0, abs=0.1), odometry  # landed
            await tel.set_rate_altitude(5.0)
            altitude = await first(tel.altitude(), what="ALTITUDE")
            assert altitude.altitude_amsl_m == pytest.approx(HOME_ALT_M, abs=0.1), altitude
            assert altitude.altitude_relative_m == pytest.approx(0.0, abs=0.1), altitude

    run_app(app, vehicle)


def test_failure_injection_needs_sys_failure_en(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            assert await drone.param.get_param_int("SYS_FAILURE_EN") == 0  # PX4's default
            with pytest.raises(FailureError) as denied:
                await drone.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, instance=0)
            # MAVSDK refuses by itself (DISABLED) when it has read SYS_FAILURE_EN = 0, else it
            # sends MAV_CMD_INJECT_FAILURE and the vehicle answers DENIED, as PX4's commander
            assert denied.value._result.result in (
                FailureResult.Result.DISABLED,
                FailureResult.Result.DENIED,
            )
            # enabled, it works: test_mavsdk3_flight's failure app (MAVSDK reads the parameter
            # when the plugin starts, so an app enables it before it connects or in a new session)
            await first(
                drone.telemetry.health(),
                lambda h: h.is_global_position_ok,
                timeout=10.0,
                what="GPS still fine: the refused failure did nothing",
            )

    run_app(app, vehicle)
