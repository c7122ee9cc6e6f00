"""Behaviour-cloning warm start (uavlink/learn/imitation.py) and its use by `uavlink train`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from uavlink.cli import main
from uavlink.config import EnvConfig, TrainConfig
from uavlink.learn.imitation import clone_actor, student_dataset, teacher_dataset, warm_start
from uavlink.learn.teachers import AoaVariant, make_teacher
from uavlink.learn.training import make_model
from uavlink.policies.baselines import AoaPolicy
from uavlink.policies.manifest import read_zip_manifest
from uavlink.policies.registry import make_baseline

CFG = EnvConfig(scenario="hotspot")


def test_teacher_dataset_is_the_rules_own_flying_and_seeded() -> None:
    obs, actions = teacher_dataset(CFG, "aoa", episodes=3, seed=4)
    assert obs.shape == (3 * CFG.episode_frames, 60) and actions.shape == (
        3 * CFG.episode_frames,
        2,
    )
    assert obs.dtype == actions.dtype == np.float32
    np.testing.assert_allclose(actions, make_baseline("aoa", CFG).act(obs), atol=1e-6)
    again = teacher_dataset(CFG, "aoa", episodes=3, seed=4)
    np.testing.assert_array_equal(obs, again[0])
    assert not np.array_equal(obs, teacher_dataset(CFG, "aoa", episodes=3, seed=5)[0])
    with pytest.raises(ValueError, match="unknown teacher 'gps'"):
        teacher_dataset(CFG, "gps", episodes=1, seed=0)


def test_teacher_dataset_flies_what_the_teacher_says_it_is() -> None:
    """No guessing by type: the privileged teacher (needs_truth) gets the true AoAs, the rule itself
    flies on the observation's noisy ones, so under AoA noise their data differ."""
    noisy = CFG.replace(aoa_noise_deg=100.0)
    obs, actions = teacher_dataset(noisy, AoaPolicy(noisy), episodes=2, seed=1)
    np.testing.assert_array_equal(actions, AoaPolicy(noisy).act(obs).astype(np.float32))
    privileged_obs, privileged = teacher_dataset(noisy, "aoa", episodes=2, seed=1)
    np.testing.assert_array_equal(privileged_obs[:2], obs[:2])  # the same episodes
    assert np.abs(privileged[:2] - actions[:2]).max() > 0.1


@pytest.mark.slow
def test_dagger_data_is_the_copys_flying_labelled_by_the_teacher() -> None:
    """A DAgger round: the copy (here an untrained actor, which flies nothing like the rule) picks
    the moves, so the frames are its own; the labels are what the teacher does in them; seeded per
    round. A fleet's GPS teacher labels from the truth of the copy's own frames."""
    import torch

    model = make_model(CFG, TrainConfig(n_envs=2), None)
    teacher = make_baseline("aoa", CFG)
    obs, labels = student_dataset(model.policy, CFG, teacher, episodes=2, seed=3, round_index=0)
    assert obs.shape == (2 * CFG.episode_frames, 60) and labels.shape == (
        2 * CFG.episode_frames,
        2,
    )
    np.testing.assert_allclose(labels, teacher.act(obs), atol=1e-6)
    rule_obs, _ = teacher_dataset(CFG, teacher, episodes=2, seed=3)
    half = CFG.episode_frames // 2
    assert not np.allclose(obs[half:], rule_obs[half:])
    again = student_dataset(model.policy, CFG, teacher, episodes=2, seed=3, round_index=0)
    np.testing.assert_array_equal(obs, again[0])
    other_round = student_dataset(model.policy, CFG, teacher, episodes=2, seed=3, round_index=1)
    assert not np.array_equal(obs[:1], other_round[0][:1])  # another round's episodes
    with torch.no_grad():
        weights = [p.clone() for p in model.policy.parameters()]
    report = warm_start(
        model.policy, [(CFG, teacher)], episodes=2, seed=3, epochs=1, dagger_rounds=2
    )
    assert (report.samples, report.dagger_rounds) == (3 * 2 * CFG.episode_frames, 2)
    assert report.to_dict()["dagger_rounds"] == 2
    assert any(
        not torch.equal(a, b) for a, b in zip(weights, model.policy.parameters(), strict=True)
    )

    fleet = EnvConfig(scenario="hotspot", n_uavs=2, fleet_slots=3, episode_frames=8)
    fleet_model = make_model(fleet, TrainConfig(n_envs=2), None)
    kmeans = make_baseline("kmeans", fleet)
    fleet_obs, fleet_labels = student_dataset(
        fleet_model.policy, fleet, kmeans, episodes=2, seed=3, round_index=0
    )
    assert fleet_obs.shape[0] == fleet_labels.shape[0] == 2 * 2 * fleet.episode_frames
    assert np.abs(fleet_labels).max() > 0.5  # kmeans flies towards its groups, not at rest


