"""Baselines for a fleet (SPEC "A fleet"): D = 1 is today's evaluation exactly; the per-cell aoa
rule, the greedy oracle and k-means for D > 1."""

from __future__ import annotations

import numpy as np
import pytest
from support.cli import ROOT, cli_json

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.evaluation import evaluate_policy
from uavlink.policies.fleet_baselines import FleetAoaPolicy, KMeansPolicy, mean_fleet_fair_rate
from uavlink.policies.registry import make_baseline


@pytest.mark.slow
@pytest.mark.parametrize("policy", ["static", "aoa", str(ROOT / "policies" / "straight.zip")])
def test_n_uavs_1_gives_exactly_todays_episodes(policy):
    args = [
        "evaluate",
        "--scenario",
        "straight",
        "--policy",
        policy,
        "--episodes",
        "8",
        "--seed",
        "3",
        "--json",
    ]
    assert cli_json(*args, "--set", "n_uavs=1") == cli_json(
        *args
    )  # in this process: no torch import per run


def test_a_fleet_policy_file_refuses_another_fleet_size():
    from uavlink.policies.contract import BUILT_FOR

    assert "n_uavs" in BUILT_FOR  # a policy's observation layout depends on D


def test_fleet_aoa_rule_follows_its_cell_and_an_empty_cell_holds():
    cfg = EnvConfig(scenario="no_move", n_uavs=2).replace(
        **{"radio.shadowing": False, "radio.fast_fading": False}
    )
    env = BatchedUavEnv(cfg, n_envs=1, seed=0)
    env.reset()
    env.mobility.position_m[:] = [
        [120.0, 40.0]
    ] * cfg.n_ues  # every UE near UAV 0 (start at (100, 0))
    obs = env.step_to(env.uav_xy_m).observation  # re-read the channel with the UEs moved
    action = FleetAoaPolicy(cfg).act(obs)
    move = env.actions.to_displacement_m(action)
    heading = np.degrees(np.arctan2(move[0, 1], move[0, 0]))
    assert np.hypot(*move[0]) > 1.0 and heading == pytest.approx(
        np.degrees(np.arctan2(40.0, 20.0)), abs=1.0
    )
    np.testing.assert_allclose(move[1], 0.0, atol=1e-9)  # UAV 1 serves nobody: it holds


def two_groups_env() -> BatchedUavEnv:
    """A fleet of two over two groups of five UEs, at (-150, 10) and (150, -10); no speed limit."""
    env = BatchedUavEnv(EnvConfig(scenario="straight_180", n_uavs=2, r_max_m=500.0), 1, seed=0)
    env.reset()
    env.mobility.position_m[0, :5] = [-150.0, 10.0]
    env.mobility.position_m[0, 5:] = [150.0, -10.0]
    return env


def test_kmeans_splits_two_groups_and_sends_each_uav_to_the_nearer_one():
    env = two_groups_env()
    move = env.actions.to_displacement_m(KMeansPolicy(env.cfg).act(None, env.ground_truth()))
    np.testing.assert_allclose(env.uav_xy_m + move, [[150.0, -10.0], [-150.0, 10.0]], atol=1e-6)


def test_the_spread_teacher_aims_ahead_of_each_group_and_away_from_the_others():
    from uavlink.learn.teachers import SpreadTeacher

    env = two_groups_env()
    cfg, truth = env.cfg, env.ground_truth()
    velocity = truth.ue_velocity_mps.reshape(2, 5, 2).mean(axis=1)  # the groups' mean velocity
    teacher = SpreadTeacher(cfg, spread_m=20.0, lead_frames=2.0)
    move = env.actions.to_displacement_m(teacher.act(None, truth))
    ahead = np.array([[150.0, -10.0], [-150.0, 10.0]]) + 2.0 * cfg.frame_s * velocity[::-1]
    away = ahead - ahead[::-1]
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    np.testing.assert_allclose(env.uav_xy_m + move, ahead + 20.0 * away, atol=1e-6)
    kmeans = env.actions.to_displacement_m(KMeansPolicy(cfg).act(None, truth))
    still = SpreadTeacher(cfg, spread_m=0.0, lead_frames=0.0)  # no knobs: kmeans itself
    np.testing.assert_allclose(env.actions.to_displacement_m(still.act(None, truth)), kmeans)


def test_mean_fleet_fair_rate_reduces_to_one_uav_and_rewards_splitting():
    from uavlink.radio.noise import noise_power_dbm
    from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
    from uavlink.radio.rates import fair_rate, rate_bps

    cfg = EnvConfig(n_uavs=2)
    ue = np.array([[[-100.0, 0.0]] * 5 + [[100.0, 0.0]] * 5])
    one = np.zeros((1, 1, 2))
    snr = 10 ** (
        (
            mean_rx_power_dbm(distance_3d_m(one, ue, 95.0), cfg.radio)[..., 0]
            - noise_power_dbm(cfg.radio.bandwidth_hz, cfg.radio)
        )
        / 10
    )
    expected = fair_rate(rate_bps(snr, cfg.radio.bandwidth_hz, 10))
    np.testing.assert_allclose(mean_fleet_fair_rate(cfg, one, ue), expected, rtol=1e-12)
    split = mean_fleet_fair_rate(cfg, np.array([[[-100.0, 0.0], [100.0, 0.0]]]), ue)
    assert split[0] > expected[0] + 1  # one UAV over each group beats one UAV in the middle


@pytest.mark.slow
def test_fleet_baselines_on_straight_180_follow_the_two_groups():
    cfg = EnvConfig(scenario="straight_180", n_uavs=2)
    rates = {
        name: evaluate_policy(make_baseline(name, cfg), cfg, episodes=16, seed=0).mean_rate_mbps
        for name in ("static", "aoa", "oracle", "kmeans")
    }
    assert rates["oracle"] > 1.2 * rates["static"] and rates["kmeans"] > 1.2 * rates["static"]
    assert rates["aoa"] > rates["static"]
