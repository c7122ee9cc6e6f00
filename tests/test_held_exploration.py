"""Exploration held for an episode (``uavlink train --gsde-log-std``,
uavlink/learn/held_exploration.py): the noise a row draws holds until the next rollout, at the
per-frame std asked, and the saved policy is a plain diagonal Gaussian one whose mean action gSDE
never touched."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support.cli import assert_user_error, run_uavlink_in_process

FLEET = ["--scenario", "hotspot", "--set", "n_uavs=2", "--set", "fleet_slots=1"]


def test_a_rows_noise_holds_for_the_rollout_at_the_per_frame_std_asked() -> None:
    """After the callback a row's noise is the same every frame it sees the same state until the
    next draw, its per-frame variance on the first observations is the one asked, a second such
    callback is refused, and at the end a diagonal Gaussian of that std is back with the mean
    action untouched."""
    import torch

    from uavlink.config import EnvConfig, TrainConfig
    from uavlink.errors import UserError
    from uavlink.learn.held_exploration import held_exploration_callback
    from uavlink.learn.training import make_model

    cfg = EnvConfig(scenario="hotspot", n_uavs=2, fleet_slots=1).validate()
    tc = TrainConfig(episodes=8, n_envs=8, critic="privileged").validate(cfg)
    model = make_model(cfg, tc, None)
    model._last_obs = model.env.reset()
    callback = held_exploration_callback(-2.0)
    callback.init_callback(model)
    callback.on_training_start({}, {})
    policy = model.policy
    obs = torch.as_tensor(model._last_obs, dtype=torch.float32)
    with torch.no_grad():
        mean_before = policy.get_distribution(obs).mode()
        policy.reset_noise(len(obs))
        first, again = (policy.get_distribution(obs).sample() for _ in range(2))
        policy.reset_noise(len(obs))
        redrawn = policy.get_distribution(obs).sample()
        variance = policy.get_distribution(obs).distribution.variance
    assert model.use_sde and model.sde_sample_freq == -1
    assert torch.equal(first, again) and not torch.allclose(first, redrawn)
    assert float(variance.mean()) == pytest.approx(np.exp(-4.0), rel=1e-3)
    second = held_exploration_callback(-1.0)  # two at once would save a policy nothing loads
    second.init_callback(model)
    with pytest.raises(UserError, match="on already"):
        second.on_training_start({}, {})
    callback.on_training_end()
    assert tuple(policy.log_std.shape) == (2,) and not model.use_sde
    assert np.allclose(policy.log_std.detach().numpy(), -2.0, atol=0.2)
    with torch.no_grad():
        assert torch.equal(policy.get_distribution(obs).mode(), mean_before)


@pytest.mark.slow  # trains
def test_train_with_held_exploration_saves_a_plain_policy_that_evaluates(tmp_path: Path) -> None:
    from stable_baselines3 import PPO
    from stable_baselines3.common.distributions import DiagGaussianDistribution

    out = tmp_path / "held.zip"
    args = ["train", *FLEET, "--n-envs", "4", "--batch-size", "256", "--critic", "privileged"]
    args += ["--warm-start", "kmeans", "--warm-start-episodes", "4", "--warm-start-epochs", "1"]
    args += ["--gsde-log-std", "-1.5", "--episodes", "16", "--eval-episodes", "0"]
    run_dir = ["--run-dir", str(tmp_path / "run"), "--checkpoint-every-steps", "2000"]
    proc = run_uavlink_in_process(*args, *run_dir, "--no-progress", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    # its checkpoints hold gSDE's noise, which no saved policy may keep: not resumed, even without
    # --gsde-log-std
    checkpoint = tmp_path / "run" / "checkpoint.zip"
    resumed = [*args[: args.index("--gsde-log-std")], "--episodes", "32", "--eval-episodes", "0"]
    refused = run_uavlink_in_process(
        *resumed, "--resume", str(checkpoint), "--out", str(tmp_path / "again.zip")
    )
    assert_user_error(refused, "exploring with gSDE cannot resume")
    manifest = json.loads(out.with_suffix(".json").read_text())
    assert manifest["training"]["hyperparameters"]["gsde_log_std"] == -1.5
    policy = PPO.load(out, device="cpu").policy
    assert isinstance(policy.action_dist, DiagGaussianDistribution) and not policy.use_sde
    assert np.allclose(policy.log_std.detach().numpy(), -1.5, atol=0.3)
    evaluated = run_uavlink_in_process(
        "evaluate", "--policy", str(out), "--episodes", "2", "--json"
    )
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads(evaluated.stdout)["mean_rate_mbps"] > 0


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--resume", "runs/none.zip"], ("--resume", "--gsde-log-std")),
        (["--snapshot", "runs/none.snapshot"], ("--snapshot", "--gsde-log-std")),
    ],
)
def test_held_exploration_refuses_what_cannot_hold_its_noise_in_one_line(
    tmp_path: Path, extra: list[str], named: tuple[str, ...]
) -> None:
    out = tmp_path / "p.zip"
    args = ["train", *FLEET, "--gsde-log-std", "-1", *extra, "--out", str(out)]
    assert_user_error(run_uavlink_in_process(*args), *named)
    assert not out.exists() and not list(tmp_path.iterdir())
