"""AUTO.MISSION, the geofence (GF_ACTION) and rally-point RTL on a Vehicle stepped in simulated
time, its store filled directly (no sockets)."""

from __future__ import annotations

import math

import pytest

from sitl_stub.core.geo import GeoOrigin
from sitl_stub.core.mission_store import FENCE, MISSION, RALLY, MissionItem, MissionStore
from sitl_stub.core.modes import FlightMode
from sitl_stub.core.params import ParamStore
from sitl_stub.core.vehicle_state import Result
from sitl_stub.flight.geofence import CIRCLE_EXCLUSION, POLYGON_INCLUSION
from sitl_stub.flight.mission_executor import (
    ACTIVE,
    COMPLETE,
    DO_CHANGE_SPEED,
    DO_JUMP,
    NAV_LAND,
    NAV_RETURN_TO_LAUNCH,
    NAV_TAKEOFF,
    NAV_WAYPOINT,
    NOT_STARTED,
    PAUSED,
)
from sitl_stub.flight.rtl import NAV_RALLY_POINT
from sitl_stub.flight.vehicle import Vehicle
from sitl_stub.mavlink.telemetry import TelemetrySender
from uavlink.mavlink.dialect import mavlink

pytestmark = pytest.mark.timeout(120)

DT = 0.1
HOME = GeoOrigin()
REL_ALT = 6  # MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def item(
    seq: int,
    command: int,
    n: float = 0.0,
    e: float = 0.0,
    z: float = 0.0,
    *,
    p1: float = 0.0,
    p2: float = 0.0,
    mission_type: int = MISSION,
    frame: int = REL_ALT,
    at_home_xy: bool = False,
) -> MissionItem:
    lat, lon = HOME.to_global(n, e)
    x, y = (0, 0) if at_home_xy else (round(lat * 1e7), round(lon * 1e7))
    return MissionItem(
        seq, frame, command, param1=p1, param2=p2, x=x, y=y, z=z, mission_type=mission_type
    )


def vehicle(**params: float) -> Vehicle:
    return Vehicle(ParamStore(params), plans=MissionStore(), origin=HOME)


class Flight:
    """Steps a vehicle and records MISSION_ITEM_REACHED (seq, time, position) and events."""

    def __init__(self, v: Vehicle) -> None:
        self.v = v
        self.reached: list[tuple[int, float, tuple[float, float, float]]] = []
        self.events: list[str] = []
        self.max_speed = 0.0
        self.breached_seen = False

    def run_until(self, done, max_s: float) -> None:
        t0 = self.v.t
        while not done():
            assert self.v.t - t0 < max_s, f"not done after {max_s} s: {self.v.state()}"
            self.step()

    def step(self, dt: float = DT) -> None:
        self.v.step(dt)
        s = self.v.state()
        self.max_speed = max(self.max_speed, s.ground_speed_mps)
        self.breached_seen |= s.fence_breached
        for seq in self.v.mission.drain_reached():
            self.reached.append((seq, self.v.t, tuple(self.v.pos)))
        self.events += [text for _, text in self.v.drain_events()]

    @property
    def seqs(self) -> list[int]:
        return [r[0] for r in self.reached]


def airborne(alt: float = 20.0, **params: float) -> Flight:
    v = vehicle(MIS_TAKEOFF_ALT=alt, **params)
    assert v.arm().ok and v.takeoff().ok
    f = Flight(v)
    f.run_until(lambda: v.mode is FlightMode.LOITER, 60.0)
    return f


def flying_mission(*items: MissionItem, **params: float) -> Flight:
    """Airborne at 20 m, ``items`` stored as the mission and AUTO.MISSION entered."""
    f = airborne(20.0, **params)
    f.v.plans.replace(MISSION, items)
    assert f.v.set_mode(FlightMode.MISSION).ok
    return f


