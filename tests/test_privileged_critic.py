"""The privileged critic (``TrainConfig.critic = "privileged"``, uavlink/learn/privileged.py): in
training the critic also reads every UE's true position and velocity and the episode's progress,
columns appended to each agent row's observation by a VecEnv wrapper; the actor reads the
observation alone, so a policy file flies, evaluates and exports on the actor's observation."""

from __future__ import annotations

import csv
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from support.cli import run_uavlink_in_process

from uavlink.config import EnvConfig, TrainConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import ObservationLayout
from uavlink.env.vec_env import UavVecEnv
from uavlink.errors import UserError
from uavlink.learn.privileged import (
    PrivilegedVecEnv,
    privileged_bounds,
    privileged_columns,
    privileged_size,
)

ROOT = Path(__file__).resolve().parents[1]
FLEET = EnvConfig(scenario="no_move", n_uavs=2)


def _expected(core: BatchedUavEnv) -> np.ndarray:
    """The columns by hand, row by row: row r is UAV r % D of env r // D."""
    cfg, rows = core.cfg, []
    truth = core.ground_truth()
    for r in range(core.n_rows):
        env = r // cfg.n_uavs
        relative = (truth.ue_xy_m[env] - truth.uav_xy_m[r]) / cfg.area.half_width_m
        velocity = truth.ue_velocity_mps[env] / cfg.ue_speed_mps
        rows.append([*relative.ravel(), *velocity.ravel(), core.frame / cfg.episode_frames])
    return np.array(rows, dtype=np.float32)


@pytest.mark.parametrize("n_uavs", [1, 2, 3])
def test_each_row_gets_its_envs_truth_and_the_width_does_not_grow_with_the_fleet(
    n_uavs: int,
) -> None:
    cfg = EnvConfig(scenario="mixed", n_uavs=n_uavs)
    size = ObservationLayout.for_config(cfg).size
    assert privileged_size(cfg) == 4 * cfg.n_ues + 1 == privileged_size(FLEET)
    plain, wide = (
        UavVecEnv(cfg, n_envs=3, seed=5),
        PrivilegedVecEnv(UavVecEnv(cfg, n_envs=3, seed=5)),
    )
    assert wide.observation_space.shape == (size + privileged_size(cfg),)
    obs, reference = wide.reset(), plain.reset()
    rng = np.random.default_rng(0)
    for _ in range(6):
        np.testing.assert_array_equal(obs[:, :size], reference)  # the env itself is untouched
        np.testing.assert_allclose(obs[:, size:], _expected(wide.venv.core), atol=1e-6)
        assert all(wide.observation_space.contains(row) for row in obs)
        actions = rng.uniform(-1, 1, (3 * n_uavs, 2)).astype(np.float32)
        obs, reward, _, _ = wide.step(actions)
        reference, plain_reward, _, _ = plain.step(actions)
        np.testing.assert_array_equal(reward, plain_reward)


def test_the_terminal_observation_carries_the_last_frames_columns() -> None:
    cfg = FLEET.replace(episode_frames=4)
    size = ObservationLayout.for_config(cfg).size
    wide, twin = PrivilegedVecEnv(UavVecEnv(cfg, n_envs=2, seed=9)), BatchedUavEnv(cfg, 2, seed=9)
    wide.reset()
    twin.reset(9)  # UavVecEnv seeds its first reset with its seed, as here
    rng = np.random.default_rng(1)
    for _ in range(cfg.episode_frames):
        actions = rng.uniform(-1, 1, (4, 2)).astype(np.float32)
        obs, _, dones, infos = wide.step(actions)
        last = twin.step(actions).observation  # no reset: its truth stays the last frame's
    assert dones.all()
    terminal = np.stack([info["terminal_observation"] for info in infos])
    np.testing.assert_array_equal(terminal[:, :size], last)
    np.testing.assert_allclose(terminal[:, size:], _expected(twin), atol=1e-6)
    assert (terminal[:, -1] == 1.0).all() and (obs[:, -1] == 0.0).all()  # then the new episode's
    np.testing.assert_allclose(obs[:, size:], _expected(wide.venv.core), atol=1e-6)


