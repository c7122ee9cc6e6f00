"""The fleet's PettingZoo face: uavlink.fleet.parallel_env."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import parallel_api_test, parallel_seed_test  # noqa: E402

from uavlink.config import SCENARIOS, EnvConfig  # noqa: E402
from uavlink.env.core import BatchedUavEnv  # noqa: E402
from uavlink.env.gym_env import UavBsEnv  # noqa: E402
from uavlink.errors import UserError  # noqa: E402
from uavlink.fleet import parallel_env  # noqa: E402
from uavlink.fleet.parallel import FleetParallelEnv  # noqa: E402


def _api_test(env: FleetParallelEnv) -> None:
    """PettingZoo's own check, with its warnings (a live agent without a reward...) as failures."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parallel_api_test(env, num_cycles=env.config.episode_frames + 5)


def test_parallel_api_test_circular_two_uavs() -> None:
    env = parallel_env("circular", 2)
    assert env.possible_agents == ["uav_0", "uav_1"]
    assert (
        env.metadata == {"name": "uavlink_fleet_v0", "render_modes": []} and env.render_mode is None
    )
    _api_test(env)
    parallel_seed_test(lambda: parallel_env("hotspot", 3, episode_frames=8), num_cycles=8)


@pytest.mark.slow
@pytest.mark.parametrize("n_uavs", [2, 3])
@pytest.mark.parametrize("scenario", SCENARIOS)
def test_parallel_api_test_every_scenario(scenario: str, n_uavs: int) -> None:
    _api_test(parallel_env(scenario, n_uavs))