def test_takeoff_three_waypoints_with_hold_and_land():
    v = vehicle()
    v.plans.replace(
        MISSION,
        (
            item(0, NAV_TAKEOFF, z=15.0, at_home_xy=True),
            item(1, NAV_WAYPOINT, 60.0, 0.0, 15.0, p1=3.0, p2=2.0),
            item(2, NAV_WAYPOINT, 60.0, 60.0, 20.0, p1=3.0, p2=2.0),
            item(3, NAV_WAYPOINT, 0.0, 60.0, 20.0, p2=2.0),
            item(4, NAV_LAND, 0.0, 60.0, 0.0),
        ),
    )
    assert v.state().mission_current == (0, 5, NOT_STARTED, 2)
    assert v.arm().ok and v.set_mode(FlightMode.MISSION).ok
    f = Flight(v)
    f.run_until(lambda: not v.armed, 400.0)  # lands, then COM_DISARM_LAND disarms
    assert f.seqs == [0, 1, 2, 3, 4]
    for seq, wp in ((1, (60.0, 0.0)), (2, (60.0, 60.0)), (3, (0.0, 60.0))):
        _, _, pos = f.reached[seq]
        assert math.dist(pos[:2], wp) <= 2.0  # inside the acceptance radius param2
    _, t_takeoff, pos = f.reached[0]
    assert -pos[2] >= 14.5 and math.hypot(pos[0], pos[1]) < 0.1  # climbed straight up
    assert f.reached[2][1] - f.reached[1][1] >= 3.0  # the hold time at waypoint 1
    assert v.pos[2] == pytest.approx(0.0, abs=0.05) and math.dist(v.pos[:2], (0.0, 60.0)) < 1.0
    assert f.max_speed == pytest.approx(v.params["MPC_XY_CRUISE"], abs=0.1)


def test_acceptance_radius_zero_means_nav_acc_rad_and_the_mission_ends_holding():
    f = airborne(20.0, NAV_ACC_RAD=10.0)
    v = f.v
    v.plans.replace(MISSION, (item(0, NAV_WAYPOINT, 80.0, 0.0, 20.0),))
    assert v.set_mode(FlightMode.MISSION).ok
    f.run_until(lambda: f.seqs, 60.0)
    assert 9.0 < 80.0 - f.reached[0][2][0] <= 10.0  # reached at NAV_ACC_RAD
    for _ in range(200):
        f.step()
    # PX4: after the last item the vehicle stays in the mission, holding at the last waypoint
    assert v.mode is FlightMode.MISSION
    assert v.state().mission_current == (0, 1, COMPLETE, 1)
    assert math.dist(v.pos[:2], (80.0, 0.0)) < 0.1 and v.state().ground_speed_mps < 0.01


def test_change_speed_sets_the_cruise_speed():
    f = flying_mission(
        item(0, DO_CHANGE_SPEED, p1=1.0, p2=2.0, frame=2),
        item(1, NAV_WAYPOINT, 100.0, 0.0, 20.0, p2=1.0),
    )
    f.run_until(lambda: 1 in f.seqs, 120.0)
    assert f.seqs == [0, 1]
    assert f.max_speed == pytest.approx(2.0, abs=0.05)


def test_jump_repeats_its_target_then_goes_on():
    f = flying_mission(
        item(0, NAV_WAYPOINT, 30.0, 0.0, 20.0, p2=1.0),
        item(1, NAV_WAYPOINT, 30.0, 30.0, 20.0, p2=1.0),
        item(2, DO_JUMP, p1=0.0, p2=2.0, frame=2),  # back to 0, twice
        item(3, NAV_WAYPOINT, 0.0, 0.0, 20.0, p2=1.0),
    )
    f.run_until(lambda: 3 in f.seqs, 400.0)
    assert f.seqs == [0, 1, 0, 1, 0, 1, 3]  # DO_JUMP itself is never "reached"


def test_pause_holds_and_resume_continues_at_the_current_item():
    f = flying_mission(
        item(0, NAV_WAYPOINT, 20.0, 0.0, 20.0, p2=1.0),
        item(1, NAV_WAYPOINT, 150.0, 0.0, 20.0, p2=1.0),
    )
    v = f.v
    f.run_until(lambda: v.pos[0] > 60.0, 120.0)
    assert v.set_mode(FlightMode.LOITER).ok  # MAVSDK pause_mission: DO_SET_MODE hold
    for _ in range(150):
        f.step()
    assert v.state().mission_current == (1, 2, PAUSED, 2)
    assert v.state().ground_speed_mps < 0.01 and v.pos[0] < 100.0
    assert v.set_mode(FlightMode.MISSION).ok
    assert v.state().mission_current[2] == ACTIVE
    f.run_until(lambda: 1 in f.seqs, 120.0)
    assert f.seqs == [0, 1]