@pytest.mark.slow
def test_cloned_actor_flies_like_its_teacher() -> None:
    """After cloning, the untrained PPO actor acts like the aoa rule on episodes it never saw, and
    flies about as well as the rule, far from what the random initial actor does."""
    model = make_model(CFG, TrainConfig(n_envs=2, batch_size=256), None)
    obs, actions = teacher_dataset(CFG, "aoa", episodes=24, seed=0)
    mse = clone_actor(model.policy, obs, actions, epochs=30, log_std=-1.5)
    assert mse < 0.01
    assert np.allclose(model.policy.log_std.detach().numpy(), -1.5)
    held_out, teacher_actions = teacher_dataset(CFG, "aoa", episodes=4, seed=99)
    student, _ = model.predict(held_out, deterministic=True)
    assert float(np.mean((student - teacher_actions) ** 2)) < 0.02


@pytest.mark.slow
def test_train_with_warm_start_records_it_and_starts_from_the_rule(tmp_path: Path, capsys) -> None:
    out = tmp_path / "ws.zip"
    code = main(
        [
            "train",
            "--scenario",
            CFG.scenario,
            "--out",
            str(out),
            "--episodes",
            "8",
            "--n-envs",
            "4",
            "--batch-size",
            "128",
            "--warm-start",
            "aoa",
            "--warm-start-episodes",
            "16",
            "--eval-episodes",
            "0",
            "--run-dir",
            str(tmp_path / "run"),
        ]
    )
    assert code == 0
    # the copy runs before PPO's first step: its start and end are said (stderr: a line each)
    err = capsys.readouterr().err
    assert "warm start: copying aoa (16 episodes)\nwarm start: done in " in err, err
    warm = read_zip_manifest(out)["training"]["warm_start"]
    assert warm["teacher"] == "aoa" and warm["samples"] == 16 * CFG.episode_frames
    assert json.loads(out.with_suffix(".json").read_text())["training"]["warm_start"] == warm
    # 1,024 PPO steps = 2 rollouts, inside the 10-rollout critic warm-up: the actor is the clone,
    # untouched (its log std still the reset value), while the critic has learned.
    from stable_baselines3 import PPO

    model = PPO.load(out, device="cpu")
    policy = model.policy
    assert np.allclose(policy.log_std.detach().numpy(), TrainConfig().warm_start.log_std)
    fresh = make_model(
        CFG, TrainConfig(n_envs=2, batch_size=256), None
    )  # same seed: the same initial critic
    assert not np.allclose(
        policy.value_net.weight.detach().numpy(), fresh.policy.value_net.weight.detach().numpy()
    )
    # and the actor acts as the rule, far closer than the untrained actor does (16 episodes' clone)
    held_out, teacher_actions = teacher_dataset(CFG, "aoa", episodes=2, seed=99)
    mse = [
        float(np.mean((m.predict(held_out, deterministic=True)[0] - teacher_actions) ** 2))
        for m in (model, fresh)
    ]
    print(f"\nheld-out action MSE to the rule: warm-started {mse[0]:.4f}, untrained {mse[1]:.4f}")
    assert mse[0] < 0.5 * mse[1], mse


