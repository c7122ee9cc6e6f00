"""The environment: action mapping, geofence, reward, the Gymnasium and SB3 faces, determinism,
and rejection of bad input (the observation: test_observation.py)."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest

import uavlink
from uavlink.config import MIXED, SCENARIO_NAMES, EnvConfig
from uavlink.env import ActionMapping, BatchedUavEnv, RewardBounds
from uavlink.env.gym_env import UavBsEnv
from uavlink.errors import UserError

ENV_ID = "uavlink/UavBs-v0"
QUIET = {"shadowing": False, "fast_fading": False}


def polar() -> ActionMapping:
    return ActionMapping(r_max_m=12.0, kind="polar-v1")


def cartesian() -> ActionMapping:
    return ActionMapping(r_max_m=12.0, kind="cartesian-v1")


def fresh(env: gym.Env) -> UavBsEnv:
    return env.unwrapped  # type: ignore[return-value]


# --- action mapping ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("action", "angle_deg", "distance_m"),
    [
        ((-1.0, -1.0), -180.0, 0.0),
        ((1.0, 1.0), -180.0, 12.0),  # +180 wraps to -180
        ((0.0, 1.0), 0.0, 12.0),  # east, full step
        ((0.5, 0.0), 90.0, 6.0),  # north, half step
        ((-0.5, -0.5), -90.0, 3.0),  # south
        ((3.0, -7.0), -180.0, 0.0),  # outside the box: clipped first
    ],
)
def test_polar_mapping_corners(action, angle_deg, distance_m):
    mapping = polar()
    clipped = mapping.validate(np.array([action]), 1)
    angle, distance = mapping.to_polar(clipped)
    assert float(angle[0]) == pytest.approx(angle_deg, abs=1e-12)
    assert float(distance[0]) == pytest.approx(distance_m, abs=1e-12)
    assert -180.0 <= angle[0] < 180.0


@pytest.mark.parametrize(
    ("action", "angle_deg", "distance_m"),
    [
        ((0.0, 0.0), 0.0, 0.0),
        ((1.0, 0.0), 0.0, 12.0),
        ((0.0, 0.5), 90.0, 6.0),
        ((-1.0, 0.0), -180.0, 12.0),
        ((0.0, -0.25), -90.0, 3.0),
        ((1.0, 1.0), 45.0, 12.0),  # |a| > 1 saturates at r_max
    ],
)
def test_cartesian_mapping(action, angle_deg, distance_m):
    mapping = cartesian()
    angle, distance = mapping.to_polar(mapping.validate(np.array([action]), 1))
    assert float(angle[0]) == pytest.approx(angle_deg, abs=1e-12)
    assert float(distance[0]) == pytest.approx(distance_m, abs=1e-12)


@pytest.mark.parametrize("kind", ["polar-v1", "cartesian-v1"])
def test_from_polar_round_trips_and_displacement(kind):
    mapping = ActionMapping(12.0, kind)
    angles = np.array([-180.0, -135.0, -90.0, 0.0, 30.0, 90.0, 179.0])
    dists = np.array([12.0, 1.0, 6.0, 12.0, 3.0, 6.0, 9.0])
    action = mapping.from_polar(angles, dists)
    assert np.all(np.abs(action) <= 1.0)
    angle, distance = mapping.to_polar(action)
    np.testing.assert_allclose(distance, dists, atol=1e-12)
    np.testing.assert_allclose(((angle - angles) + 180.0) % 360.0 - 180.0, 0.0, atol=1e-9)
    move = mapping.to_displacement_m(action)
    np.testing.assert_allclose(move[3], (12.0, 0.0), atol=1e-12)  # 0 deg is east
    np.testing.assert_allclose(move[5], (0.0, 6.0), atol=1e-12)  # 90 deg is north
    np.testing.assert_allclose(np.hypot(*move.T), dists, atol=1e-12)
    assert ActionMapping.from_dict(mapping.to_dict()) == mapping


def test_unknown_action_mapping_is_rejected():
    with pytest.raises(ValueError, match="unknown action mapping 'spherical'"):
        ActionMapping(12.0, "spherical")


@pytest.mark.parametrize("kind", ["polar-v1", "cartesian-v1"])
def test_env_moves_the_uav_by_the_mapped_action(kind):
    env = BatchedUavEnv(EnvConfig(scenario="no_move", action_mapping=kind), n_envs=2, seed=0)
    env.reset()
    env.step(env.actions.from_polar(np.array([90.0, 180.0]), np.array([6.0, 12.0])))
    np.testing.assert_allclose(env.uav_xy_m, [[0.0, 6.0], [-12.0, 0.0]], atol=1e-9)
    env.step(env.actions.from_polar(np.array([0.0, 0.0]), np.array([0.0, 0.0])))  # hover
    np.testing.assert_allclose(env.uav_xy_m, [[0.0, 6.0], [-12.0, 0.0]], atol=1e-9)


def test_uav_is_clipped_at_the_geofence():
    env = BatchedUavEnv(EnvConfig(scenario="no_move"), n_envs=2, seed=0)
    env.reset()
    north_east = env.actions.from_polar(np.array([0.0, 90.0]), np.array([12.0, 12.0]))
    for _ in range(20):  # 240 m of commands, 200 m of room
        env.step(north_east)
    np.testing.assert_allclose(env.uav_xy_m, [[200.0, 0.0], [0.0, 200.0]], atol=1e-9)
    env.step_to(np.array([[1e4, -1e4], [-250.0, 3.0]]))
    np.testing.assert_allclose(env.uav_xy_m, [[200.0, -200.0], [-200.0, 3.0]])


# --- reward ------------------------------------------------------------------------------------


def test_reward_bounds_values():
    bounds = RewardBounds.for_config(EnvConfig())
    hover_rate = 1e6 * math.log2(1 + 10 ** (2.4338))  # 8.09 Mbps per UE
    assert bounds.max_fair_rate == pytest.approx(10 * math.log10(hover_rate), abs=1e-3)
    assert bounds.min_fair_rate == pytest.approx(10 * math.log10(0.395e6), abs=0.05)
    assert float(bounds.normalise(bounds.max_fair_rate)) == pytest.approx(1.0)
    assert float(bounds.normalise(bounds.min_fair_rate)) == pytest.approx(0.0)


def test_reward_is_one_hovering_over_the_cluster_and_zero_at_the_far_corner():
    cfg = EnvConfig(scenario="no_move").replace(**QUIET)
    env = BatchedUavEnv(cfg, n_envs=4, seed=0)
    env.reset()
    hover = env.actions.from_polar(np.zeros(4), np.zeros(4))
    for _ in range(3):
        result = env.step(hover)
        assert np.all(result.reward > 0.995) and np.all(result.reward <= 1.0 + 1e-12)
        np.testing.assert_allclose(result.mean_rate_mbps, 8.08, atol=0.02)
    # All UEs in the south-west corner, the UAV in the north-east one: 566 m apart.
    env.mobility.position_m[:] = -200.0
    env.mobility.velocity_mps[:] = 0.0
    far = env.step_to(np.full((4, 2), 200.0))
    np.testing.assert_allclose(far.reward, 0.0, atol=1e-9)
    np.testing.assert_allclose(far.mean_rate_mbps, 0.395, atol=0.005)
    np.testing.assert_allclose(far.reward, env.reward_bounds.normalise(far.fair_rate))


# --- Gymnasium face ----------------------------------------------------------------------------


def test_env_is_registered_on_import():
    assert uavlink.ENV_ID == ENV_ID
    assert ENV_ID in gym.registry


def _check_all(env: gym.Env) -> list[str]:
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(fresh(env), skip_render_check=True)
        sb3_check_env(env, warn=True, skip_render_check=True)
    return [str(w.message) for w in caught]


@pytest.mark.parametrize(
    ("scenario", "aoa_noise_deg"),
    [(s, 0.0) for s in SCENARIO_NAMES] + [("straight", 5.0), (MIXED, 5.0)],
)
def test_gymnasium_and_sb3_env_checkers_pass(scenario, aoa_noise_deg):
    env = gym.make(ENV_ID, scenario=scenario, aoa_noise_deg=aoa_noise_deg)
    messages = _check_all(env)
    assert messages == []
    assert fresh(env).config.scenario == scenario
    assert fresh(env).config.radio.aoa_noise_deg == aoa_noise_deg


def _episode(env: gym.Env, seed: int, frames: int = 128):
    obs, info = env.reset(seed=seed)
    actions = np.random.default_rng(123).uniform(-1, 1, (frames, 2)).astype(np.float32)
    observations, rewards, infos = [obs], [], []
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        rewards.append(reward)
        infos.append((terminated, truncated, info))
    return np.array(observations), np.array(rewards), infos


def test_same_seed_bit_identical_episode_different_seed_differs():
    env_a = gym.make(ENV_ID, scenario="hotspot", aoa_noise_deg=5.0)
    env_b = gym.make(ENV_ID, scenario="hotspot", aoa_noise_deg=5.0)
    obs_a, rew_a, _ = _episode(env_a, seed=7, frames=40)
    obs_b, rew_b, _ = _episode(env_b, seed=7, frames=40)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(rew_a, rew_b)
    obs_again, rew_again, _ = _episode(env_a, seed=7, frames=40)  # reseeding the same env
    np.testing.assert_array_equal(obs_again, obs_a)
    np.testing.assert_array_equal(rew_again, rew_a)
    obs_c, rew_c, _ = _episode(env_b, seed=8, frames=40)
    assert not np.array_equal(obs_c, obs_a)
    assert not np.array_equal(rew_c, rew_a)


def test_unseeded_envs_differ():
    first = [fresh(gym.make(ENV_ID, scenario="hotspot")).reset()[0] for _ in range(2)]
    assert not np.array_equal(first[0], first[1])


def test_episode_truncates_at_128_with_rate_info():
    env = gym.make(ENV_ID, scenario="circular")
    obs, rewards, infos = _episode(env, seed=0, frames=128)
    assert obs.shape == (129, fresh(env).layout.size)
    assert all(not terminated for terminated, _, _ in infos)
    assert [truncated for _, truncated, _ in infos] == [False] * 127 + [True]
    for _, _, info in infos:
        assert set(info) >= {"mean_rate_mbps", "fair_rate"}
        assert 0.0 < info["mean_rate_mbps"] < 12.0 and np.isfinite(info["fair_rate"])
    assert np.all(np.isfinite(rewards)) and rewards.dtype == np.float64
    # Reward and info agree: reward = normalised fair rate.
    bounds = fresh(env).core.reward_bounds
    np.testing.assert_allclose(rewards, [bounds.normalise(i["fair_rate"]) for _, _, i in infos])


def test_gym_env_accepts_config_overrides():
    env = fresh(gym.make(ENV_ID, scenario="no_move", **QUIET, r_max_m=6.0))
    assert env.config.radio.shadowing is False and env.config.radio.fast_fading is False
    assert env.config.r_max_m == 6.0
    assert env.action_space.shape == (2,) and env.observation_space.shape == (env.layout.size,)


def test_gym_env_applies_named_arguments_over_a_config_and_refuses_what_it_cannot_be():
    cfg = EnvConfig(scenario="hotspot")
    env = fresh(gym.make(ENV_ID, config=cfg, scenario="no_move", n_ues=5))
    assert env.config.scenario == "no_move" and env.config.n_ues == 5
    assert fresh(gym.make(ENV_ID, config=cfg)).config == cfg.validate()
    assert fresh(gym.make(ENV_ID, render_mode=None)).render() is None
    with pytest.raises(UserError, match="render_mode 'rgb_array' is not supported"):
        UavBsEnv(
            render_mode="rgb_array"
        )  # (gym.make would warn first that it is not in render_modes)
    with pytest.raises(UserError, match="n_uavs=2.*parallel_env"):
        gym.make(ENV_ID, n_uavs=2)


def test_gym_env_steps_only_inside_an_episode():
    env = UavBsEnv("circular", episode_frames=3)
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(2))
    env.reset(seed=0)
    assert [env.step(np.zeros(2))[3] for _ in range(3)] == [False, False, True]
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(2))
    env.reset(seed=1)
    env.step(np.zeros(2))


# --- SB3 VecEnv face ---------------------------------------------------------------------------

# SB3's VecEnv.__init__ asks every env for ``render_mode`` and warns when it is missing.
vec_warning = pytest.mark.filterwarnings("ignore:The `render_mode` attribute is not defined")


@vec_warning
def test_vec_env_auto_reset_contract():
    from stable_baselines3.common.vec_env import VecEnv

    from uavlink.env.vec_env import UavVecEnv

    cfg = EnvConfig(scenario="straight")
    venv = UavVecEnv(cfg, n_envs=3, seed=0)
    twin = BatchedUavEnv(cfg, n_envs=3, seed=0)  # the same physics, stepped by hand
    assert isinstance(venv, VecEnv)
    assert venv.num_envs == 3
    obs = venv.reset()
    np.testing.assert_array_equal(obs, twin.reset())
    assert obs.shape == (3, venv.observation_space.shape[0]) and obs.dtype == np.float32
    assert venv.observation_space.contains(obs[0])
    first_obs = obs.copy()
    rng = np.random.default_rng(0)
    returns = np.zeros(3)
    rates = np.zeros(3)
    for frame in range(1, 129):
        actions = rng.uniform(-1, 1, (3, 2)).astype(np.float32)
        obs, rewards, dones, infos = venv.step(actions)
        expected = twin.step(actions)
        returns += expected.reward
        rates += expected.mean_rate_mbps
        np.testing.assert_allclose(rewards, expected.reward, rtol=1e-6)
        assert rewards.shape == (3,) and dones.shape == (3,) and len(infos) == 3
        if frame < 128:
            assert not dones.any()
            assert all(info == {} for info in infos)
            np.testing.assert_array_equal(obs, expected.observation)
        else:
            assert dones.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True
        # The terminal observation is the old episode's last; the returned one the new episode's first.
        np.testing.assert_array_equal(info["terminal_observation"], expected.observation[i])
        assert not np.array_equal(info["terminal_observation"], obs[i])
        episode = info["episode"]
        assert episode["l"] == 128
        assert episode["r"] == pytest.approx(returns[i], rel=1e-9)
        assert episode["mean_rate_mbps"] == pytest.approx(rates[i] / 128, rel=1e-9)
    new_frames = obs.reshape(3, 4, -1)
    np.testing.assert_array_equal(new_frames, new_frames[:, :1].repeat(4, axis=1))
    np.testing.assert_allclose(
        venv.core.layout.newest_frame(obs)["uav_xy_m"], 0.0
    )  # back at centre
    assert venv.core.frame == 0
    assert not np.array_equal(obs, first_obs)  # the next episode is a new draw, not a replay


@vec_warning
def test_vec_env_sb3_api_and_wrappers():
    from stable_baselines3.common.vec_env import VecCheckNan, VecNormalize

    from uavlink.env.vec_env import UavVecEnv

    venv = UavVecEnv(EnvConfig(scenario="mixed"), n_envs=4, seed=3)
    assert venv.seed(11) == [11] * 4
    a = venv.reset()
    venv.seed(11)
    np.testing.assert_array_equal(venv.reset(), a)  # seed() applies to the next reset
    assert venv.get_attr("n_envs") == [4] * 4
    assert venv.get_attr("n_envs", indices=[0, 2]) == [4, 4]
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 4
    assert len(venv.env_method("ground_truth")) == 4
    # Standard SB3 wrappers drive it across an episode boundary.
    wrapped = VecNormalize(VecCheckNan(venv, raise_exception=True), gamma=0.99)
    obs = wrapped.reset()
    for _ in range(130):
        obs, rewards, dones, infos = wrapped.step(np.zeros((4, 2), np.float32))
    assert obs.shape == (4, venv.observation_space.shape[0]) and np.all(np.isfinite(obs))
    wrapped.close()


# --- bad input ---------------------------------------------------------------------------------


def test_unknown_scenario_is_rejected():
    with pytest.raises(
        ValueError, match=r"unknown scenario 'zigzag'; choose from no_move, straight"
    ):
        EnvConfig(scenario="zigzag").validate()
    with pytest.raises(ValueError, match="unknown scenario 'zigzag'"):
        gym.make(ENV_ID, scenario="zigzag")
    with pytest.raises(ValueError, match="unknown scenario"):
        BatchedUavEnv(EnvConfig(scenario="zigzag"))


def test_negative_aoa_noise_is_rejected():
    with pytest.raises(ValueError, match=r"radio\.aoa_noise_deg must be >= 0, got -1"):
        gym.make(ENV_ID, scenario="straight", aoa_noise_deg=-1.0)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"bandwidth_hz": -10e6}, r"radio\.bandwidth_hz must be positive"),
        ({"n_resource_blocks": 0}, r"radio\.n_resource_blocks must be positive, got 0"),
        ({"cluster_size_m": 500.0}, r"cluster_size_m must be smaller than the area"),
        ({"n_ues": 0}, r"env\.n_ues must be positive, got 0"),
        ({"tx_power_dbm": float("nan")}, r"radio\.tx_power_dbm must be a finite number"),
        ({"uav_altitude_m": 0.0}, r"area\.uav_altitude_m must be positive"),
        ({"episode_frames": 0}, r"env\.episode_frames must be positive"),
        ({"scenario": "straight_90", "n_ues": 1}, r"needs at least 2 UEs"),
    ],
)
def test_non_physical_config_is_rejected(changes, message):
    cfg = EnvConfig().replace(**changes)
    with pytest.raises(ValueError, match=message):
        cfg.validate()
    with pytest.raises(ValueError, match=message):
        BatchedUavEnv(cfg)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("n_resource_blocks", 2.5, r"radio\.n_resource_blocks must be an integer, got 2\.5"),
        ("n_ues", "ten", r"n_ues must be an integer, got 'ten'"),
        ("radio.fast_fading", "maybe", r"radio\.fast_fading must be true or false, got 'maybe'"),
    ],
)
def test_a_value_of_the_wrong_type_is_refused_naming_its_key(key, value, message):
    with pytest.raises(ValueError, match=message):
        EnvConfig().replace(**{key: value})


def test_unknown_config_key_is_rejected():
    with pytest.raises(ValueError, match="unknown config key 'warp_drive'"):
        EnvConfig().replace(warp_drive=True)
    with pytest.raises(ValueError, match=r"unknown config key 'radio\.warp'"):
        EnvConfig().replace(**{"radio.warp": 1})


@pytest.mark.parametrize("action", [np.zeros(3), np.zeros((2, 2)), np.zeros(1), np.float32(0.0)])
def test_action_of_wrong_shape_is_rejected(action):
    env = gym.make(ENV_ID, scenario="no_move")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"the action has shape \(2,\) \(the action space's\)"):
        fresh(env).step(action)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_is_rejected(bad):
    env = fresh(gym.make(ENV_ID, scenario="no_move"))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN or infinity"):
        env.step(np.array([0.0, bad], np.float32))
    batched = BatchedUavEnv(EnvConfig(), n_envs=2, seed=0)
    batched.reset()
    with pytest.raises(ValueError, match="NaN or infinity"):
        batched.step(np.array([[0.0, 0.0], [bad, 0.0]]))
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        batched.step(np.zeros((3, 2)))


def test_step_before_reset_and_bad_batch_size():
    with pytest.raises(RuntimeError, match="reset"):
        BatchedUavEnv(EnvConfig(), n_envs=1).step(np.zeros((1, 2)))
    for n_envs in (0, -3, 2.5):
        with pytest.raises(ValueError, match="n_envs must be a positive integer"):
            BatchedUavEnv(EnvConfig(), n_envs=n_envs)