def test_fleets_of_two_three_and_four_trained_together_each_get_their_columns() -> None:
    """One any-size policy trains on several fleet sizes side by side (fleet_sizes_up_to): each
    size's part is wrapped, and every part gives one width, as the any-size observation does."""
    from uavlink.env.vec_env import FleetSizesVecEnv
    from uavlink.learn.privileged import privileged_env

    cfg = EnvConfig().replace(n_uavs=2, fleet_slots=3, episode_frames=4).validate()
    venv = privileged_env(FleetSizesVecEnv.for_sizes(cfg, (2, 3, 4), n_envs=2, seed=5))
    assert isinstance(venv, FleetSizesVecEnv) and venv.num_envs == 2 * (2 + 3 + 4)
    size = ObservationLayout.for_config(cfg).size
    assert venv.observation_space.shape == (size + privileged_size(cfg),)
    obs = venv.reset()
    for _ in range(cfg.episode_frames):
        obs, _, dones, infos = venv.step(np.zeros((venv.num_envs, 2), np.float32))
    assert dones.all() and obs.shape == (18, size + privileged_size(cfg))
    assert all(info["terminal_observation"].shape == obs.shape[1:] for info in infos)
    assert all(info["terminal_observation"][-1] == 1.0 for info in infos)
    first = 0
    for part in venv.parts:
        assert isinstance(part, PrivilegedVecEnv)
        rows = part.num_envs
        np.testing.assert_allclose(obs[first : first + rows, size:], _expected(part.venv.core))
        first += rows


def test_ues_that_stand_still_read_zero_velocity() -> None:
    cfg = EnvConfig(ue_speed_mps=0.0)
    core = BatchedUavEnv(cfg, 2, seed=0)
    core.reset()
    columns = privileged_columns(core.ground_truth(), cfg)
    u = 2 * cfg.n_ues
    assert np.isfinite(columns).all() and not columns[:, u : 2 * u].any()
    low, high = privileged_bounds(cfg)
    assert ((columns >= low) & (columns <= high)).all()


@pytest.mark.slow  # builds PPO (torch)
def test_the_actor_reads_the_actors_observation_only_the_critic_reads_more() -> None:
    """Random privileged columns change the critic's values, and nothing of the actor: not its
    deterministic actions, not its distribution's mean or log-probabilities."""
    import torch

    from uavlink.learn.training import make_model
    from uavlink.policies.sb3_policy import ActorPolicy

    model = make_model(FLEET, TrainConfig(n_envs=4, batch_size=256, critic="privileged"), None)
    policy, size = model.policy, ObservationLayout.for_config(FLEET).size
    assert type(policy).__name__ == "PrivilegedCriticPolicy" and policy.actor_obs_size == size
    env = model.get_env()
    obs = env.reset()
    for _ in range(5):
        obs, *_ = env.step(np.random.default_rng(2).uniform(-1, 1, (8, 2)).astype(np.float32))
    low, high = privileged_bounds(FLEET)
    other = obs.copy()
    other[:, size:] = np.random.default_rng(3).uniform(low, high, other[:, size:].shape)
    a, b = torch.as_tensor(obs), torch.as_tensor(other)
    with torch.no_grad():
        (act_a, value_a, logp_a), (act_b, value_b, logp_b) = policy(a, True), policy(b, True)
        mean_a = policy.get_distribution(a).distribution.mean
        mean_b = policy.get_distribution(b).distribution.mean
        some = torch.as_tensor(np.random.default_rng(4).uniform(-1, 1, (len(obs), 2)))
        _, logp_some_a, _ = policy.evaluate_actions(a, some)
        _, logp_some_b, _ = policy.evaluate_actions(b, some)
    assert torch.equal(act_a, act_b) and torch.equal(mean_a, mean_b) and torch.equal(logp_a, logp_b)
    assert torch.equal(logp_some_a, logp_some_b)
    np.testing.assert_array_equal(
        model.predict(obs, deterministic=True)[0], model.predict(other, deterministic=True)[0]
    )
    assert (value_a - value_b).abs().min() > 0  # every row's value moved
    # what evaluate and fly run: the actor on the actor's observation alone, as SB3 predicts
    actor = ActorPolicy(policy, ObservationLayout.for_config(FLEET), "p").act(obs[:, :size])
    np.testing.assert_allclose(actor, model.predict(obs, deterministic=True)[0], atol=1e-6)