def test_set_current_moves_the_executor_and_mission_start_picks_the_first_item():
    f = airborne(20.0)
    v = f.v
    v.plans.replace(
        MISSION,
        (
            item(0, NAV_WAYPOINT, 100.0, 0.0, 20.0, p2=1.0),
            item(1, NAV_WAYPOINT, 0.0, 40.0, 20.0, p2=1.0),
            item(2, NAV_WAYPOINT, 0.0, 0.0, 20.0, p2=1.0),
        ),
    )
    assert v.start_mission(7).result is Result.DENIED
    assert v.start_mission(1).ok  # MISSION_START param1
    f.run_until(lambda: f.seqs, 60.0)
    assert f.seqs == [1] and v.pos[0] < 1.0  # never went to item 0
    assert v.plans.set_current(0)  # MISSION_SET_CURRENT
    f.run_until(lambda: 0 in f.seqs, 120.0)
    assert f.seqs[:2] == [1, 0]


def test_no_mission_is_refused_and_an_rtl_item_hands_over_to_return():
    f = airborne(20.0)
    v = f.v
    outcome = v.set_mode(FlightMode.MISSION)
    assert outcome.result is Result.DENIED and "no mission" in outcome.reason
    v.plans.replace(
        MISSION,
        (item(0, NAV_WAYPOINT, 30.0, 0.0, 20.0, p2=1.0), item(1, NAV_RETURN_TO_LAUNCH, frame=2)),
    )
    assert v.set_mode(FlightMode.MISSION).ok
    f.run_until(lambda: v.mode is FlightMode.RTL, 60.0)
    assert f.seqs == [0, 1]
    f.run_until(lambda: not v.armed, 200.0)
    assert math.hypot(v.pos[0], v.pos[1]) < 0.6


@pytest.mark.parametrize(
    ("rally_ne", "start_ne", "dest_ne"),
    [
        ((150.0, 0.0), (120.0, 0.0), (150.0, 0.0)),  # the rally point is nearer than home
        ((150.0, 0.0), (20.0, 0.0), (0.0, 0.0)),  # home is nearer
    ],
)
def test_rtl_lands_at_the_nearest_of_home_and_the_rally_points(rally_ne, start_ne, dest_ne):
    f = airborne(20.0, RTL_RETURN_ALT=30.0)
    v = f.v
    v.plans.replace(
        RALLY,
        (
            item(0, NAV_RALLY_POINT, *rally_ne, 0.0, mission_type=RALLY),
            item(1, NAV_RALLY_POINT, -150.0, -150.0, 0.0, mission_type=RALLY),
        ),
    )
    v.plans.replace(MISSION, (item(0, NAV_WAYPOINT, *start_ne, 20.0, p2=1.0),))
    assert v.set_mode(FlightMode.MISSION).ok
    f.run_until(lambda: f.seqs, 100.0)
    peak = 0.0
    assert v.return_to_launch().ok
    while v.armed:
        f.step()
        peak = max(peak, -v.pos[2])
    assert peak == pytest.approx(30.0, abs=0.6)  # RTL_RETURN_ALT
    assert math.dist(v.pos[:2], dest_ne) < 0.6 and v.pos[2] == pytest.approx(0.0, abs=0.05)


def square_fence(v: Vehicle, half_m: float = 100.0) -> None:
    corners = ((-half_m, -half_m), (-half_m, half_m), (half_m, half_m), (half_m, -half_m))
    v.plans.replace(
        FENCE,
        tuple(
            item(i, POLYGON_INCLUSION, n, e, p1=4.0, mission_type=FENCE)
            for i, (n, e) in enumerate(corners)
        ),
    )


def offboard_to(f: Flight, ned: tuple[float, float, float], seconds: float) -> None:
    v = f.v
    assert v.offer_setpoint(*ned) and v.start_offboard().ok
    for _ in range(int(seconds / DT)):
        v.offer_setpoint(*ned)
        f.step()


