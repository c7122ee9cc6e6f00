"""Radio model: known answers from the SPEC's link budget, and statistics of the random parts.

Every statistical test draws from a fixed seed, so it is deterministic; the tolerances are several
standard errors wide, so a correct model passes for any seed and a wrong one (a factor, an exponent,
a missing term) fails by far more.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from uavlink.config import AreaConfig, RadioConfig
from uavlink.radio import (
    RadioChannel,
    circular_mean_std_deg,
    distance_3d_m,
    fair_rate,
    mean_rician_power_gain,
    mean_rx_power_dbm,
    measured_aoa_deg,
    noise_power_dbm,
    path_loss_db,
    rate_bps,
    rician_gain_table,
    rician_power_gain,
    round_robin_rbs,
    tabulated_rician_power_gain,
    true_aoa_deg,
    wrap_deg,
)
from uavlink.radio.shadowing import initial_shadowing_db, update_shadowing_db

QUIET = RadioConfig(shadowing=False, fast_fading=False)  # mean channel: deterministic
AREA = AreaConfig()
HOVER_SNR_DB = 19.0 - (128.1 + 37.6 * math.log10(0.095)) + 95.0  # 24.34 dB straight overhead


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# --- path loss, noise, link budget -------------------------------------------------------------


@pytest.mark.parametrize(
    ("distance_m", "expected_db"),
    [
        (1000.0, 128.1),
        (100.0, 128.1 - 37.6),  # 90.5 dB
        (95.0, 128.1 + 37.6 * math.log10(0.095)),
        (10_000.0, 128.1 + 37.6),
    ],
)
def test_path_loss_known_answers(distance_m, expected_db):
    assert float(path_loss_db(distance_m)) == pytest.approx(expected_db, abs=1e-9)


def test_path_loss_floored_at_35_m():
    at_35 = 128.1 + 37.6 * math.log10(0.035)  # 73.35 dB
    near = path_loss_db(np.array([0.0, 1.0, 20.0, 34.999, 35.0]))
    np.testing.assert_allclose(near, at_35, atol=1e-3)
    assert float(path_loss_db(36.0)) > at_35 + 0.4  # and it grows again past the floor


def test_path_loss_is_monotonic_in_distance():
    d = np.linspace(35.0, 2000.0, 500)
    assert np.all(np.diff(path_loss_db(d)) > 0)


def test_noise_floor_known_answers():
    assert noise_power_dbm(10e6) == pytest.approx(-95.0, abs=1e-9)
    assert noise_power_dbm(RadioConfig().rb_bandwidth_hz) == pytest.approx(-112.0, abs=0.02)
    assert RadioConfig().rb_bandwidth_hz == pytest.approx(200e3)
    # The noise figure and bandwidth enter as they should.
    assert noise_power_dbm(10e6, RadioConfig(noise_figure_db=5.0)) == pytest.approx(-99.0)
    assert noise_power_dbm(20e6) - noise_power_dbm(10e6) == pytest.approx(10 * math.log10(2))


def test_received_power_budget():
    assert float(mean_rx_power_dbm(1000.0)) == pytest.approx(19.0 - 128.1)
    o2i = RadioConfig(outdoor_to_indoor_loss_db=10.0, antenna_gain_db=3.0)
    assert float(mean_rx_power_dbm(1000.0, o2i)) == pytest.approx(19.0 + 3.0 - 10.0 - 128.1)


def test_distance_3d_shape_and_value():
    uav = np.array([[[0.0, 0.0], [30.0, 40.0]]])  # (N=1, D=2, 2)
    ue = np.array([[[0.0, 0.0], [3.0, 4.0], [30.0, 40.0]]])  # (N=1, U=3, 2)
    d = distance_3d_m(uav, ue, 95.0)
    assert d.shape == (1, 3, 2)
    assert d[0, 0, 0] == pytest.approx(95.0)
    assert d[0, 1, 0] == pytest.approx(math.sqrt(25 + 95**2))
    assert d[0, 0, 1] == pytest.approx(math.sqrt(2500 + 95**2))
    assert d[0, 2, 1] == pytest.approx(95.0)


def test_round_robin_and_rates():
    np.testing.assert_array_equal(round_robin_rbs(50, 10), [5] * 10)
    uneven = round_robin_rbs(50, 7)
    assert uneven.sum() == 50 and uneven.max() - uneven.min() == 1
    # R_u = (B / U) log2(1 + SINR)
    assert float(rate_bps(np.array(1.0), 10e6, 10)) == pytest.approx(1e6)
    assert float(rate_bps(np.array(3.0), 10e6, 10)) == pytest.approx(2e6)
    # R_fair = sum_u log10(R_u), R_u in bit/s
    assert float(fair_rate(np.array([1e6, 1e7, 1e5]))) == pytest.approx(6 + 7 + 5)


def test_hover_over_static_ue_gives_8_mbps():
    """The SPEC's calibration point: straight overhead at 95 m, no shadowing or fading."""
    channel = RadioChannel(QUIET, AREA, n_ues=10)
    uav = np.zeros((1, 1, 2))
    ue = np.zeros((1, 10, 2))
    first = channel.reset(rng(), uav, ue)
    np.testing.assert_allclose(first.sinr_db, HOVER_SNR_DB, atol=1e-9)
    assert pytest.approx(24.34, abs=0.01) == HOVER_SNR_DB
    expected_bps = 1e6 * math.log2(1 + 10 ** (HOVER_SNR_DB / 10))
    np.testing.assert_allclose(first.rate_bps, expected_bps, rtol=1e-12)
    assert expected_bps / 1e6 == pytest.approx(8.09, abs=0.02)
    again = channel.step(rng(), uav, ue)  # nothing moves, nothing random: the same frame
    np.testing.assert_array_equal(again.sinr_db, first.sinr_db)


