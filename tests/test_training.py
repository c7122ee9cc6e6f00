"""Training, policy files and their manifests (tiny budgets; full training is a command)."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from support.cli import TINY_TRAINING

from uavlink.cli import main
from uavlink.config import EnvConfig, TrainConfig
from uavlink.evaluation import evaluate_policy
from uavlink.learn.training import time_to_fraction, train
from uavlink.policies.manifest import MANIFEST_NAME, PolicyFileError, read_zip_manifest
from uavlink.policies.sb3_policy import SB3Policy

pytestmark = pytest.mark.slow  # trains PPO


@pytest.fixture
def tiny_policy(tiny_policy_zip: Path) -> Path:
    """The session's tiny `straight` policy (tests/conftest.py)."""
    return tiny_policy_zip


def test_tiny_training_learns_to_follow(tiny_policy: Path, tmp_path: Path) -> None:
    cfg = EnvConfig(scenario="straight")
    learned = evaluate_policy(SB3Policy(tiny_policy), cfg, episodes=32, seed=1)
    untrained_out = tmp_path / "untrained.zip"
    train(
        cfg,
        TrainConfig(episodes=1, n_envs=1, batch_size=64, n_epochs=1),
        untrained_out,
        None,
        progress=False,
    )
    untrained = evaluate_policy(SB3Policy(untrained_out), cfg, episodes=32, seed=1)
    from uavlink.policies.baselines import StaticPolicy

    static = evaluate_policy(StaticPolicy(cfg), cfg, episodes=32, seed=1)
    print(
        f"\nstraight, 32 episodes: static {static.mean_rate_mbps:.3f}, untrained "
        f"{untrained.mean_rate_mbps:.3f}, 12k-step PPO {learned.mean_rate_mbps:.3f} Mbps"
    )
    assert learned.mean_rate_mbps > static.mean_rate_mbps + 0.2
    assert learned.mean_rate_mbps > untrained.mean_rate_mbps + 0.2


def test_manifest_round_trip(tiny_policy: Path) -> None:
    manifest = read_zip_manifest(tiny_policy)
    assert manifest["env_config"]["scenario"] == "straight"
    assert EnvConfig.from_dict(manifest["env_config"]) == EnvConfig(scenario="straight")
    assert manifest["action_mapping"] == {"r_max_m": 12.0, "kind": "cartesian-v1"}
    assert manifest["observation_layout"]["version"] == 1
    hyper = manifest["training"]["hyperparameters"]
    assert TrainConfig.from_dict(hyper) == TrainConfig(**TINY_TRAINING)
    assert (
        hyper["learning_rate"] == 3e-4 and hyper["warm_start"]["teacher"] == ""
    )  # the nested shape
    assert manifest["training"]["total_timesteps"] >= 96 * 128
    assert "torch" in manifest["versions"] and "stable-baselines3" in manifest["versions"]
    beside = json.loads(tiny_policy.with_suffix(".json").read_text())
    assert beside == manifest