def _random_actions(env: FleetParallelEnv, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {agent: rng.uniform(-1, 1, 2).astype(np.float32) for agent in env.agents}


def _rollout(env: FleetParallelEnv, seed: int, frames: int) -> list[dict[str, np.ndarray]]:
    obs, _ = env.reset(seed=seed)
    rng, out = np.random.default_rng(0), [obs]
    for _ in range(frames):
        out.append(env.step(_random_actions(env, rng))[0])
    return out


def test_spaces_and_observations() -> None:
    env = parallel_env("straight_180", 3, episode_frames=6)
    assert env.layout.version == 2
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_spaces[agent]
        assert env.observation_space(agent).shape == (env.layout.size,)
        assert env.observation_space(agent).dtype == np.float32
        assert env.action_space(agent) == env.action_spaces[agent]
        assert env.action_space(agent).shape == (2,) and env.action_space(agent).low.min() == -1
    for obs in _rollout(env, seed=3, frames=6):
        assert all(env.observation_space(a).contains(o) for a, o in obs.items())
        assert env.state_space.contains(env.state())
    np.testing.assert_array_equal(
        env.state(), np.concatenate([obs[a] for a in env.possible_agents])
    )


def test_seeded_reset_is_reproducible_and_unseeded_draws() -> None:
    env = parallel_env("hotspot", 2, episode_frames=5)
    first, again = _rollout(env, seed=11, frames=5), _rollout(env, seed=11, frames=5)
    for a, b in zip(first, again, strict=True):
        for agent in env.possible_agents:
            np.testing.assert_array_equal(a[agent], b[agent])
    other = parallel_env("hotspot", 2, episode_frames=5)
    unseeded = [e.reset()[0]["uav_0"] for e in (env, other)]
    assert not np.array_equal(unseeded[0], unseeded[1])  # UE starts drawn from different seeds


def test_agents_see_the_core_rows_and_share_the_team_reward() -> None:
    env = parallel_env("straight_90", 3, episode_frames=6)
    core = BatchedUavEnv(env.config, n_envs=1)
    obs, infos = env.reset(seed=5)
    core_obs = core.reset(5)
    assert infos == {agent: {} for agent in env.possible_agents}
    rng = np.random.default_rng(1)
    for _ in range(6):
        for d, agent in enumerate(env.possible_agents):
            np.testing.assert_array_equal(obs[agent], core_obs[d])
        actions = _random_actions(env, rng)
        obs, rewards, terms, truncs, infos = env.step(actions)
        result = core.step(np.stack([actions[a] for a in env.possible_agents]))
        core_obs = result.observation
        assert len(set(rewards.values())) == 1 and rewards["uav_0"] == pytest.approx(
            result.reward[0]
        )
        assert not any(terms.values())
        for info in infos.values():
            assert info == {
                "mean_rate_mbps": pytest.approx(result.mean_rate_mbps[0]),
                "fair_rate": pytest.approx(result.fair_rate[0]),
            }


def test_episode_truncates_at_the_last_frame_and_empties_agents() -> None:
    env = parallel_env("circular", 2, episode_frames=4)
    with pytest.raises(RuntimeError, match="reset"):
        env.step({"uav_0": [0, 0], "uav_1": [0, 0]})
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for frame in range(1, 5):
        _, _, terms, truncs, _ = env.step(_random_actions(env, rng))
        assert set(truncs) == set(terms) == {"uav_0", "uav_1"}
        assert all(truncs.values()) == (frame == 4) and not any(terms.values())
        assert env.agents == ([] if frame == 4 else ["uav_0", "uav_1"])
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
    env.reset()
    assert env.agents == ["uav_0", "uav_1"]


def test_every_live_agent_must_act() -> None:
    env = parallel_env("no_move", 2, episode_frames=4)
    env.reset(seed=0)
    with pytest.raises(UserError, match="missing \\['uav_1'\\]"):
        env.step({"uav_0": [0.0, 0.0]})
    with pytest.raises(UserError, match="unknown \\['uav_7'\\]"):
        env.step({"uav_0": [0.0, 0.0], "uav_1": [0.0, 0.0], "uav_7": [0.0, 0.0]})
    with pytest.raises(ValueError, match="NaN"):
        env.step({"uav_0": [np.nan, 0.0], "uav_1": [0.0, 0.0]})


def test_common_mistakes_get_a_message_that_names_them() -> None:
    """Before, numpy's and dict's own errors: 'all input arrays must have the same shape', 'the
    truth value of an array ... is ambiguous', a bare KeyError, an AttributeError for config=."""
    env = parallel_env("no_move", 2, episode_frames=4)
    env.reset(seed=0)
    with pytest.raises(UserError, match=r"shape \(2,\): got uav_0 \(3,\)"):
        env.step({"uav_0": np.zeros(3), "uav_1": np.zeros(2)})
    with pytest.raises(UserError, match="actions must be a dict of agent -> action"):
        env.step([np.zeros(2), np.zeros(2)])
    with pytest.raises(UserError, match="no agent 'uav_7'"):
        env.observation_space("uav_7")
    with pytest.raises(UserError, match="config must be an EnvConfig"):
        parallel_env(config="no_move")


def test_separation_holds_over_random_actions_towards_each_other() -> None:
    env = parallel_env("circular", 3)
    env.reset(seed=2)
    rng, closest = np.random.default_rng(3), np.inf
    while env.agents:  # each UAV heads for the centre, with noise: the filter must keep 20 m
        xy = env.core.uav_xy_m
        towards = -xy / np.maximum(np.linalg.norm(xy, axis=1, keepdims=True), 1e-9)
        env.step(
            {
                a: np.clip(towards[d] + rng.normal(0, 0.5, 2), -1, 1)
                for d, a in enumerate(env.agents)
            }
        )
        gaps = np.linalg.norm(env.core.uav_xy_m[:, None] - env.core.uav_xy_m[None], axis=-1)
        closest = min(closest, gaps[np.triu_indices(3, 1)].min())
    assert env.config.uav_separation_m - 1e-9 <= closest < 40.0  # they did come close


def test_one_uav_matches_the_gymnasium_env() -> None:
    env = parallel_env("straight", 1, episode_frames=6)
    assert env.possible_agents == ["uav_0"] and env.layout.version == 1
    gym_env = UavBsEnv("straight", episode_frames=6)
    obs, _ = env.reset(seed=9)
    gym_obs, _ = gym_env.reset(seed=9)
    rng = np.random.default_rng(4)
    for _ in range(6):
        np.testing.assert_array_equal(obs["uav_0"], gym_obs)
        action = rng.uniform(-1, 1, 2)
        obs, rewards, _, truncs, infos = env.step({"uav_0": action})
        gym_obs, reward, _, trunc, info = gym_env.step(action)
        assert rewards["uav_0"] == reward and truncs["uav_0"] == trunc and infos["uav_0"] == info
    assert env.agents == [] and trunc


def test_config_and_overrides() -> None:
    cfg = EnvConfig().replace(scenario="hotspot", n_uavs=3, episode_frames=7)
    assert parallel_env(config=cfg).config == cfg.validate()
    env = parallel_env("no_move", config=cfg, episode_frames=9)
    assert (env.config.scenario, env.config.n_uavs, env.config.episode_frames) == ("no_move", 3, 9)
    assert parallel_env().config.n_uavs == 2 and parallel_env().config.scenario == "circular"
    with pytest.raises(UserError):
        parallel_env(n_uavs=0)
    with pytest.raises(UserError, match="render_mode"):
        FleetParallelEnv(render_mode="human")


def test_missing_pettingzoo_is_a_user_error_and_import_stays_light(monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "pettingzoo", None)
    monkeypatch.delitem(sys.modules, "uavlink.fleet.parallel", raising=False)
    with pytest.raises(UserError, match=r"pip install 'uavlink\[fleet\]'"):
        parallel_env()
    code = "import sys, uavlink, uavlink.fleet\nprint('pettingzoo' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert out.stdout.strip() == "False"
