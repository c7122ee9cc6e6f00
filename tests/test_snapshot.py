"""Training snapshots (uavlink/learn/snapshot.py): a run stopped between rollouts and continued from
its snapshot ends with the uninterrupted run's weights and learning curve, bit for bit."""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest
from support.interrupt import cut_training

from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.train import WarmStartConfig
from uavlink.errors import UserError
from uavlink.learn.training import train

pytestmark = pytest.mark.slow  # trains four tiny runs

FLEET = EnvConfig(scenario="straight", n_uavs=2, fleet_slots=3, episode_frames=16)
ONE = EnvConfig(scenario="circular", episode_frames=16)


def _fleet_settings(cfg: EnvConfig) -> TrainConfig:
    """Sizes 2-4 side by side, the privileged critic, a kmeans copy with a 2-rollout critic warm-up."""
    return TrainConfig(
        n_envs=2,
        n_steps=16,
        batch_size=32,
        n_epochs=2,
        episodes=2 * 3 * 8,
        fleet_sizes_up_to=4,
        critic="privileged",
        warm_start=WarmStartConfig(teacher="kmeans", episodes=6, epochs=2, critic_rollouts=2),
        seed=3,
    ).validate(cfg)


def _weights(path: Path) -> dict[str, np.ndarray]:
    from stable_baselines3 import PPO

    return {k: v.numpy() for k, v in PPO.load(path, device="cpu").policy.state_dict().items()}


@pytest.mark.parametrize(
    ("cfg", "settings", "stop_at"),
    [
        (FLEET, _fleet_settings, 3),  # within the critic's warm-up (the actor frozen)
        (FLEET, _fleet_settings, 6),  # past it
        (ONE, lambda cfg: TrainConfig(n_envs=4, n_steps=16, batch_size=32, episodes=32, seed=1), 4),
    ],
)
def test_a_run_continued_from_its_snapshot_is_the_uninterrupted_run(
    tmp_path: Path, cfg: EnvConfig, settings, stop_at: int
) -> None:
    cfg = cfg.validate()
    tc = settings(cfg)
    whole = train(cfg, tc, tmp_path / "whole.zip", progress=False)
    snapshot = tmp_path / "run.snapshot"
    cut_training(cfg, tc, tmp_path / "cut.zip", snapshot, stop_at)
    assert snapshot.is_file() and not (tmp_path / "cut.zip").exists()
    continued = train(cfg, tc, tmp_path / "cut.zip", progress=False, snapshot=snapshot)
    assert not snapshot.exists()  # the run finished: its snapshot is gone
    a, b = _weights(tmp_path / "whole.zip"), _weights(tmp_path / "cut.zip")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    for key in ("learning_curve", "total_timesteps", "warm_start", "steps_to_95pct_final"):
        assert continued[key] == whole[key], key


def test_a_continued_run_logs_to_its_run_folder_from_where_it_stopped(tmp_path: Path) -> None:
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    cfg = ONE.validate()
    tc = TrainConfig(n_envs=4, n_steps=16, batch_size=32, episodes=32, seed=1)
    snapshot = tmp_path / "run.snapshot"
    cut_training(cfg, tc, tmp_path / "p.zip", snapshot, 4, run_dir=tmp_path / "stopped")
    train(
        cfg,
        tc,
        tmp_path / "p.zip",
        run_dir=tmp_path / "continued",
        progress=False,
        snapshot=snapshot,
    )
    steps: set[int] = set()
    for events in (tmp_path / "continued").rglob("events.out.tfevents.*"):
        log = EventAccumulator(str(events))
        log.Reload()
        steps |= {s.step for s in log.Scalars("rollout/ep_rew_mean")}
    assert max(steps) == tc.total_timesteps(cfg) and min(steps) > 128  # the rollouts after the cut


def _rates_by_step(table: Path) -> list[tuple[str, str]]:
    import csv

    with table.open() as f:
        return [(r["time/total_timesteps"], r["rollout/mean_rate_mbps"]) for r in csv.DictReader(f)]


