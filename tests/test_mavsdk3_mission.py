"""MAVSDK-Python 3.x (gRPC, ``mavsdk-grpc``) mission apps: mission.py (upload, fly to the end,
return, download), mission_raw.py (raw items for the mission, fence and rally lists: upload,
download, clear) and geofence.py (polygon and circle fences: upload, download, clear), against
``python -m sitl_stub`` with no flags.

mission.py differs from the example in two added lines: a 10 m take-off and a 30 m return
altitude (the stub's defaults are the operating altitude, 95 m and 60 m, which would make the
flight long). One vehicle per app.
"""

from __future__ import annotations

import asyncio
import math

import pytest

pytest.importorskip("mavsdk_grpc", reason="the 3.x gRPC client: pip install mavsdk-grpc")
from mavsdk_grpc import mission_raw  # noqa: E402
from mavsdk_grpc.geofence import Circle, FenceType, GeofenceData, Point, Polygon  # noqa: E402
from mavsdk_grpc.mission import MissionItem, MissionPlan  # noqa: E402
from support.cli import PX4_PORTS
from support.mavsdk_apps import (  # noqa: E402
    AUTO_SPEED,
    WAYPOINTS_DEG,
    assert_same_raw_items,
    first,
    grpc_drone,
    run_app,
    sitl_vehicle,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300), PX4_PORTS]

NAN = float("nan")


@pytest.fixture
def vehicle():
    with sitl_vehicle() as v:
        yield v


def mission_item(lat_deg: float, lon_deg: float) -> MissionItem:
    return MissionItem(
        lat_deg,
        lon_deg,
        25,
        10,
        True,
        NAN,
        NAN,
        MissionItem.CameraAction.NONE,
        NAN,
        NAN,
        NAN,
        NAN,
        NAN,
        MissionItem.VehicleAction.NONE,
    )


def test_mission_upload_fly_to_the_end_and_download():
    """mission.py: upload, fly it and its return at AUTO_SPEED, download."""

    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            progress: list[tuple[int, int]] = []

            async def print_mission_progress() -> None:
                async for mission_progress in drone.mission.mission_progress():
                    print(f"Mission progress: {mission_progress.current}/{mission_progress.total}")
                    progress.append((mission_progress.current, mission_progress.total))

            progress_task = asyncio.ensure_future(print_mission_progress())
            mission_plan = MissionPlan([mission_item(*wp) for wp in WAYPOINTS_DEG])
            await drone.mission.set_return_to_launch_after_mission(True)
            await drone.action.set_takeoff_altitude(10.0)
            await drone.action.set_return_to_launch_altitude(30.0)
            print("-- Uploading mission")
            await drone.mission.upload_mission(mission_plan)
            await first(
                drone.telemetry.health(),
                lambda h: h.is_global_position_ok and h.is_home_position_ok,
            )
            print("-- Arming")
            await drone.action.arm()
            print("-- Starting mission")
            await drone.mission.start_mission()
            await first(drone.telemetry.in_air(), bool, what="take-off")
            await first(
                drone.telemetry.in_air(),
                lambda a: not a,
                timeout=150.0,
                what="landing after the mission and its return",
            )
            progress_task.cancel()
            assert (3, 3) in progress, progress
            assert await drone.mission.is_mission_finished()

            downloaded = await drone.mission.download_mission()
            assert len(downloaded.mission_items) == 3, downloaded
            for item, (lat_deg, lon_deg) in zip(
                downloaded.mission_items, WAYPOINTS_DEG, strict=True
            ):
                assert item.latitude_deg == pytest.approx(lat_deg, abs=1e-7)
                assert item.longitude_deg == pytest.approx(lon_deg, abs=1e-7)
                assert item.relative_altitude_m == pytest.approx(25.0)
                assert item.speed_m_s == pytest.approx(10.0) and item.is_fly_through
            assert await drone.mission.get_return_to_launch_after_mission()

    with sitl_vehicle(speed=AUTO_SPEED) as vehicle:
        run_app(app, vehicle, timeout_s=240.0)


