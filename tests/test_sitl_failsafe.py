"""The failsafe reactions and the land detector on their own: pure functions of parameters and
state, which sitl_stub.flight.vehicle applies (its flights are in test_sitl_vehicle.py)."""

from __future__ import annotations

import pytest

from sitl_stub.core.modes import FlightMode
from sitl_stub.flight.failsafe import Action, Reaction, geofence_breach, offboard_lost
from sitl_stub.flight.land_detector import TAKEN_OFF_ALT_M, LandDetector


@pytest.mark.parametrize(
    ("com_obl_act", "action"),
    [(0, Action.LAND), (1, Action.HOLD), (2, Action.RETURN), (5, Action.RETURN)],
)
def test_offboard_loss_maps_com_obl_act_in_the_air_and_holds_on_the_ground(
    com_obl_act, action
) -> None:
    assert offboard_lost(com_obl_act, in_air=True) == Reaction(
        action, announce=f"Failsafe: offboard lost, activating {action.value}"
    )
    assert offboard_lost(com_obl_act, in_air=False).action is Action.HOLD


def test_geofence_breach_maps_gf_action_and_keeps_a_return_or_a_landing() -> None:
    safe = (10.0, -5.0)
    assert geofence_breach(1, FlightMode.LOITER, safe) == Reaction(Action.WARN)
    assert geofence_breach(2, FlightMode.OFFBOARD, safe) == Reaction(
        Action.HOLD, safe, "Failsafe: geofence, activating Hold"
    )
    assert geofence_breach(3, FlightMode.MISSION, safe).action is Action.RETURN
    terminate = geofence_breach(4, FlightMode.LOITER, safe)
    assert terminate.action is Action.LAND and terminate.announce.endswith(
        "Land (no termination in SITL)"
    )
    assert geofence_breach(5, FlightMode.LOITER, safe) == Reaction(
        Action.LAND, safe, "Failsafe: geofence, activating Land"
    )
    for mode in (FlightMode.RTL, FlightMode.LAND):
        assert geofence_breach(2, mode, safe) == Reaction(Action.WARN)


def test_land_detector_touches_down_once_and_disarms_after_com_disarm_land() -> None:
    ground = LandDetector()
    ground.armed(t_s=0.0)
    assert (
        not ground.update(1.0, TAKEN_OFF_ALT_M + 1, -2.0, armed=True, wants_up=True)
        and ground.has_flown
    )
    assert ground.update(5.0, 0.0, 0.0, armed=True, wants_up=False)  # touch-down
    assert not ground.update(5.1, 0.0, 0.0, armed=True, wants_up=False)  # once
    assert not ground.disarm_due(6.0, disarm_after_s=2.0, landing_mode=False)
    assert ground.disarm_due(7.0, disarm_after_s=2.0, landing_mode=False)
    assert not ground.disarm_due(70.0, disarm_after_s=0.0, landing_mode=True)  # 0 disables it
    fresh = LandDetector()
    fresh.armed(t_s=0.0)  # armed on the ground, never flown: only a landing mode disarms it
    assert not fresh.disarm_due(10.0, 2.0, landing_mode=False) and fresh.disarm_due(
        10.0, 2.0, landing_mode=True
    )
