"""Training keeps the weights that fly best on validation episodes (uavlink/learn/selection.py)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from support.cli import TINY_TRAINING

from uavlink.config import EnvConfig, TrainConfig
from uavlink.learn.selection import validation_rate_mbps
from uavlink.learn.training import train
from uavlink.policies.sb3_policy import SB3Policy

pytestmark = pytest.mark.slow  # trains PPO

CFG = EnvConfig(scenario="straight")
EPISODES = 16


def test_training_ships_the_best_scored_weights_and_only_observes_to_choose(tmp_path: Path) -> None:
    plain_tc = TrainConfig(**TINY_TRAINING)
    chosen = train(
        CFG,
        replace(plain_tc, validation_episodes=EPISODES),
        tmp_path / "chosen.zip",
        None,
        progress=False,
    )
    train(CFG, plain_tc, tmp_path / "last.zip", None, progress=False)
    report = chosen["validation"]
    rollouts = -(-chosen["total_timesteps"] // (plain_tc.n_envs * plain_tc.n_steps))
    steps = [step for step, _ in report["curve"]]
    # scored before the first update (step 0), after each update, and at the end
    assert steps == [i * plain_tc.n_envs * plain_tc.n_steps for i in range(rollouts)] + [
        chosen["total_timesteps"]
    ]
    scores = [mbps for _, mbps in report["curve"]]
    assert report["kept_mbps"] == max(scores)
    assert report["kept_steps"] == steps[scores.index(max(scores))]  # the earliest of equals
    assert len(set(scores)) > 1  # PPO moved the policy: there was something to choose from
    # The shipped weights fly the kept score on the same episodes.
    shipped = validation_rate_mbps(SB3Policy(tmp_path / "chosen.zip"), CFG, EPISODES, plain_tc.seed)
    assert shipped == pytest.approx(report["kept_mbps"], abs=1e-6)
    # The scoring only observes: the same training without it ends on the curve's last weights.
    last = validation_rate_mbps(SB3Policy(tmp_path / "last.zip"), CFG, EPISODES, plain_tc.seed)
    assert last == pytest.approx(scores[-1], abs=1e-6)


def test_training_without_validation_records_none(tiny_policy_zip: Path) -> None:
    from uavlink.policies.manifest import read_zip_manifest

    assert read_zip_manifest(tiny_policy_zip)["training"]["validation"] is None


def test_train_cli_says_which_weights_it_kept(tmp_path: Path, capsys) -> None:
    from uavlink.cli import main

    out = tmp_path / "p.zip"
    assert (
        main(
            [
                "train",
                "--scenario",
                "straight",
                "--episodes",
                "32",
                "--n-envs",
                "16",
                "--batch-size",
                "256",
                "--validation-episodes",
                "8",
                "--eval-episodes",
                "0",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    kept = json.loads(out.with_suffix(".json").read_text())["training"]["validation"]
    assert (
        f"kept the weights after {kept['kept_steps']:,} steps: {kept['kept_mbps']:.3f} Mbps on 8 "
        f"validation episodes"
    ) in capsys.readouterr().out


def test_a_fleet_keeps_its_best_weights_too(tmp_path: Path) -> None:
    """A fleet's agent rows fly the same actor: the scoring flies the whole fleet."""
    cfg = EnvConfig(scenario="straight_180", n_uavs=2)
    tc = TrainConfig(episodes=32, n_envs=16, batch_size=256, validation_episodes=4)
    report = train(cfg, tc, tmp_path / "fleet.zip", None, progress=False)["validation"]
    assert len(report["curve"]) == 3  # the start, after the first of two updates, the end
    shipped = validation_rate_mbps(SB3Policy(tmp_path / "fleet.zip"), cfg, 4, tc.seed)
    assert shipped == pytest.approx(report["kept_mbps"], abs=1e-6)


def test_held_exploration_keeps_its_best_mean_weights(tmp_path: Path) -> None:
    """With gSDE the std changes shape where training ends (uavlink/learn/held_exploration.py): the
    kept weights are the mean network, which flies the kept score again."""
    cfg = EnvConfig(scenario="straight_180", n_uavs=2)
    tc = TrainConfig(
        episodes=48, n_envs=16, batch_size=256, validation_episodes=4, gsde_log_std=-1.0
    )
    report = train(cfg, tc, tmp_path / "held.zip", None, progress=False)["validation"]
    assert len(report["curve"]) == 4  # the start, after each of the first two updates, the end
    shipped = validation_rate_mbps(SB3Policy(tmp_path / "held.zip"), cfg, 4, tc.seed)
    assert shipped == pytest.approx(report["kept_mbps"], abs=1e-6)
