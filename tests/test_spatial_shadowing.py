"""The spatially consistent channel (SPEC "A spatially consistent channel"): its checks."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import AreaConfig, EnvConfig, RadioConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.radio.channel import RadioChannel
from uavlink.radio.spatial_shadowing import SpatialShadowField

SPATIAL = RadioConfig(shadowing_model="spatial")
N_FIELDS = 40_000  # episodes (fields) behind each statistic


def _fields(seed: int = 0, radio: RadioConfig = SPATIAL) -> SpatialShadowField:
    return SpatialShadowField.draw(np.random.default_rng(seed), N_FIELDS, radio)


def _at(field: SpatialShadowField, uav_xy_m, ue_xy_m) -> np.ndarray:
    uav = np.broadcast_to(np.asarray(uav_xy_m, float), (N_FIELDS, 1, 2))
    ue = np.broadcast_to(np.asarray(ue_xy_m, float), (N_FIELDS, 1, 2))
    return field.shadow_db(uav, ue)[:, 0, 0]


def test_marginal_is_zero_mean_with_8_db_std():
    values = _at(_fields(1), [30.0, -20.0], [-60.0, 45.0])
    assert values.mean() == pytest.approx(0.0, abs=0.15)
    assert values.std() == pytest.approx(8.0, abs=0.3)


@pytest.mark.parametrize(
    ("distance_m", "expected"), [(10, 0.82), (25, 0.61), (50, 0.37), (100, 0.14)]
)
@pytest.mark.parametrize("end", ["ue", "uav"])
def test_correlation_follows_exp_minus_distance_over_50_m(distance_m, expected, end):
    field = _fields(2)
    uav, ue = np.array([10.0, 20.0]), np.array([-40.0, 70.0])
    step = np.array([distance_m * np.cos(0.7), distance_m * np.sin(0.7)])
    before = _at(field, uav, ue)
    after = _at(field, uav + step, ue) if end == "uav" else _at(field, uav, ue + step)
    assert np.corrcoef(before, after)[0, 1] == pytest.approx(expected, abs=0.05)


def test_both_ends_moving_25_m_multiply_their_correlations():
    field = _fields(3)
    before = _at(field, [0.0, 0.0], [50.0, 50.0])
    after = _at(field, [25.0, 0.0], [50.0, 75.0])
    assert np.corrcoef(before, after)[0, 1] == pytest.approx(0.37, abs=0.05)


def test_the_uav_end_can_have_its_own_decorrelation_distance():
    field = _fields(4, RadioConfig(shadowing_model="spatial", shadowing_uav_decorrelation_m=25.0))
    before, after = _at(field, [0.0, 0.0], [0.0, 0.0]), _at(field, [25.0, 0.0], [0.0, 0.0])
    assert np.corrcoef(before, after)[0, 1] == pytest.approx(np.exp(-1.0), abs=0.05)


def _channel_shadow(radio: RadioConfig, uav_path_m, ue_xy_m, seed: int = 5) -> list[np.ndarray]:
    """The links' shadowing (N=8, U=3, D=1) as a UAV flies ``uav_path_m`` over fixed UEs."""
    channel = RadioChannel(radio, AreaConfig(), n_ues=3)
    rng = np.random.default_rng(seed)
    ue = np.broadcast_to(np.asarray(ue_xy_m, float), (8, 3, 2)).copy()
    uav = lambda xy: np.broadcast_to(np.asarray(xy, float), (8, 1, 2)).copy()  # noqa: E731
    channel.reset(rng, uav(uav_path_m[0]), ue)
    shadows = [channel.shadow_db]
    for xy in uav_path_m[1:]:
        channel.step(rng, uav(xy), ue)
        shadows.append(channel.shadow_db)
    return shadows


UES = [[-30.0, 10.0], [40.0, 40.0], [0.0, -80.0]]


def test_a_uav_that_returns_reads_the_same_shadowing():
    there_and_back = _channel_shadow(SPATIAL, [[0, 0], [12, 0], [0, 0]], UES)
    np.testing.assert_array_equal(there_and_back[0], there_and_back[2])
    assert not np.allclose(there_and_back[0], there_and_back[1])


def test_a_zig_zag_sees_two_values_not_fresh_draws():
    shadows = _channel_shadow(SPATIAL, [[0, 0], [12, 0]] * 5, UES)
    for k, shadow in enumerate(shadows):
        np.testing.assert_array_equal(shadow, shadows[k % 2])
    # The AR(1) model re-draws part of the shadowing at every move: its zig-zag never repeats.
    ar1 = _channel_shadow(RadioConfig(), [[0, 0], [12, 0]] * 5, UES)
    assert not np.allclose(ar1[0], ar1[2])


def test_shadowing_off_means_zero_in_either_model():
    radio = RadioConfig(shadowing=False, shadowing_model="spatial")
    assert all(np.all(s == 0) for s in _channel_shadow(radio, [[0, 0], [12, 0]], UES))


def _episode(model: str, seed: int) -> list[np.ndarray]:
    cfg = EnvConfig(scenario="hotspot").replace(**{"radio.shadowing_model": model}).validate()
    env = BatchedUavEnv(cfg, n_envs=4, seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, (cfg.episode_frames, 4, 2))
    return [env.reset(), *(env.step(a).observation for a in actions)]


def test_seeded_spatial_episodes_reproduce_bit_for_bit():
    for a, b in zip(_episode("spatial", 7), _episode("spatial", 7), strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(_episode("spatial", 7)[-1], _episode("spatial", 8)[-1])


def test_the_default_channel_is_still_ar1():
    assert RadioConfig().shadowing_model == "ar1"
    with pytest.raises(ValueError, match="radio.shadowing_model must be one of ar1, spatial"):
        EnvConfig().replace(**{"radio.shadowing_model": "gauss"}).validate()


def test_several_uavs_read_one_field_and_two_over_one_spot_read_the_same():
    field = SpatialShadowField.draw(np.random.default_rng(9), 6, SPATIAL)
    ue = np.random.default_rng(10).uniform(-200, 200, (6, 4, 2))
    uavs = np.array([[[0.0, 0.0], [30.0, -40.0], [0.0, 0.0]]] * 6)
    both = field.shadow_db(uavs, ue)  # (6, 4, 3)
    for d in range(3):
        np.testing.assert_allclose(
            both[:, :, d], field.shadow_db(uavs[:, d : d + 1], ue)[:, :, 0], atol=1e-4
        )
    np.testing.assert_array_equal(both[:, :, 0], both[:, :, 2])
