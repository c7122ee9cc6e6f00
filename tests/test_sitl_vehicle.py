"""Kinematics and mode logic of the SITL vehicle (sitl_stub.flight.vehicle), in simulated time only."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sitl_stub.core.modes import FlightMode, LandedState
from sitl_stub.core.params import ParamStore
from sitl_stub.core.vehicle_state import Result
from sitl_stub.flight.vehicle import Vehicle

pytestmark = pytest.mark.timeout(60)

DT = 0.05


def make(**params: float) -> Vehicle:
    return Vehicle(ParamStore(params))


def airborne(alt: float = 10.0) -> Vehicle:
    """Armed, took off to ``alt`` and holding in AUTO.LOITER."""
    v = make(MIS_TAKEOFF_ALT=alt)
    assert v.arm().ok and v.takeoff().ok
    run_until(v, lambda: v.mode is FlightMode.LOITER, 60.0)
    return v


def run_until(v: Vehicle, done, max_s: float, setpoint=None) -> float:
    """Step until ``done()``; streams ``setpoint`` (n, e, d) every step when given. Returns sim s."""
    t0 = v.t
    while not done():
        assert v.t - t0 < max_s, f"not done after {max_s} s: {v.state()}"
        if setpoint is not None:
            v.offer_setpoint(*setpoint)
        v.step(DT)
    return v.t - t0


def start_offboard(v: Vehicle, sp: tuple[float, float, float]) -> None:
    assert v.offer_setpoint(*sp)
    assert v.start_offboard().ok
    assert v.mode is FlightMode.OFFBOARD


def test_starts_disarmed_on_ground_in_loiter():
    s = make().state()
    assert not s.armed and s.mode is FlightMode.LOITER
    assert s.landed_state is LandedState.ON_GROUND
    assert (s.north_m, s.east_m, s.down_m) == (0.0, 0.0, 0.0)


def test_takeoff_climbs_to_mis_takeoff_alt_then_loiters():
    v = make()  # MIS_TAKEOFF_ALT default is the SPEC's 95 m
    assert v.takeoff().result is Result.TEMPORARILY_REJECTED  # disarmed
    assert v.arm().ok and v.takeoff().ok
    v.step(1.0)
    s = v.state()
    assert s.mode is FlightMode.TAKEOFF and s.landed_state is LandedState.TAKEOFF
    assert s.vd_mps >= -v.params["MPC_TKO_SPEED"] - 1e-9
    took = run_until(v, lambda: v.mode is not FlightMode.TAKEOFF, 120.0)
    assert v.mode is FlightMode.LOITER  # never idles in AUTO.READY
    assert took == pytest.approx(95.0 / 1.5, rel=0.1)
    v.step(5.0)
    s = v.state()
    assert s.altitude_m == pytest.approx(95.0, abs=0.1)
    assert s.landed_state is LandedState.IN_AIR and s.ground_speed_mps < 1e-6


def test_takeoff_altitude_argument_overrides_param():
    v = make()
    assert v.arm().ok and v.takeoff(12.0).ok
    run_until(v, lambda: v.mode is FlightMode.LOITER, 60.0)
    v.step(5.0)
    assert v.state().altitude_m == pytest.approx(12.0, abs=0.1)
    assert v.takeoff(-3.0).result is Result.DENIED


def test_horizontal_speed_and_acceleration_limits():
    v = airborne()
    start_offboard(v, (0.0, 0.0, -10.0))
    prev = v.state()
    top = 0.0
    for _ in range(int(30 / DT)):
        v.offer_setpoint(150.0, 150.0, -10.0)
        v.step(DT)
        s = v.state()
        top = max(top, s.ground_speed_mps)
        dv = math.hypot(s.vn_mps - prev.vn_mps, s.ve_mps - prev.ve_mps)
        assert dv <= v.params["MPC_ACC_HOR_MAX"] * DT + 1e-9
        prev = s
    assert top == pytest.approx(12.0, abs=1e-6)  # MPC_XY_VEL_MAX
    assert prev.north_m == pytest.approx(150.0, abs=0.5)
    assert prev.east_m == pytest.approx(150.0, abs=0.5)


def test_lowered_speed_limit_applies_at_once():
    v = airborne()
    start_offboard(v, (0.0, 0.0, -10.0))
    run_until(v, lambda: v.state().ground_speed_mps > 11.9, 20.0, (180.0, 0.0, -10.0))
    assert v.params.set("MPC_XY_VEL_MAX", 5.0)
    v.offer_setpoint(180.0, 0.0, -10.0)
    v.step(DT)
    assert v.state().ground_speed_mps <= 5.0 + 1e-9


def test_reaches_setpoint_without_overshoot():
    v = airborne()
    start_offboard(v, (40.0, -30.0, -20.0))
    max_north = 0.0
    for _ in range(int(40 / DT)):
        v.offer_setpoint(40.0, -30.0, -20.0)
        v.step(DT)
        max_north = max(max_north, v.state().north_m)
    s = v.state()
    assert (s.north_m, s.east_m, s.down_m) == pytest.approx((40.0, -30.0, -20.0), abs=0.05)
    assert max_north <= 40.0 + 0.05


def test_setpoint_outside_geofence_is_clamped_and_never_crossed():
    v = airborne()
    start_offboard(v, (500.0, -900.0, -10.0))
    assert v.state().setpoint_ned == (200.0, -200.0, -10.0)
    assert v.state().setpoints_clamped == 1
    for _ in range(int(60 / DT)):
        v.offer_setpoint(500.0, -900.0, -10.0)
        v.step(DT)
        s = v.state()
        assert abs(s.north_m) <= 200.0 and abs(s.east_m) <= 200.0
    assert (s.north_m, s.east_m) == pytest.approx((200.0, -200.0), abs=0.05)


def test_setpoint_below_ground_is_clamped_to_ground():
    v = airborne()
    start_offboard(v, (0.0, 0.0, 30.0))
    assert v.state().setpoint_ned == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_setpoint_is_rejected(bad):
    v = airborne()
    start_offboard(v, (10.0, 10.0, -10.0))
    assert not v.offer_setpoint(bad, 0.0, -10.0)
    assert not v.offer_setpoint(0.0, 0.0, bad)
    s = v.state()
    assert s.setpoint_ned == (10.0, 10.0, -10.0)
    assert s.setpoints_rejected == 2 and s.setpoints_accepted == 1


def test_offboard_refused_without_a_recent_stream():
    v = airborne()
    out = v.start_offboard()
    # PX4's commander answers a refused mode change TEMPORARILY_REJECTED: try again later.
    assert out.result is Result.TEMPORARILY_REJECTED and "setpoint" in out.reason
    v.offer_setpoint(5.0, 5.0, -10.0)
    v.step(1.2)  # older than COM_OF_LOSS_T
    assert v.start_offboard().result is Result.TEMPORARILY_REJECTED
    assert v.mode is FlightMode.LOITER
    v.offer_setpoint(5.0, 5.0, -10.0)
    assert v.start_offboard().ok


def test_offboard_loss_fails_safe_to_loiter_after_com_of_loss_t():
    v = airborne()
    start_offboard(v, (0.0, 0.0, -10.0))
    run_until(v, lambda: v.state().ground_speed_mps > 5.0, 20.0, (100.0, 0.0, -10.0))
    v.step(0.9)  # stream stopped, still within COM_OF_LOSS_T = 1.0 s
    assert v.mode is FlightMode.OFFBOARD
    v.step(0.2)
    s = v.state()
    assert s.mode is FlightMode.LOITER and s.offboard_failsafes == 1
    assert any("offboard lost" in text for _, text in v.drain_events())
    v.step(20.0)  # brakes and holds, does not continue to the setpoint
    held = v.state()
    assert held.ground_speed_mps < 0.01 and held.north_m < 100.0 - 5.0
    assert held.altitude_m == pytest.approx(10.0, abs=0.2)


def test_offboard_loss_timeout_is_a_parameter():
    v = airborne()
    v.params.set("COM_OF_LOSS_T", 3.0)
    start_offboard(v, (0.0, 0.0, -10.0))
    v.step(2.5)
    assert v.mode is FlightMode.OFFBOARD
    v.step(1.0)
    assert v.mode is FlightMode.LOITER


@pytest.mark.parametrize(("action", "mode"), [(0, FlightMode.LAND), (2, FlightMode.RTL)])
def test_offboard_loss_action_is_configurable(action, mode):
    v = airborne()
    v.params.set("COM_OBL_ACT", action)
    start_offboard(v, (0.0, 0.0, -10.0))
    v.step(1.5)
    assert v.mode is mode


def test_land_then_auto_disarm_after_com_disarm_land():
    v = airborne(8.0)
    assert v.land().ok
    v.step(1.0)
    assert v.state().landed_state is LandedState.LANDING
    run_until(v, lambda: v.state().landed_state is LandedState.ON_GROUND, 60.0)
    s = v.state()
    assert s.armed and s.altitude_m == 0.0
    v.step(1.5)
    assert v.armed  # COM_DISARM_LAND = 2 s
    v.step(0.6)
    s = v.state()
    assert not s.armed and s.mode is FlightMode.LOITER


def test_landing_descent_rates():
    v = airborne(20.0)
    v.land()
    run_until(v, lambda: v.state().altitude_m < 15.0, 30.0)
    assert v.state().vd_mps == pytest.approx(v.params["MPC_Z_VEL_MAX_DN"], abs=1e-6)
    run_until(v, lambda: v.state().altitude_m < 3.0, 30.0)
    assert v.state().vd_mps == pytest.approx(v.params["MPC_LAND_SPEED"], abs=1e-6)


def test_rtl_climbs_returns_home_and_lands():
    v = airborne(20.0)
    start_offboard(v, (120.0, -80.0, -20.0))
    run_until(
        v,
        lambda: math.dist((v.pos[0], v.pos[1]), (120.0, -80.0)) < 0.5,
        60.0,
        (120.0, -80.0, -20.0),
    )
    assert v.return_to_launch().ok
    max_alt = 0.0
    while v.armed:
        assert v.t < 400.0
        v.step(DT)
        max_alt = max(max_alt, v.state().altitude_m)
        assert v.state().ground_speed_mps <= v.params["MPC_XY_CRUISE"] + 1e-9
    s = v.state()
    assert max_alt == pytest.approx(v.params["RTL_RETURN_ALT"], abs=0.5)
    assert (s.north_m, s.east_m, s.altitude_m) == pytest.approx((0.0, 0.0, 0.0), abs=0.05)


def test_arming_rules():
    v = make()
    assert v.land().ok  # mode change on the ground is allowed ...
    assert v.arm().result is Result.TEMPORARILY_REJECTED  # ... but AUTO.LAND prevents arming (PX4)
    assert v.hold().ok and v.arm().ok
    assert v.arm().ok  # idempotent
    v.takeoff(10.0)
    v.step(3.0)
    assert v.disarm().result is Result.TEMPORARILY_REJECTED  # in the air
    assert v.disarm(force=True).ok
    v.step(5.0)  # falls
    s = v.state()
    assert not s.armed and s.altitude_m == 0.0 and s.landed_state is LandedState.ON_GROUND


def test_set_mode_dispatch_and_reentry_is_noop():
    v = airborne()
    assert v.set_mode(FlightMode.LOITER).ok
    assert v.set_mode(FlightMode.OFFBOARD).result is Result.TEMPORARILY_REJECTED
    assert v.set_mode(FlightMode.RTL).ok and v.mode is FlightMode.RTL
    assert v.set_mode(FlightMode.LAND).ok and v.mode is FlightMode.LAND


def test_step_rejects_bad_dt():
    with pytest.raises(ValueError):
        make().step(-1.0)
    with pytest.raises(ValueError):
        make().step(math.nan)


_coord = st.floats(min_value=-1000.0, max_value=1000.0, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    st.lists(
        st.tuples(
            _coord,
            _coord,
            st.floats(min_value=-150.0, max_value=50.0),
            st.floats(min_value=0.1, max_value=8.0),
        ),
        min_size=1,
        max_size=6,
    )
)
def test_any_setpoint_sequence_stays_inside_fence_and_limits(plan):
    v = airborne(5.0)
    start_offboard(v, (0.0, 0.0, -5.0))
    for n, e, d, hold_s in plan:
        for _ in range(int(hold_s / 0.25)):
            v.offer_setpoint(n, e, d)
            v.step(0.25)
            s = v.state()
            assert abs(s.north_m) <= 200.0 and abs(s.east_m) <= 200.0
            assert s.down_m <= 0.0
            assert s.ground_speed_mps <= 12.0 + 1e-9
            assert -3.0 - 1e-9 <= s.vd_mps <= 1.5 + 1e-9