def test_rate_falls_with_distance():
    channel = RadioChannel(QUIET, AREA, n_ues=4)
    ue = np.array([[[0.0, 0.0], [50.0, 0.0], [200.0, 0.0], [400.0, 400.0]]])
    readings = channel.reset(rng(), np.zeros((1, 1, 2)), ue)
    assert np.all(np.diff(readings.rate_bps[0]) < 0)
    # Far corner of the area (566 m horizontal, 574 m 3-D): SNR -5.0 dB, 0.39 Mbps per UE of 10.
    ten = RadioChannel(QUIET, AREA, n_ues=10)
    far = ten.reset(rng(), np.array([[[200.0, 200.0]]]), np.full((1, 10, 2), -200.0))
    np.testing.assert_allclose(far.sinr_db, -5.02, atol=0.01)
    np.testing.assert_allclose(far.rate_bps, 0.395e6, rtol=0.01)


# --- fast fading -------------------------------------------------------------------------------


def test_rician_gain_has_unit_mean_and_right_variance():
    k = 10.0  # K = 10 dB
    gains = rician_power_gain(rng(1), (400_000,), k_db=10.0)
    assert gains.min() >= 0.0
    assert gains.mean() == pytest.approx(1.0, abs=0.003)
    # Var |h|^2 = (1 + 2K) / (K + 1)^2 for a unit-mean Rician power gain.
    assert gains.var() == pytest.approx((1 + 2 * k) / (k + 1) ** 2, rel=0.02)
    # K -> infinity is no fading; K = -inf dB (0) is Rayleigh: exponential with variance 1.
    rayleigh = rician_power_gain(rng(2), (400_000,), k_db=-300.0)
    assert rayleigh.mean() == pytest.approx(1.0, abs=0.005)
    assert rayleigh.var() == pytest.approx(1.0, rel=0.02)


@pytest.mark.parametrize("n_rbs", [1, 5, 6])
def test_mean_of_n_draw_matches_n_per_rb_draws(n_rbs):
    """The one-shot draw of the mean of n RB gains has the distribution of the explicit mean."""
    samples = 200_000
    exact = mean_rician_power_gain(rng(3), (samples,), np.array(n_rbs), k_db=10.0)
    explicit = rician_power_gain(rng(4), (samples, n_rbs), k_db=10.0).mean(axis=1)
    assert exact.min() >= 0.0
    assert exact.mean() == pytest.approx(1.0, abs=0.003)
    assert exact.mean() == pytest.approx(explicit.mean(), abs=0.004)
    assert exact.var() == pytest.approx(explicit.var(), rel=0.03)
    k = 10.0
    assert exact.var() == pytest.approx((1 + 2 * k) / (k + 1) ** 2 / n_rbs, rel=0.03)
    # Two-sample Kolmogorov-Smirnov distance: the whole distribution agrees, not only 2 moments.
    grid = np.quantile(explicit, np.linspace(0.001, 0.999, 400))
    cdf_exact = np.searchsorted(np.sort(exact), grid) / samples
    cdf_explicit = np.searchsorted(np.sort(explicit), grid) / samples
    assert np.abs(cdf_exact - cdf_explicit).max() < 0.01  # KS critical value at 1e-3: ~0.006


