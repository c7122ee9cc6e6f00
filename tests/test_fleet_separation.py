"""The fleet's separation filter (SPEC "A fleet"): no action sequence brings two UAVs closer than
the minimum, in the env and in the flight loop's setpoints (both use uavlink.mobility.fleet)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from uavlink.config import EnvConfig
from uavlink.mobility.fleet import min_separation_m, separate, start_positions_m

SEP_M = 20.0


def test_start_positions_spread_on_the_circle():
    np.testing.assert_allclose(start_positions_m(1, 100.0), [[0.0, 0.0]])
    np.testing.assert_allclose(
        start_positions_m(2, 100.0), [[100.0, 0.0], [-100.0, 0.0]], atol=1e-12
    )
    three = start_positions_m(3, 100.0)
    np.testing.assert_allclose(np.linalg.norm(three, axis=1), 100.0)
    assert min_separation_m(three[None])[0] == pytest.approx(100.0 * np.sqrt(3.0))


def test_a_head_on_move_stops_at_the_minimum():
    current = np.array([[[0.0, 0.0], [30.0, 0.0]]])
    target = np.array([[[25.0, 0.0], [30.0, 0.0]]])  # UAV 0 flies 25 m towards UAV 1, which hovers
    out = separate(current, target, SEP_M)
    assert out[0, 0, 0] == pytest.approx(10.0, abs=1e-6)  # stopped 20 m short of UAV 1
    assert min_separation_m(out)[0] >= SEP_M
    np.testing.assert_array_equal(out[0, 1], [30.0, 0.0])


def test_moves_that_keep_apart_are_untouched():
    current = np.array([[[0.0, 0.0], [100.0, 0.0]]])
    target = current + np.array([[[-12.0, 3.0], [5.0, -7.0]]])
    np.testing.assert_array_equal(separate(current, target, SEP_M), target)


@settings(max_examples=60, deadline=None)
@given(
    n_uavs=st.integers(2, 4),
    seed=st.integers(0, 2**31 - 1),
    steps=st.integers(1, 40),
    reach=st.sampled_from([12.0, 40.0]),
)
def test_no_action_sequence_brings_two_uavs_closer_than_the_minimum(n_uavs, seed, steps, reach):
    """Random moves, many aimed straight at another UAV: the minimum holds after every frame."""
    rng = np.random.default_rng(seed)
    n = 16
    xy = np.broadcast_to(start_positions_m(n_uavs, 30.0), (n, n_uavs, 2)).copy()
    for _ in range(steps):
        chase = xy[:, rng.permutation(n_uavs)] - xy  # towards another UAV's spot ...
        noise = rng.uniform(-reach, reach, xy.shape)  # ... or anywhere
        target = xy + np.where(rng.random((n, n_uavs, 1)) < 0.5, chase, noise)
        xy = separate(xy, target, SEP_M)
        assert (min_separation_m(xy) >= SEP_M).all()


def test_fleet_config_checks_the_start_circle():
    from uavlink.errors import ConfigError

    EnvConfig(n_uavs=3).validate()
    with pytest.raises(ConfigError, match="uav_separation_m"):
        EnvConfig(n_uavs=40).validate()
    with pytest.raises(ConfigError, match="fleet_start_radius_m"):
        EnvConfig(n_uavs=2, fleet_start_radius_m=250.0).validate()
    with pytest.raises(ConfigError, match="fleet_reuse"):
        EnvConfig(fleet_reuse="tdma").validate()