@pytest.mark.slow  # trains PPO
def test_one_privileged_critic_trains_on_fleets_of_two_three_and_four_together(
    tmp_path: Path,
) -> None:
    from uavlink.learn.training import train
    from uavlink.policies.sb3_policy import SB3Policy

    cfg = EnvConfig().replace(n_uavs=2, fleet_slots=3, episode_frames=16).validate()
    tc = TrainConfig(
        episodes=12, n_envs=2, n_steps=16, batch_size=32, fleet_sizes_up_to=4, critic="privileged"
    )
    training = train(cfg, tc, tmp_path / "any.zip", None, progress=False)
    assert training["total_timesteps"] == 2 * 16 * (2 + 3 + 4) * 2  # two rollouts of 18 rows
    policy = SB3Policy(tmp_path / "any.zip")
    for d in (2, 3, 4):  # the actor on each size's own observation
        obs = BatchedUavEnv(cfg.replace(n_uavs=d).validate(), 2, seed=d).reset()
        assert policy.act(obs).shape == (2 * d, 2)


def _train(tmp_path: Path, *extra: str) -> tuple[Path, float]:
    out = tmp_path / "fleet.zip"
    start = time.perf_counter()
    proc = run_uavlink_in_process(
        "train",
        "--scenario",
        "no_move",
        "--set",
        "n_uavs=2",
        "--critic",
        "privileged",
        "--out",
        str(out),
        "--episodes",
        "8",
        "--n-envs",
        "4",
        "--batch-size",
        "256",
        "--n-epochs",
        "2",
        "--run-dir",
        str(tmp_path / "run"),
        "--eval-episodes",
        "2",
        "--no-progress",
        *extra,
    )
    assert proc.returncode == 0, proc.stderr
    return out, time.perf_counter() - start