def raw_waypoint(
    seq: int, lat_deg: float, lon_deg: float, mission_type: int = 0, command: int = 16
) -> mission_raw.MissionItem:
    """mission_raw.py's item: frame 3 (global, relative altitude), acceptance radius 10 m."""
    return mission_raw.MissionItem(
        seq,
        3,
        command,
        int(seq == 0),
        1,
        0,
        10,
        0,
        NAN,
        int(lat_deg * 10**7),
        int(lon_deg * 10**7),
        30.0,
        mission_type,
    )


def test_mission_raw_upload_download_clear_mission_fence_rally(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            items = [
                raw_waypoint(0, 47.40271757, 8.54285027),
                raw_waypoint(1, 47.40271757, 8.54361892),
            ]
            print("-- Uploading mission")
            await drone.mission_raw.upload_mission(items)
            assert_same_raw_items(await drone.mission_raw.download_mission(), items)

            # an inclusion polygon (NAV_FENCE_POLYGON_VERTEX_INCLUSION, param1 = vertex count)
            corners = ((47.3970, 8.5445), (47.3985, 8.5445), (47.3985, 8.5467), (47.3970, 8.5467))
            fence = [
                mission_raw.MissionItem(
                    i, 0, 5001, 0, 1, 4, 0, 0, 0, int(la * 1e7), int(lo * 1e7), 0, 1
                )
                for i, (la, lo) in enumerate(corners)
            ]
            await drone.mission_raw.upload_geofence(fence)
            got_fence = await drone.mission_raw.download_geofence()
            assert [(i.command, i.x, i.y, i.mission_type) for i in got_fence] == [
                (i.command, i.x, i.y, 1) for i in fence
            ]
            rally = [raw_waypoint(0, 47.3979, 8.5458, mission_type=2, command=5100)]
            await drone.mission_raw.upload_rally_points(rally)
            got_rally = await drone.mission_raw.download_rallypoints()
            assert [(i.command, i.x, i.y, i.mission_type) for i in got_rally] == [
                (5100, *((rally[0].x, rally[0].y)), 2)
            ]

            await drone.mission_raw.clear_mission()
            assert list(await drone.mission_raw.download_mission()) == []
            # clearing the mission leaves the fence and the rally points (their own lists)
            assert len(await drone.mission_raw.download_geofence()) == 4

    run_app(app, vehicle)


def test_geofence_upload_download_clear(vehicle):
    async def app(address: str) -> None:
        async with grpc_drone(address) as drone:
            print("Fetching home location coordinates...")
            terrain_info = await first(drone.telemetry.home())
            latitude, longitude = terrain_info.latitude_deg, terrain_info.longitude_deg
            await asyncio.sleep(1)
            p1 = Point(latitude - 0.0001, longitude - 0.0001)
            p2 = Point(latitude + 0.0001, longitude - 0.0001)
            p3 = Point(latitude + 0.0001, longitude + 0.0001)
            p4 = Point(latitude - 0.0001, longitude + 0.0001)
            polygon = Polygon([p1, p2, p3, p4], FenceType.INCLUSION)
            # (the example adds Circle(Point(0, 0), 0, INCLUSION) as "no circle": MAVSDK 4's own
            # argument check refuses a zero radius before anything is sent, so it is left out)
            print("Uploading geofence...")
            await drone.geofence.upload_geofence(GeofenceData([polygon], []))
            print("Geofence uploaded!")

            keep_out = Circle(Point(latitude + 0.0005, longitude), 20.0, FenceType.EXCLUSION)
            await drone.geofence.upload_geofence(GeofenceData([polygon], [keep_out]))
            got = await drone.geofence.download_geofence()
            assert len(got.polygons) == 1 and got.polygons[0].fence_type == FenceType.INCLUSION
            for sent, back in zip(polygon.points, got.polygons[0].points, strict=True):
                assert back.latitude_deg == pytest.approx(sent.latitude_deg, abs=1e-7)
                assert back.longitude_deg == pytest.approx(sent.longitude_deg, abs=1e-7)
            assert len(got.circles) == 1, got
            assert got.circles[0].fence_type == FenceType.EXCLUSION
            assert got.circles[0].radius == pytest.approx(20.0)
            assert math.isclose(got.circles[0].point.latitude_deg, latitude + 0.0005, abs_tol=1e-7)

            await drone.geofence.clear_geofence()
            cleared = await drone.geofence.download_geofence()
            assert not cleared.polygons and not cleared.circles, cleared

    run_app(app, vehicle)