def test_layout_mismatch_refused(tiny_policy: Path) -> None:
    policy = SB3Policy(tiny_policy)
    with pytest.raises(
        ValueError,
        match=r"policy 'straight' expects v1 \(n_ues=10, memory=4.*env provides v1 \(n_ues=10, memory=2",
    ):
        evaluate_policy(policy, EnvConfig(scenario="straight", memory=2), episodes=1)


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["truncate", "garbage", "no_manifest", "bad_manifest"])
def test_damaged_policy_file_refused(tiny_policy: Path, tmp_path: Path, damage: str) -> None:
    path = tmp_path / "damaged.zip"
    data = tiny_policy.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(b"not a zip at all" * 10)
    else:
        with zipfile.ZipFile(tiny_policy) as src, zipfile.ZipFile(path, "w") as dst:
            for name in src.namelist():
                if name != MANIFEST_NAME:
                    dst.writestr(name, src.read(name))
            if damage == "bad_manifest":
                dst.writestr(MANIFEST_NAME, json.dumps({"format": "something-else"}))
    with pytest.raises(PolicyFileError, match=str(path)):
        SB3Policy(path)
    proc = subprocess.run(
        [sys.executable, "-m", "uavlink.cli", "evaluate", "--policy", str(path), "--episodes", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_evaluation_is_deterministic(tiny_policy: Path) -> None:
    cfg = EnvConfig(scenario="straight")
    a = evaluate_policy(SB3Policy(tiny_policy), cfg, episodes=4, seed=7)
    b = evaluate_policy(SB3Policy(tiny_policy), cfg, episodes=4, seed=7)
    assert np.array_equal(a.episode_rate_mbps, b.episode_rate_mbps)


def test_time_to_fraction() -> None:
    curve = [(i * 100, min(1.0, i / 50)) for i in range(1, 101)]
    steps = time_to_fraction(curve, 0.95, window=1)
    assert steps == 4800


def test_train_cli_resumes_from_checkpoint(tmp_path: Path) -> None:
    run = tmp_path / "run"
    out = tmp_path / "p.zip"
    args = [
        "train",
        "--scenario",
        "no_move",
        "--out",
        str(out),
        "--n-envs",
        "4",
        "--batch-size",
        "256",
        "--n-epochs",
        "1",
        "--run-dir",
        str(run),
        "--eval-episodes",
        "2",
    ]
    # the first run in this process (no child's torch import), the resumed one as users run it
    assert main([*args, "--episodes", "8", "--no-progress"]) == 0
    assert (run / "ppo_1").is_dir(), "TensorBoard logs"
    header = (run / "ppo_1" / "progress.csv").read_text().splitlines()[0].split(",")
    assert {"train/explained_variance", "train/value_loss"} <= set(header)  # the same, as a table
    manifest = read_zip_manifest(out)
    assert set(manifest["evaluation"]) == {"no_move"}
    checkpoint = run / "checkpoint.zip"
    out.replace(checkpoint)  # a policy zip is a valid SB3 checkpoint
    second = subprocess.run(
        [
            sys.executable,
            "-m",
            "uavlink.cli",
            *args,
            "--episodes",
            "16",
            "--resume",
            str(checkpoint),
            "--learning-rate",
            "0.01",
            "--batch-size",
            "512",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert second.returncode == 0, second.stderr
    assert "\r" not in second.stderr, "no progress bar when stderr is not a terminal"
    # a line at every tenth of the budget instead, from where the checkpoint left off (8 of 16 episodes)
    lines = [line for line in second.stderr.splitlines() if line.startswith("train: ")]
    assert [line.split(" %")[0] for line in lines] == [f"train: {p}" for p in range(60, 101, 10)]
    assert lines[-1].startswith("train: 100 % (2,048 of 2,048 steps), ") and " Mbps, " in lines[-1]
    assert "no_move: " in second.stdout and " Mbps " in second.stdout  # its evaluation, printed
    training = read_zip_manifest(out)["training"]
    assert training["total_timesteps"] == 16 * 128
    # the resumed model trained with this command's PPO settings, which its manifest records
    from stable_baselines3 import PPO

    resumed = PPO.load(out, device="cpu")
    assert (resumed.learning_rate, resumed.batch_size) == (0.01, 512)
    assert (
        training["hyperparameters"]["learning_rate"],
        training["hyperparameters"]["batch_size"],
    ) == (0.01, 512)
    # a checkpoint of another observation: one line, before anything starts
    other = subprocess.run(
        [
            sys.executable,
            "-m",
            "uavlink.cli",
            *args,
            "--episodes",
            "16",
            "--resume",
            str(checkpoint),
            "--set",
            "place_cell_m=12",
            "--run-dir",
            str(tmp_path / "other"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert other.returncode == 2 and other.stderr.count("\n") == 1, other.stderr
    assert "its observation has 60 values, this env's 112" in other.stderr
    assert not (tmp_path / "other").exists()


def test_ctrl_c_leaves_a_whole_checkpoint_to_resume_from(tmp_path: Path) -> None:
    """KeyboardInterrupt mid-training (here from a callback, as Ctrl-C would arrive) saves the run's
    checkpoint whole and says where it is; nothing of the policy file is written."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class CtrlC(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= 1024:
                raise KeyboardInterrupt
            return True

    cfg, run = EnvConfig(scenario="no_move"), tmp_path / "run"
    tc = TrainConfig(episodes=64, n_envs=4, batch_size=256, n_epochs=1)
    with pytest.raises(
        KeyboardInterrupt, match=r"checkpoint at 1,024 steps in .*checkpoint.zip; --resume"
    ):
        train(cfg, tc, tmp_path / "p.zip", run, progress=False, callbacks=[CtrlC()])
    assert PPO.load(run / "checkpoint.zip", device="cpu").num_timesteps == 1024
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert not (run / "checkpoint.partial.zip").exists()


def test_budget_is_in_episodes_of_the_envs_length(tmp_path: Path, capsys) -> None:
    out = tmp_path / "short.zip"
    assert (
        main(
            [
                "train",
                "--scenario",
                "straight",
                "--set",
                "episode_frames=16",
                "--episodes",
                "4",
                "--n-envs",
                "4",
                "--n-steps",
                "16",
                "--batch-size",
                "32",
                "--n-epochs",
                "1",
                "--out",
                str(out),
                "--run-dir",
                str(tmp_path / "run"),
                "--eval-episodes",
                "0",
                "--no-progress",
            ]
        )
        == 0
    )
    assert "for 64 env steps" in capsys.readouterr().err
    manifest = read_zip_manifest(out)
    assert (
        manifest["training"]["total_timesteps"] == 4 * 16
        and manifest["env_config"]["episode_frames"] == 16
    )


def test_rollouts_that_cut_episodes_are_warned(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    args = [
        "train",
        "--scenario",
        "straight",
        "--set",
        "episode_frames=16",
        "--episodes",
        "4",
        "--n-envs",
        "4",
        "--batch-size",
        "32",
        "--n-epochs",
        "1",
        "--run-dir",
        str(tmp_path / "run"),
        "--eval-episodes",
        "0",
        "--no-progress",
    ]
    for n_steps in (8, 32):
        caplog.clear()
        assert (
            main([*args, "--n-steps", str(n_steps), "--out", str(tmp_path / f"{n_steps}.zip")]) == 0
        )
        cut = "train.n_steps=8 is not a multiple of env.episode_frames=16" in caplog.text
        assert cut == (n_steps == 8), caplog.text