@pytest.mark.slow  # trains PPO, exports ONNX
def test_a_privileged_critic_fleet_trains_evaluates_and_exports_the_actor_alone(
    tmp_path: Path,
) -> None:
    from uavlink.policies.onnx_policy import OnnxPolicy
    from uavlink.policies.sb3_policy import SB3Policy

    # a warm start (the fleet's aoa rule cloned into the actor on actor observations, then the
    # critic alone fitted) and validation episodes: the whole training path with the wide env
    out, train_s = _train(
        tmp_path,
        "--warm-start",
        "aoa",
        "--warm-start-episodes",
        "4",
        "--warm-start-epochs",
        "2",
        "--warm-start-critic-rollouts",
        "1",
        "--validation-episodes",
        "2",
    )
    manifest = json.loads(out.with_suffix(".json").read_text())
    training = manifest["training"]
    assert training["hyperparameters"]["critic"] == "privileged"
    assert training["total_timesteps"] == 8 * 128 * 2
    assert training["warm_start"]["samples"] == 4 * 128 * 2
    assert np.isfinite(training["warm_start"]["final_mse"])
    assert len(training["validation"]["curve"]) == 3  # before each of 2 updates, and at the end
    # the per-update metrics SB3 logs, as a table beside TensorBoard's events
    with (tmp_path / "run" / "ppo_1" / "progress.csv").open() as table:
        records = list(csv.DictReader(table))
    updates = [r for r in records if r["train/explained_variance"] and r["train/value_loss"]]
    assert len(updates) == 2 and records[-1] is updates[-1]  # every update's, the last one's too
    assert records[-1]["time/total_timesteps"] == str(8 * 128 * 2)
    assert all(r["rollout/mean_rate_mbps"] for r in records[:-1])

    size = ObservationLayout.for_config(FLEET).size
    zipped = SB3Policy(out)
    assert zipped.layout.size == size and zipped.model.observation_space.shape == (
        size + privileged_size(FLEET),
    )
    start = time.perf_counter()
    evaluated = run_uavlink_in_process(
        "evaluate", "--policy", str(out), "--episodes", "2", "--json"
    )
    evaluate_s = time.perf_counter() - start
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads(evaluated.stdout)["mean_rate_mbps"] > 0

    onnx = tmp_path / "fleet.onnx"
    start = time.perf_counter()
    exported = run_uavlink_in_process("export", str(out), "--out", str(onnx))
    export_s = time.perf_counter() - start
    assert exported.returncode == 0, exported.stderr
    assert f"[batch, {size}]" in exported.stdout and "1000 of 1000 bit-identical" in exported.stdout
    twin = OnnxPolicy(onnx)
    assert twin.layout == zipped.layout
    assert twin.manifest["training"]["hyperparameters"]["critic"] == "privileged"
    env = BatchedUavEnv(FLEET, n_envs=8, seed=11)
    obs, rng = env.reset(), np.random.default_rng(11)
    for _ in range(8):  # the twin equals the zip to the last bit, on the actor's observation
        np.testing.assert_array_equal(twin.act(obs), zipped.act(obs))
        obs = env.step(rng.uniform(-1, 1, (obs.shape[0], 2)).astype(np.float32)).observation
    print(f"\ntrain {train_s:.1f} s, evaluate {evaluate_s:.1f} s, export {export_s:.1f} s")

    # resuming needs the same critic: one line, before anything starts
    resumed = run_uavlink_in_process(
        "train",
        "--scenario",
        "no_move",
        "--set",
        "n_uavs=2",
        "--out",
        str(tmp_path / "again.zip"),
        "--resume",
        str(out),
        "--run-dir",
        str(tmp_path / "again"),
    )
    assert resumed.returncode == 2 and resumed.stderr.count("\n") == 1, resumed.stderr
    assert "its critic is 'privileged', not --critic 'actor'" in resumed.stderr
    assert not (tmp_path / "again").exists()

    # a start from its weights: a privileged critic keeps its own inputs; a plain one cannot
    from uavlink.learn.policy_transfer import start_from_policy
    from uavlink.learn.training import make_model

    keep = shutil.copy(out, tmp_path / "start.zip")
    grown = make_model(
        FLEET, TrainConfig(n_envs=2, batch_size=256, critic="privileged"), None
    ).policy
    start_from_policy(grown, FLEET, keep)
    source = zipped.model.policy.state_dict()
    assert all(np.array_equal(v, source[k]) for k, v in grown.state_dict().items())
    with pytest.raises(UserError, match="another net_arch or train.critic"):
        start_from_policy(
            make_model(FLEET, TrainConfig(n_envs=2, batch_size=256), None).policy, FLEET, keep
        )


@pytest.mark.slow  # builds PPO and loads a policy (torch)
def test_a_plain_fleet_policy_starts_a_privileged_critic_that_values_as_it_did() -> None:
    """Started from a shipped fleet policy (its critic read the observation), the privileged
    critic's own inputs get zero weights: actions and values are the file's, whatever they read."""
    import torch
    from stable_baselines3 import PPO

    from uavlink.learn.policy_transfer import start_from_policy
    from uavlink.learn.training import make_model
    from uavlink.policies.contract import manifest_env
    from uavlink.policies.manifest import read_zip_manifest

    path = ROOT / "policies" / "fleet_d2" / "hotspot.zip"
    cfg = manifest_env(read_zip_manifest(path))
    model = make_model(cfg, TrainConfig(n_envs=2, batch_size=256, critic="privileged"), None)
    report = start_from_policy(model.policy, cfg, path)
    assert report["inputs_new"] == 0
    source = PPO.load(path, device="cpu").policy
    env = model.get_env()
    obs = env.reset()
    size = ObservationLayout.for_config(cfg).size
    with torch.no_grad():
        new = model.policy(torch.as_tensor(obs), deterministic=True)
        old = source(torch.as_tensor(obs[:, :size]), deterministic=True)
    np.testing.assert_allclose(new[0].numpy(), old[0].numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(new[1].numpy(), old[1].numpy(), rtol=1e-5, atol=1e-5)
