"""A fleet's radio (SPEC "A fleet"): strongest-power association, silent empty cells, per-cell
round robin, full or orthogonal reuse or one cell while the others listen, what each UAV hears; and the env's agent rows for D UAVs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uavlink.config import AreaConfig, EnvConfig, RadioConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.mobility.fleet import min_separation_m
from uavlink.radio.cells import Cells
from uavlink.radio.channel import RadioChannel
from uavlink.radio.noise import noise_power_dbm
from uavlink.radio.pathloss import mean_rx_power_dbm

QUIET = RadioConfig(shadowing=False, fast_fading=False)  # mean channel: deterministic
AREA = AreaConfig()


def _read(uav_xy, ue_xy, radio=QUIET, reuse="full", seed=0):
    uav, ue = np.asarray(uav_xy, float)[None], np.asarray(ue_xy, float)[None]
    return RadioChannel(radio, AREA, ue.shape[1], reuse).reset(np.random.default_rng(seed), uav, ue)


def _snr(horizontal_m: float, bandwidth_hz: float = QUIET.bandwidth_hz) -> float:
    """Linear SNR of a link at this horizontal distance over ``bandwidth_hz`` (no shadowing)."""
    rx = mean_rx_power_dbm(math.hypot(horizontal_m, AREA.uav_altitude_m), QUIET)
    return 10 ** ((rx - noise_power_dbm(bandwidth_hz, QUIET)) / 10)


def test_each_ue_attaches_to_the_strongest_uav_and_cells_rank_by_ue_index():
    rx = np.array([[[-60.0, -70.0], [-80.0, -75.0], [-65.0, -65.0], [-90.0, -50.0]]])
    cells = Cells.associate(rx)
    np.testing.assert_array_equal(cells.serving, [[0, 1, 0, 1]])  # a tie goes to UAV 0
    np.testing.assert_array_equal(cells.size, [[2, 2]])
    np.testing.assert_array_equal(cells.rank, [[0, 0, 1, 1]])
    np.testing.assert_array_equal(cells.rbs_per_ue(5), [[3, 3, 2, 2]])  # RB k to rank k mod 2


def test_a_uav_without_ues_is_silent():
    ue = [[0.0, 0.0], [20.0, 0.0]]
    alone = _read([[0.0, 0.0]], ue)
    near_idle = _read([[0.0, 0.0], [150.0, 0.0]], ue)  # both UEs attach to UAV 0
    np.testing.assert_array_equal(near_idle.serving, [[0, 0]])
    np.testing.assert_allclose(near_idle.sinr_db, alone.sinr_db, atol=1e-9)
    np.testing.assert_allclose(near_idle.rate_bps, alone.rate_bps, rtol=1e-12)


def test_two_active_cells_interfere_on_every_rb():
    # One UE under each UAV, 100 m apart: S / (I + N) per RB, each UE alone in its cell (B / 1).
    read = _read([[0.0, 0.0], [100.0, 0.0]], [[0.0, 0.0], [100.0, 0.0]])
    np.testing.assert_array_equal(read.serving, [[0, 1]])
    s, i = (
        _snr(0.0),
        _snr(100.0),
    )  # per-RB ratios equal the whole-band ones: power and noise split alike
    expected_db = 10 * math.log10(s / (i + 1.0))
    np.testing.assert_allclose(read.sinr_db[0], expected_db, atol=1e-9)
    np.testing.assert_allclose(
        read.rate_bps[0], QUIET.bandwidth_hz * math.log2(1 + s / (i + 1)), rtol=1e-12
    )


def test_per_cell_round_robin_shares_the_band_among_the_cells_ues():
    # Three UEs under UAV 0, one under a far UAV 1 (interference negligible): B/3 and B/1.
    ue = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [5000.0, 0.0]]
    read = _read([[0.0, 0.0], [5000.0, 0.0]], ue)
    np.testing.assert_array_equal(read.serving, [[0, 0, 0, 1]])
    shares = read.rate_bps[0] / np.log2(1 + 10 ** (read.sinr_db[0] / 10))
    np.testing.assert_allclose(
        shares, [QUIET.bandwidth_hz / 3] * 3 + [QUIET.bandwidth_hz], rtol=1e-12
    )


def test_orthogonal_reuse_has_no_interference_and_splits_the_band():
    read = _read([[0.0, 0.0], [100.0, 0.0]], [[0.0, 0.0], [100.0, 0.0]], reuse="orthogonal")
    # Each UAV puts its power on K / 2 RBs: per-RB SNR doubles, bandwidth halves.
    np.testing.assert_allclose(read.sinr_db[0], 10 * math.log10(2 * _snr(0.0)), atol=1e-9)
    np.testing.assert_allclose(
        read.rate_bps[0], QUIET.bandwidth_hz / 2 * math.log2(1 + 2 * _snr(0.0)), rtol=1e-12
    )


def test_a_listening_fleet_has_one_cell_the_uav_strongest_for_the_most_ues():
    rx = np.array([[[-60.0, -70.0], [-80.0, -75.0], [-65.0, -66.0]]])
    cells = Cells.listen(rx)  # UAV 0 is the strongest for two UEs of three: it serves all three
    np.testing.assert_array_equal(cells.serving, [[0, 0, 0]])
    np.testing.assert_array_equal(cells.size, [[3, 0]])
    np.testing.assert_array_equal(cells.rank, [[0, 1, 2]])
    tie = np.array([[[-60.0, -70.0], [-80.0, -50.0]]])  # one UE each: the louder in all wins
    np.testing.assert_array_equal(Cells.listen(tie).serving, [[1, 1]])


def test_listening_uavs_send_nothing_and_still_hear_every_ue():
    uav, ue = [[0.0, 0.0], [40.0, 0.0]], [[-10.0, 0.0], [0.0, 5.0], [45.0, 0.0]]
    full = _read(uav, ue)
    listen = _read(uav, ue, reuse="listen")
    alone = _read(uav[:1], ue)
    assert full.serving[0].tolist() == [0, 0, 1]  # with every UAV serving, UE 2 is UAV 1's
    np.testing.assert_array_equal(listen.serving, [[0, 0, 0]])
    # one cell, no interference: what UAV 0 alone gives, while UAV 1 hears what it heard before
    np.testing.assert_allclose(listen.sinr_db, alone.sinr_db, atol=1e-9)
    np.testing.assert_allclose(listen.rate_bps, alone.rate_bps, rtol=1e-12)
    np.testing.assert_allclose(listen.heard_sinr_db, full.heard_sinr_db, atol=1e-9)


def test_each_uav_hears_every_ue_and_measures_its_aoa():
    read = _read([[0.0, 0.0], [100.0, 0.0]], [[0.0, 50.0], [100.0, -50.0]])
    assert read.heard_sinr_db.shape == (1, 2, 2) and read.heard_aoa_deg.shape == (1, 2, 2)
    np.testing.assert_allclose(read.heard_sinr_db[0, 0, 0], 10 * math.log10(_snr(50.0)), atol=1e-9)
    np.testing.assert_allclose(
        read.heard_sinr_db[0, 0, 1], 10 * math.log10(_snr(math.hypot(100, 50))), atol=1e-9
    )
    np.testing.assert_allclose(
        read.heard_aoa_deg[0],
        [[90.0, math.degrees(math.atan2(-50, 100))], [math.degrees(math.atan2(50, -100)), -90.0]],
        atol=1e-9,
    )
    np.testing.assert_allclose(read.aoa_deg[0], [90.0, -90.0], atol=1e-9)  # at each UE's server


def test_full_reuse_fading_statistics_match_the_single_uav_path():
    """With the second UAV's cell empty, D = 2 (per-RB fading, drawn per scheduled RB) and D = 1
    (the RB mean in one draw) give the same SINR statistics."""
    radio = RadioConfig(shadowing=False)
    n = 5_000
    ue = np.zeros((n, 10, 2))
    one = (
        RadioChannel(radio, AREA, 10)
        .reset(np.random.default_rng(16), np.zeros((n, 1, 2)), ue)
        .sinr_db
    )
    far = np.concatenate([np.zeros((n, 1, 2)), np.full((n, 1, 2), 1e6)], axis=1)
    two = RadioChannel(radio, AREA, 10).reset(np.random.default_rng(17), far, ue).sinr_db
    assert two.mean() == pytest.approx(one.mean(), abs=0.02)
    assert two.std() == pytest.approx(one.std(), rel=0.03)


@pytest.mark.parametrize("n_uavs", [2, 3])
def test_fleet_env_rows_rewards_and_separation(n_uavs):
    cfg = EnvConfig(scenario="mixed", n_uavs=n_uavs).replace(**{"radio.shadowing_model": "spatial"})
    env = BatchedUavEnv(cfg, n_envs=8, seed=4)
    obs = env.reset()
    assert obs.shape == (8 * n_uavs, env.layout.size) and env.layout.version == 2
    rng = np.random.default_rng(0)
    for _ in range(cfg.episode_frames):
        result = env.step(rng.uniform(-1, 1, (8 * n_uavs, 2)))
        rewards = result.reward.reshape(8, n_uavs)
        np.testing.assert_array_equal(
            rewards, rewards[:, :1].repeat(n_uavs, axis=1)
        )  # one team reward
        assert (min_separation_m(env.uav_xy_m.reshape(8, n_uavs, 2)) >= cfg.uav_separation_m).all()
    assert result.truncated.all() and result.mean_rate_mbps.shape == (8,)
    frame = env.layout.newest_frame(result.observation)
    np.testing.assert_allclose(frame["uav_xy_m"], env.uav_xy_m, atol=1e-4)
    served = frame["served_by"].reshape(8, n_uavs, -1)
    np.testing.assert_array_equal(
        (served[:, 0] + 0) % n_uavs, env.readings.serving
    )  # UAV 0 counts from 0
    np.testing.assert_array_equal((served[:, 1] + 1) % n_uavs, env.readings.serving)


def test_fleet_env_is_reproducible_by_seed():
    cfg = EnvConfig(scenario="straight_180", n_uavs=2)
    runs = []
    for _ in range(2):
        env = BatchedUavEnv(cfg, n_envs=4, seed=9)
        env.reset()
        runs.append(np.concatenate([env.step(np.full((8, 2), 0.3)).observation for _ in range(5)]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_listening_fleet_meets_the_same_ues_as_a_full_reuse_fleet():
    """How a fleet uses its band is a policy's choice (``PER_POLICY``), compared on the same
    episodes: the UEs' paths do not depend on it, and the same UAV positions give the listening
    fleet its one cell's rates."""
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import PER_POLICY
    from uavlink.policies.registry import make_baseline

    assert "fleet_reuse" in PER_POLICY
    results = {}
    for reuse in ("full", "listen"):
        cfg = EnvConfig(scenario="no_move", n_uavs=2, fleet_reuse=reuse).validate()
        results[reuse] = evaluate_policy(
            make_baseline("static", cfg), cfg, 2, seed=5, record_trajectory=True
        )
    full, listen = results["full"].trajectory, results["listen"].trajectory
    np.testing.assert_array_equal(full.ue_xy_m, listen.ue_xy_m)
    np.testing.assert_array_equal(full.uav_xy_m, listen.uav_xy_m)
    assert (listen.serving == listen.serving[:, :1]).all()  # one cell serves every UE
    assert not (full.serving == full.serving[:, :1]).all()
