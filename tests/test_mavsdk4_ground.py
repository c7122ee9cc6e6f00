"""MAVSDK 4.x (the ``mavsdk`` package's ctypes API) apps that stay on the ground: info, param,
telemetry and failure injection's guard, against ``python -m sitl_stub`` started with no flags.

The same apps as tests/test_mavsdk3_ground.py, written the 4.x way (``Mavsdk`` as a ground
station, ``first_autopilot``, one ``*Async`` object per plugin, ``subscribe_*`` streams). One
vehicle serves the module: none of these apps arms it.
"""

from __future__ import annotations

import pytest

pytest.importorskip("mavsdk.asyncio", reason="MAVSDK 4.x: pip install 'mavsdk>=4.1'")
from mavsdk.asyncio.plugins.failure import (  # noqa: E402
    FailureAsync,
    FailureError,
    FailureResult,
    FailureType,
    FailureUnit,
)
from mavsdk.asyncio.plugins.info import InfoAsync  # noqa: E402
from mavsdk.asyncio.plugins.param import ParamAsync, ParamError  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import FixType, FlightMode, TelemetryAsync  # noqa: E402
from support.cli import PX4_PORTS  # noqa: E402
from support.mavsdk_apps import (  # noqa: E402
    HOME_ALT_M,
    HOME_LAT_DEG,
    HOME_LON_DEG,
    first,
    mavsdk4_drone,
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
        async with mavsdk4_drone(address) as drone:
            info = InfoAsync(drone)
            version = await info.get_version()
            assert version.flight_sw_major == 1 and version.flight_sw_minor >= 14, version
            ident = await info.get_identification()
            assert ident.hardware_uid.strip("0"), ident

    run_app(app, vehicle)


def test_param_get_set_int_and_float(vehicle):
    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            param = ParamAsync(drone)
            assert await param.get_param_int("COM_OBL_ACT") == 1
            await param.set_param_int("COM_OBL_ACT", 2)
            assert await param.get_param_int("COM_OBL_ACT") == 2
            await param.set_param_int("COM_OBL_ACT", 1)

            assert await param.get_param_float("MPC_XY_CRUISE") == pytest.approx(5.0)
            await param.set_param_float("MPC_XY_CRUISE", 7.5)
            assert await param.get_param_float("MPC_XY_CRUISE") == pytest.approx(7.5)
            await param.set_param_float("MPC_XY_CRUISE", 5.0)

            all_params = await param.get_all_params()
            ints = {p.name: p.value for p in all_params.int_params}
            floats = {p.name: p.value for p in all_params.float_params}
            assert ints["COM_OBL_ACT"] == 1 and floats["MPC_XY_CRUISE"] == pytest.approx(5.0)
            with pytest.raises(ParamError):
                await param.get_param_float("NO_SUCH_PARAM")

    run_app(app, vehicle)


def test_telemetry_position_battery_gps_armed_in_air_mode_health_home(vehicle):
    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            tel = TelemetryAsync(drone)
            battery = await first(tel.subscribe_battery(), what="BATTERY_STATUS")
            assert 50.0 < battery.remaining_percent <= 100.0 and battery.voltage_v > 10.0, battery
            gps_info = await first(tel.subscribe_gps_info(), what="GPS_RAW_INT")
            assert gps_info.fix_type == FixType.FIX_3D and gps_info.num_satellites >= 6, gps_info
            assert not await first(tel.subscribe_in_air())
            assert not await first(tel.subscribe_armed())
            assert await first(tel.subscribe_flight_mode()) == FlightMode.HOLD
            position = await first(tel.subscribe_position())
            assert position.latitude_deg == pytest.approx(HOME_LAT_DEG, abs=1e-6)
            assert position.longitude_deg == pytest.approx(HOME_LON_DEG, abs=1e-6)
            assert position.absolute_altitude_m == pytest.approx(HOME_ALT_M, abs=0.1)
            home = await first(tel.subscribe_home(), what="HOME_POSITION")
            assert home.latitude_deg == pytest.approx(HOME_LAT_DEG, abs=1e-6)
            assert home.absolute_altitude_m == pytest.approx(HOME_ALT_M, abs=0.1)
            health = await first(tel.subscribe_health(), lambda h: h.is_armable, what="armable")
            assert all(vars(health).values()), health
            assert await first(tel.subscribe_health_all_ok(), bool, what="health_all_ok")
            await first(tel.subscribe_home(), timeout=10.0, what="a second HOME_POSITION")

    run_app(app, vehicle)


def test_failure_injection_needs_sys_failure_en(vehicle):
    async def app(address: str) -> None:
        async with mavsdk4_drone(address) as drone:
            param, failure = ParamAsync(drone), FailureAsync(drone)
            assert await param.get_param_int("SYS_FAILURE_EN") == 0  # PX4's default
            with pytest.raises(FailureError) as denied:
                await failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
            assert denied.value.result in (FailureResult.DISABLED, FailureResult.DENIED)
            # enabled, it works: test_mavsdk4_flight's failure app (MAVSDK reads the parameter
            # once, when the failure plugin is created)
            await first(
                TelemetryAsync(drone).subscribe_health(),
                lambda h: h.is_global_position_ok,
                timeout=10.0,
                what="GPS still fine: the refused failure did nothing",
            )

    run_app(app, vehicle)