@pytest.mark.parametrize("k_db", [10.0, 0.0, -300.0, 25.0])
def test_tabulated_gain_has_the_rician_law(k_db):
    """The table (equiprobable strata, built by integrating the density) has the exact mean and
    variance of the unit-mean Rician power gain, and its draws the distribution of the exact ones."""
    k = 10.0 ** (k_db / 10.0)
    table = rician_gain_table(k_db).astype(float)
    assert table.mean() == pytest.approx(1.0, abs=1e-6)
    assert table.var() == pytest.approx((1 + 2 * k) / (k + 1) ** 2, rel=1e-4)
    assert np.all(np.diff(table) >= 0.0) and table[0] >= 0.0
    samples = 400_000
    drawn = tabulated_rician_power_gain(rng(7), (samples,), k_db)
    exact = rician_power_gain(rng(8), (samples,), k_db)
    assert drawn.dtype == np.float32 and drawn.mean() == pytest.approx(1.0, abs=0.005)
    grid = np.quantile(exact, np.linspace(0.001, 0.999, 400))
    cdf_drawn = np.searchsorted(np.sort(drawn), grid) / samples
    cdf_exact = np.searchsorted(np.sort(exact), grid) / samples
    assert np.abs(cdf_drawn - cdf_exact).max() < 0.006  # two-sample KS critical value at 1e-3
    np.testing.assert_array_equal(drawn, tabulated_rician_power_gain(rng(7), (samples,), k_db))


def test_mean_of_n_draw_broadcasts_rb_counts():
    counts = round_robin_rbs(50, 7)  # 8, 7, 7, ... RBs per UE
    gains = mean_rician_power_gain(rng(5), (50_000, 7), counts, k_db=10.0)
    assert gains.shape == (50_000, 7)
    variance = gains.var(axis=0)
    k = 10.0
    np.testing.assert_allclose(variance, (1 + 2 * k) / (k + 1) ** 2 / counts, rtol=0.05)


# --- shadowing ---------------------------------------------------------------------------------


def test_shadowing_std_is_8_db():
    shadow = initial_shadowing_db(rng(6), (200_000,), RadioConfig())
    assert shadow.mean() == pytest.approx(0.0, abs=0.05)
    assert shadow.std() == pytest.approx(8.0, rel=0.01)
    assert np.all(initial_shadowing_db(rng(6), (10,), RadioConfig(shadowing=False)) == 0.0)


def test_shadowing_update_is_stationary_with_gudmundson_correlation():
    radio = RadioConfig()
    before = initial_shadowing_db(rng(7), (200_000,), radio)
    for displacement, rho in (
        (0.0, 1.0),
        (10.0, math.exp(-0.2)),
        (50.0, math.exp(-1.0)),
        (500.0, math.exp(-10.0)),
    ):
        after = update_shadowing_db(rng(8), before, np.full(before.shape, displacement), radio)
        assert after.std() == pytest.approx(8.0, rel=0.01)  # AR(1) keeps the marginal
        assert np.corrcoef(before, after)[0, 1] == pytest.approx(rho, abs=0.01)


def _shadow_pairs(uav0, ue0, uav1, ue1, n=20_000, seed=9):
    """SINR (dB) of one link before and after a move that keeps its 3-D distance, fading off."""
    radio = RadioConfig(fast_fading=False)
    channel = RadioChannel(radio, AREA, n_ues=1)
    tile = lambda xy: np.tile(np.asarray(xy, float), (n, 1, 1))  # noqa: E731
    before = channel.reset(rng(seed), tile([uav0]), tile([ue0])).sinr_db[:, 0]
    after = channel.step(rng(seed + 1), tile([uav1]), tile([ue1])).sinr_db[:, 0]
    return before, after


def test_channel_shadowing_std_and_correlation_over_50_m_ue_move():
    # The UE moves 50 m along a chord of a circle round the UAV: the path loss is unchanged,
    # so the SINR change is the shadowing change alone.
    radius = 100.0
    half_angle = math.asin(25.0 / radius)  # chord of 50 m
    start = [radius * math.cos(-half_angle), radius * math.sin(-half_angle)]
    end = [radius * math.cos(half_angle), radius * math.sin(half_angle)]
    before, after = _shadow_pairs([0.0, 0.0], start, [0.0, 0.0], end)
    mean_db = float(mean_rx_power_dbm(math.hypot(radius, 95.0))) + 95.0
    assert before.mean() == pytest.approx(mean_db, abs=0.15)
    assert before.std() == pytest.approx(8.0, rel=0.02)
    assert after.std() == pytest.approx(8.0, rel=0.02)
    assert np.corrcoef(before, after)[0, 1] == pytest.approx(math.exp(-1.0), abs=0.02)


