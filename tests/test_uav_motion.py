"""env.uav_motion = "px4": the UAV flies to its setpoint as sitl_stub's PX4 position loop does, and
the move shifts the setpoint (as ``uavlink fly`` sends it); "instant", the default, is the paper's."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import uavlink.mobility.uav_motion as uav_motion
from sitl_stub.core.params import ParamStore
from sitl_stub.flight.pos_control import hold_in_fence, track
from sitl_stub.flight.vehicle import SUBSTEP_S
from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.errors import ConfigError
from uavlink.mobility.uav_motion import PX4_MOTION


@pytest.mark.parametrize("fence_m", [math.inf, 40.0])
def test_the_position_loop_is_sitl_stubs(fence_m: float) -> None:
    """Random starts, velocities and setpoints: one frame of the batched loop lands where
    sitl_stub's controller and hard fence, substep by substep, fly the same vehicle, to the bit (a
    lockstep flight is to equal its PX4-motion evaluation, and a policy's episode turns on the last
    bits); with a 40 m fence most vehicles are carried onto it."""
    rng = np.random.default_rng(0)
    pos, vel = rng.uniform(-40, 40, (200, 2)), rng.uniform(-12, 12, (200, 2))
    setpoint = np.clip(pos + rng.uniform(-30, 30, (200, 2)), -fence_m, fence_m)
    got_pos, got_vel = PX4_MOTION.fly(pos, vel, setpoint, 1.0, fence_m)
    # the limits are the vehicle's default parameters (the gain and braking are track()'s own, below)
    params = ParamStore()
    assert (PX4_MOTION.max_speed_mps, PX4_MOTION.max_accel_mps2) == (
        params["MPC_XY_VEL_MAX"],
        params["MPC_ACC_HOR_MAX"],
    )
    fenced = 0
    for i in range(len(pos)):
        p, v = [pos[i, 0], pos[i, 1], -95.0], [vel[i, 0], vel[i, 1], 0.0]
        for _ in range(round(1.0 / SUBSTEP_S)):
            track(
                p,
                v,
                (setpoint[i, 0], setpoint[i, 1], -95.0),
                (PX4_MOTION.max_speed_mps, 3.0, 1.5),
                PX4_MOTION.max_accel_mps2,
                SUBSTEP_S,
            )
            hold_in_fence(p, v, fence_m)
            fenced += max(abs(p[0]), abs(p[1])) == fence_m
        np.testing.assert_array_equal(got_pos[i], p[:2])
        np.testing.assert_array_equal(got_vel[i], v[:2])
    assert (fenced > 0) == (fence_m < math.inf)


def _flown(motion: str, moves: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """The UAV's positions and setpoints (frames + 1, 2) over cartesian moves in [-1, 1]."""
    cfg = EnvConfig(scenario="no_move", uav_motion=motion).validate()
    env = BatchedUavEnv(cfg, 1, seed=0)
    env.reset()
    positions, setpoints = [env.uav_xy_m[0].copy()], [env.setpoint_xy_m[0].copy()]
    for move in moves:
        env.step(np.array([move]))
        positions.append(env.uav_xy_m[0].copy())
        setpoints.append(env.setpoint_xy_m[0].copy())
    return np.array(positions), np.array(setpoints)


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    rows=st.integers(1, 8),
    fence_m=st.sampled_from([math.inf, 30.0]),
    duration_s=st.sampled_from([0.0, 0.013, 1.0, 2.37]),
)
def test_the_float_kernel_flies_numpys_bits(
    seed: int, rows: int, fence_m: float, duration_s: float
) -> None:
    """A few rows fly in Python floats, many in numpy: the same starts, velocities and setpoints
    (some at the setpoint, some carried onto the fence) give the same positions, paths and
    velocities to the bit, so a flight's guard predicts what the env's batch does."""
    rng = np.random.default_rng(seed)
    pos, vel = rng.uniform(-40, 40, (rows, 2)), rng.uniform(-12, 12, (rows, 2))
    setpoint = np.where(rng.random((rows, 1)) < 0.2, pos, pos + rng.uniform(-30, 30, (rows, 2)))
    vel[rng.random(rows) < 0.2] = 0.0

    def both_kernels() -> tuple[np.ndarray, ...]:
        flown = PX4_MOTION.fly(pos, vel, setpoint, duration_s, fence_m)
        return (*flown, PX4_MOTION.path(pos, vel, setpoint, 40, fence_m))

    floats = both_kernels()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(uav_motion, "FLOAT_KERNEL_MAX_ROWS", 0)
        numpy = both_kernels()
    for a, b in zip(floats, numpy, strict=True):
        assert a.shape == b.shape
        np.testing.assert_array_equal(a, b)


def test_a_full_speed_move_from_a_hover_takes_px4_more_than_a_frame() -> None:
    east = [(1.0, 0.0)] * 6 + [
        (0.0, 0.0)
    ] * 14  # 72 m east at the paper's 12 m per frame, then hover
    instant, _ = _flown("instant", east)
    px4, setpoints = _flown("px4", east)
    np.testing.assert_allclose(instant[6], [72.0, 0.0])
    np.testing.assert_allclose(setpoints[6:], [[72.0, 0.0]] * 15)  # the moves shift the setpoint
    steps_m = np.linalg.norm(np.diff(px4, axis=0), axis=1)
    assert 2.0 < steps_m[0] < 3.0  # 5 m/s^2 from a hover: 2.5 m in the first second
    assert (steps_m <= 12.0 + 1e-9).all()  # never faster than MPC_XY_VEL_MAX
    assert px4[6, 0] < 60.0  # still trailing its setpoint when the moves stop
    np.testing.assert_allclose(px4[-1], [72.0, 0.0], atol=0.5)  # and there without overshoot
    assert px4[:, 0].max() <= 72.0 + 1e-9


def test_px4_motion_flies_one_uav_or_a_fleet() -> None:
    with pytest.raises(ConfigError, match="unknown uav_motion"):
        EnvConfig(uav_motion="teleport").validate()
    # a fleet's setpoints move as the flight loop's (tests/test_fleet_px4.py)
    for n_uavs in (1, 2, 3):
        assert EnvConfig(uav_motion="px4", n_uavs=n_uavs).validate().n_uavs == n_uavs


def test_the_genie_plans_instant_moves_beside_a_px4_uav() -> None:
    """Compared with a policy whose UAV flies as PX4 does, the genie gets the same world with instant
    moves (its bound: a PX4 path moves at most r_max per frame too)."""
    from uavlink.policies.contract import EnvOverrides, load_with_env

    overrides = EnvOverrides(scenario="no_move", settings={"uav_motion": "px4"})
    (_, static_cfg), (genie, genie_cfg) = load_with_env(["static", "genie"], overrides)
    assert (
        static_cfg.uav_motion == "px4" and genie_cfg.uav_motion == genie.cfg.uav_motion == "instant"
    )
    assert genie_cfg.replace(uav_motion="px4") == static_cfg