def test_a_run_continued_in_its_run_folder_keeps_its_progress_table(tmp_path: Path) -> None:
    """SB3 opens progress.csv empty; the continued run's table is the uninterrupted run's."""
    cfg = ONE.validate()
    tc = TrainConfig(n_envs=4, n_steps=16, batch_size=32, episodes=32, seed=1)
    train(cfg, tc, tmp_path / "whole.zip", run_dir=tmp_path / "whole", progress=False)
    snapshot = tmp_path / "run.snapshot"
    cut_training(cfg, tc, tmp_path / "p.zip", snapshot, 4, run_dir=tmp_path / "run")
    cut = _rates_by_step(tmp_path / "run" / "ppo_1" / "progress.csv")
    train(cfg, tc, tmp_path / "p.zip", run_dir=tmp_path / "run", progress=False, snapshot=snapshot)
    whole = _rates_by_step(tmp_path / "whole" / "ppo_1" / "progress.csv")
    continued = _rates_by_step(tmp_path / "run" / "ppo_1" / "progress.csv")
    # the rows up to the snapshot kept, the one logged after it (before the stop) not doubled
    assert len(cut) >= 3 and continued[: len(cut) - 1] == cut[:-1]
    assert continued == whole


def test_a_snapshot_of_another_training_or_no_snapshot_is_refused_in_one_line(
    tmp_path: Path,
) -> None:
    cfg = ONE.validate()
    tc = TrainConfig(n_envs=4, n_steps=16, batch_size=32, episodes=16, seed=1)
    snapshot = tmp_path / "run.snapshot"
    snapshot.write_bytes(pickle.dumps({"format": "uavlink-train-snapshot-v1", "key": "other"}))
    with pytest.raises(UserError, match="a snapshot of another training"):
        train(cfg, tc, tmp_path / "p.zip", progress=False, snapshot=snapshot)
    snapshot.write_bytes(b"not a pickle")
    with pytest.raises(UserError, match="not a training snapshot"):
        train(cfg, tc, tmp_path / "p.zip", progress=False, snapshot=snapshot)
    assert snapshot.read_bytes() == b"not a pickle"  # left as it was
    keeps_best = dataclasses.replace(tc, validation_episodes=4)
    with pytest.raises(UserError, match="cannot start from --resume, keep the --validation"):
        train(cfg, keeps_best, tmp_path / "p.zip", progress=False, snapshot=snapshot)


def test_uavlink_train_snapshot_continues_a_stopped_run_and_refuses_resume(
    tmp_path: Path, capsys
) -> None:
    from uavlink.cli import main

    args = ["train", "--scenario", "circular", "--set", "episode_frames=16", "--n-envs", "4"]
    args += ["--n-steps", "16", "--batch-size", "32", "--episodes", "32", "--seed", "1"]
    args += ["--eval-episodes", "0", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "whole.zip")]) == 0
    # a run stopped at its third rollout, as `uavlink train --snapshot FILE` builds it
    cfg = ONE.replace(scenario="circular").validate()
    tc = TrainConfig(n_envs=4, n_steps=16, batch_size=32, episodes=32, seed=1)
    snapshot = tmp_path / "snaps" / "run.snapshot"  # its folder is made
    cut_training(cfg, tc, tmp_path / "cut.zip", snapshot, 3)
    capsys.readouterr()
    assert main([*args, "--out", str(tmp_path / "cut.zip"), "--snapshot", str(snapshot)]) == 0
    assert f"continuing from the snapshot {snapshot}" in capsys.readouterr().err
    a, b = _weights(tmp_path / "whole.zip"), _weights(tmp_path / "cut.zip")
    assert all(np.array_equal(a[k], b[k]) for k in a) and not snapshot.exists()
    refused = [*args, "--out", str(tmp_path / "r.zip"), "--snapshot", str(snapshot)]
    assert main([*refused, "--resume", str(tmp_path / "whole.zip")]) == 2
    assert "--snapshot continues a run exactly" in capsys.readouterr().err