@pytest.mark.slow
def test_gated_teacher_and_its_settings(tmp_path: Path, capsys) -> None:
    """The aoa teacher with its shadow gate and speed span flies that variant of the rule; both belong
    to aoa only, and `uavlink train` records them (and the exploration std PPO restarts from) in the
    manifest."""
    cfg = EnvConfig(scenario="straight_180")
    obs, actions = teacher_dataset(
        cfg, make_teacher(cfg, "aoa", shadow_gate_db=0.0, sinr_span_db=2.0), episodes=2, seed=3
    )
    np.testing.assert_allclose(
        actions, AoaVariant(cfg, sinr_span_db=2.0, shadow_gate_db=0.0).act(obs), atol=1e-6
    )
    assert (np.abs(actions).sum(axis=1) == 0).any()  # the gate made it hover somewhere
    assert not np.allclose(
        actions, AoaVariant(cfg, shadow_gate_db=0.0).act(obs), atol=1e-3
    )  # the span counts
    for flag in (
        "--warm-start-shadow-gate-db",
        "--warm-start-sinr-span-db",
        "--warm-start-shadow-estimator-episodes",
    ):
        assert (
            main(
                ["train", "--scenario", "straight_180", "--out", str(tmp_path / "x.zip"), flag, "2"]
            )
            == 2
        )
        assert (
            "needs --warm-start aoa" in capsys.readouterr().err
            and not (tmp_path / "x.zip").exists()
        )
    assert (
        main(
            [
                "train",
                "--scenario",
                "straight_180",
                "--out",
                str(tmp_path / "x.zip"),
                "--warm-start",
                "aoa",
                "--warm-start-shadow-estimator-episodes",
                "8",
            ]
        )
        == 2
    )
    assert (
        "needs --warm-start-shadow-gate-db" in capsys.readouterr().err
        and not (tmp_path / "x.zip").exists()
    )
    for flag in (
        "--warm-start-sinr-span-db",
        "--warm-start-epochs",
        "--warm-start-shadow-estimator-episodes",
    ):
        assert (
            main(
                [
                    "train",
                    "--scenario",
                    "straight_180",
                    "--out",
                    str(tmp_path / "x.zip"),
                    "--warm-start",
                    "aoa",
                    flag,
                    "0",
                ]
            )
            == 2
        )
        assert "must be positive" in capsys.readouterr().err and not (tmp_path / "x.zip").exists()
    out = tmp_path / "gated.zip"
    assert (
        main(
            [
                "train",
                "--scenario",
                "straight_180",
                "--out",
                str(out),
                "--episodes",
                "4",
                "--n-envs",
                "4",
                "--batch-size",
                "128",
                "--warm-start",
                "aoa",
                "--warm-start-episodes",
                "4",
                "--warm-start-shadow-gate-db",
                "0.5",
                "--warm-start-sinr-span-db",
                "3",
                "--warm-start-log-std",
                "-3",
                "--warm-start-epochs",
                "2",
                "--warm-start-shadow-estimator-episodes",
                "8",
                "--eval-episodes",
                "0",
                "--no-progress",
                "--run-dir",
                str(tmp_path / "run"),
            ]
        )
        == 0
    )
    training = read_zip_manifest(out)["training"]
    hyper = training["hyperparameters"]["warm_start"]
    assert hyper["shadow_gate_db"] == 0.5 and hyper["log_std"] == -3.0
    assert hyper["sinr_span_db"] == 3.0 and hyper["epochs"] == 2
    assert hyper["shadow_estimator_episodes"] == 8
    assert (
        training["warm_start"]["epochs"] == 2
        and training["warm_start"]["shadow_estimator_r2"] < 1.0
    )