def test_channel_shadowing_decorrelates_over_combined_ue_and_uav_move():
    # UAV and UE both move 25 m north: same geometry, combined displacement 50 m.
    before, after = _shadow_pairs([0.0, 0.0], [80.0, 0.0], [0.0, 25.0], [80.0, 25.0])
    assert np.corrcoef(before, after)[0, 1] == pytest.approx(math.exp(-1.0), abs=0.02)
    # Nothing moves: the shadowing is frozen (correlation 1, identical values).
    still_before, still_after = _shadow_pairs([0.0, 0.0], [80.0, 0.0], [0.0, 0.0], [80.0, 0.0])
    np.testing.assert_array_equal(still_before, still_after)


def test_channel_shadow_db_is_what_the_readings_add_and_a_copy():
    radio = RadioConfig(fast_fading=False)
    channel = RadioChannel(radio, AREA, n_ues=10)
    with pytest.raises(RuntimeError, match="before reset"):
        _ = channel.shadow_db
    uav, ue = np.zeros((4, 1, 2)), np.full((4, 10, 2), 60.0)
    readings = channel.reset(rng(3), uav, ue)
    shadow = channel.shadow_db
    without = float(mean_rx_power_dbm(math.hypot(60.0 * math.sqrt(2), 95.0))) - channel.noise_dbm
    np.testing.assert_allclose(readings.sinr_db, without + shadow[..., 0], atol=1e-9)
    shadow[:] = 0.0  # a copy: the channel is untouched
    assert np.abs(channel.shadow_db).max() > 1.0


def test_channel_fading_spreads_sinr_with_unit_mean_gain():
    radio = RadioConfig(shadowing=False)
    channel = RadioChannel(radio, AREA, n_ues=10)
    readings = channel.reset(rng(10), np.zeros((5000, 1, 2)), np.zeros((5000, 10, 2)))
    linear_ratio = 10 ** ((readings.sinr_db - HOVER_SNR_DB) / 10)
    assert linear_ratio.mean() == pytest.approx(1.0, abs=0.005)  # fading is unit-mean in power
    assert linear_ratio.std() == pytest.approx(math.sqrt(21 / 121 / 5), rel=0.05)  # 5 RBs per UE


# --- AoA and circular statistics ---------------------------------------------------------------


def test_wrap_deg_range():
    assert float(wrap_deg(180.0)) == -180.0
    assert float(wrap_deg(-180.0)) == -180.0
    assert float(wrap_deg(540.0)) == -180.0
    assert float(wrap_deg(359.0)) == pytest.approx(-1.0)
    assert float(wrap_deg(-190.0)) == pytest.approx(170.0)
    wide = wrap_deg(rng(11).uniform(-5000.0, 5000.0, 100_000))
    assert wide.min() >= -180.0 and wide.max() < 180.0
    # Just below -180 by a rounding hair: x % 360 rounds to 360.0; the result must still be < 180.
    hair = wrap_deg(-180.0 - rng(12).uniform(0.0, 1e-12, 100_000))
    assert hair.min() >= -180.0 and hair.max() < 180.0


def test_circular_mean_across_the_wrap():
    mean, std = circular_mean_std_deg(np.array([179.0, -179.0]))
    assert float(mean) == pytest.approx(-180.0, abs=1e-9)  # not the naive 0
    assert float(std) == pytest.approx(
        math.degrees(math.sqrt(-2 * math.log(math.cos(math.radians(1)))))
    )
    mean, std = circular_mean_std_deg(np.array([170.0, -170.0, 180.0]))
    assert abs(float(wrap_deg(mean - 180.0))) < 1e-9
    mean, _ = circular_mean_std_deg(np.array([10.0, 350.0]))
    assert float(mean) == pytest.approx(0.0, abs=1e-9)


def test_circular_std_of_identical_angles_is_zero_and_batches():
    angles = np.array([[42.0] * 10, [-180.0] * 10, [179.5] * 10])
    mean, std = circular_mean_std_deg(angles)
    np.testing.assert_allclose(mean, [42.0, -180.0, 179.5], atol=1e-9)
    np.testing.assert_allclose(std, 0.0, atol=1e-5)
    # Opposite pairs have no preferred direction: R = 0, std large (clipped, finite).
    _, spread = circular_mean_std_deg(np.array([0.0, 180.0]))
    assert np.isfinite(spread) and spread > 300.0