def test_a_setpoint_beyond_an_inclusion_polygon_stops_at_the_fence_and_holds():
    f = airborne(20.0, MPC_XY_VEL_MAX=12.0)
    v = f.v
    square_fence(v)
    offboard_to(f, (180.0, 0.0, -20.0), 60.0)
    assert v.mode is FlightMode.LOITER
    assert "Geofence violation" in f.events and "Failsafe: geofence, activating Hold" in f.events
    assert f.breached_seen and not v.state().fence_breached  # holding inside: no longer
    assert v.state().max_abs_xy_m <= 100.0 and v.pos[0] > 95.0
    assert v.state().ground_speed_mps < 0.01


def test_a_mission_waypoint_into_an_exclusion_circle_stops_before_it():
    f = airborne(20.0)
    v = f.v
    v.plans.replace(FENCE, (item(0, CIRCLE_EXCLUSION, 80.0, 0.0, p1=20.0, mission_type=FENCE),))
    v.plans.replace(MISSION, (item(0, NAV_WAYPOINT, 150.0, 0.0, 20.0, p2=1.0),))
    assert v.set_mode(FlightMode.MISSION).ok
    for _ in range(600):
        f.step()
        assert v.pos[0] <= 60.0 + 0.05  # BREACH_TOLERANCE_M
    assert v.mode is FlightMode.LOITER and v.pos[0] > 55.0 and not f.seqs
    assert v.state().mission_current[2] == PAUSED


@pytest.mark.parametrize(
    ("action", "mode", "announced"),
    [
        (0, FlightMode.OFFBOARD, None),
        (1, FlightMode.OFFBOARD, None),
        (3, FlightMode.RTL, "Failsafe: geofence, activating Return"),
        (4, FlightMode.LAND, "Failsafe: geofence, activating Land (no termination in SITL)"),
        (5, FlightMode.LAND, "Failsafe: geofence, activating Land"),
    ],
)
def test_gf_action_variants(action, mode, announced):
    f = airborne(20.0, GF_ACTION=action)
    v = f.v
    square_fence(v)
    offboard_to(f, (180.0, 0.0, -20.0), 40.0)
    assert v.mode is mode or (mode is FlightMode.LAND and not v.armed)  # landed and disarmed
    assert ("Geofence violation" in f.events) == (action != 0)
    if announced:
        assert announced in f.events
    if action in (0, 1):  # nothing stops it: it flies out to the setpoint
        assert v.pos[0] == pytest.approx(180.0, abs=0.5)
        assert v.state().fence_breached == (action == 1)
    if action in (4, 5):
        assert v.state().max_abs_xy_m <= 100.0 and v.pos[2] > -15.0  # landing inside the fence


def test_sys_status_and_mission_current_report_the_vehicle_state():
    """SYS_STATUS clears the geofence health bit while breached; MISSION_CURRENT carries the
    executor's (seq, total, state, mode)."""
    f = airborne(20.0, GF_ACTION=1)
    v = f.v
    square_fence(v, 30.0)
    v.plans.replace(MISSION, (item(0, NAV_WAYPOINT, 60.0, 0.0, 20.0),))
    assert v.set_mode(FlightMode.MISSION).ok
    f.run_until(lambda: v.state().fence_breached, 60.0)
    sent: list = []
    parser = mavlink.MAVLink(None)

    class Capture:
        def write(self, buf: bytes) -> None:
            sent.extend(parser.parse_buffer(bytes(buf)) or [])

    telemetry = TelemetrySender(mavlink.MAVLink(Capture(), srcSystem=1, srcComponent=1), HOME)
    s = v.state()
    telemetry.send("SYS_STATUS", s)
    telemetry.send("MISSION_CURRENT", s)
    telemetry.mission_item_reached(7)
    status, current, reached = sent
    assert status.onboard_control_sensors_present & mavlink.MAV_SYS_STATUS_GEOFENCE
    assert not status.onboard_control_sensors_health & mavlink.MAV_SYS_STATUS_GEOFENCE
    assert (current.seq, current.total, current.mission_state, current.mission_mode) == (
        0,
        1,
        mavlink.MISSION_STATE_ACTIVE,
        1,
    )
    assert reached.seq == 7