def test_true_aoa_compass():
    ue = np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0], [0.0, -100.0], [50.0, 50.0]])
    aoa = true_aoa_deg(np.zeros(2), ue)
    np.testing.assert_allclose(wrap_deg(aoa), [0.0, 90.0, -180.0, -90.0, 45.0], atol=1e-12)
    # From a UAV that is not at the origin.
    assert float(true_aoa_deg(np.array([10.0, 10.0]), np.array([10.0, 30.0]))) == pytest.approx(
        90.0
    )


@pytest.mark.parametrize("sigma", [1.0, 5.0, 50.0])
def test_aoa_noise_std_is_honoured(sigma):
    truth = np.full(200_000, 179.0)  # right next to the wrap
    measured = measured_aoa_deg(rng(13), truth, sigma)
    assert measured.min() >= -180.0 and measured.max() < 180.0
    error = wrap_deg(measured - truth)
    assert error.std() == pytest.approx(sigma, rel=0.02)
    mean, circ_std = circular_mean_std_deg(measured)
    assert abs(float(wrap_deg(mean - 179.0))) < 0.2
    # For a wrapped normal, the circular std is exactly sigma.
    assert float(circ_std) == pytest.approx(sigma, rel=0.02)


def test_aoa_without_noise_is_exact_and_channel_honours_noise():
    truth = np.array([0.0, 90.0, 180.0, -45.0])
    np.testing.assert_array_equal(measured_aoa_deg(rng(), truth, 0.0), wrap_deg(truth))
    ue = np.tile(np.array([[100.0, 0.0], [0.0, 100.0], [-100.0, 0.0]]), (20_000, 1, 1))
    uav = np.zeros((20_000, 1, 2))
    exact = RadioChannel(QUIET, AREA, n_ues=3).reset(rng(), uav, ue).aoa_deg
    np.testing.assert_allclose(exact[0], [0.0, 90.0, -180.0], atol=1e-12)
    noisy = (
        RadioChannel(
            RadioConfig(shadowing=False, fast_fading=False, aoa_noise_deg=5.0), AREA, n_ues=3
        )
        .reset(rng(14), uav, ue)
        .aoa_deg
    )
    error = wrap_deg(noisy - exact)
    np.testing.assert_allclose(error.std(axis=0), 5.0, rtol=0.03)


def test_channel_step_before_reset_is_an_error():
    channel = RadioChannel(QUIET, AREA, n_ues=1)
    with pytest.raises(RuntimeError, match="reset"):
        channel.step(rng(), np.zeros((1, 1, 2)), np.zeros((1, 1, 2)))


def test_aoa_noise_randomised_per_episode():
    """aoa_noise_max_deg: each env draws its own AoA noise std in [aoa_noise_deg, max] at reset."""
    from uavlink.radio.aoa import true_aoa_deg, wrap_deg
    from uavlink.radio.channel import RadioChannel

    radio = RadioConfig(
        aoa_noise_deg=5.0, aoa_noise_max_deg=40.0, shadowing=False, fast_fading=False
    )
    channel = RadioChannel(radio, AreaConfig(), n_ues=200)
    rng = np.random.default_rng(3)
    uav = np.zeros((64, 1, 2))
    ue = rng.uniform(-150, 150, size=(64, 200, 2))
    errors = [wrap_deg(channel.reset(rng, uav, ue).aoa_deg - true_aoa_deg(uav, ue))]
    errors += [
        wrap_deg(channel.step(rng, uav, ue).aoa_deg - true_aoa_deg(uav, ue)) for _ in range(3)
    ]
    per_env_std = np.concatenate(errors, axis=1).std(axis=1)
    assert per_env_std.min() > 5.0 * 0.8 and per_env_std.max() < 40.0 * 1.15
    assert per_env_std.std() > 5.0  # the std really differs between episodes
    # Fixed within an episode: the std seen over the first and the last frames agree.
    first, last = (
        np.concatenate(errors[:2], axis=1).std(axis=1),
        np.concatenate(errors[2:], axis=1).std(axis=1),
    )
    assert np.corrcoef(first, last)[0, 1] > 0.9
    with pytest.raises(ValueError, match="aoa_noise_max_deg"):
        RadioConfig(aoa_noise_deg=10.0, aoa_noise_max_deg=5.0).validate()
