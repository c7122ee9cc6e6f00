"""TrainConfig: its checks, the `uavlink train` flags derived from its fields, old manifests, layers."""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

from uavlink.cli import main
from uavlink.config import (
    PAPER_HYPERPARAMETERS,
    EnvConfig,
    RadioConfig,
    TrainConfig,
    WarmStartConfig,
)
from uavlink.config.fields import add_options, config_fields, flag_of, from_options, with_changes
from uavlink.errors import ConfigError, UserError

ROOT = Path(__file__).resolve().parents[1]

# (changes by field path, what the one-line message names): every check of TrainConfig.validate().
BAD = [
    ({"episodes": 0}, "train.episodes must be positive"),
    ({"episodes": 8.5}, "train.episodes must be an integer"),
    ({"learning_rate": 0.0}, "train.learning_rate must be positive"),
    ({"learning_rate": float("nan")}, "train.learning_rate must be a finite number"),
    ({"net_arch": ()}, "train.net_arch must be a non-empty list"),
    ({"net_arch": (64, 0)}, "train.net_arch must be a non-empty list of positive integers"),
    ({"gamma": 0.0}, "train.gamma must be positive"),
    ({"gamma": 1.01}, "train.gamma must be <= 1"),
    ({"gae_lambda": -0.1}, "train.gae_lambda must be >= 0"),
    ({"gae_lambda": 1.5}, "train.gae_lambda must be <= 1"),
    ({"max_grad_norm": 0.0}, "train.max_grad_norm must be positive"),
    ({"clip_range": -0.2}, "train.clip_range must be positive"),
    ({"n_envs": 0}, "train.n_envs must be positive"),
    ({"n_steps": 0}, "train.n_steps must be positive"),
    ({"n_envs": 1, "n_steps": 1}, "train.n_envs x train.n_steps must be >= 2"),
    ({"batch_size": 1}, "train.batch_size must be >= 2"),
    ({"n_epochs": 0}, "train.n_epochs must be positive"),
    ({"ent_coef": -1.0}, "train.ent_coef must be >= 0"),
    ({"vf_coef": -1.0}, "train.vf_coef must be >= 0"),
    ({"normalize_reward": 1}, "train.normalize_reward must be true or false"),
    ({"aoa_noise_max_deg": -5.0}, "train.aoa_noise_max_deg must be >= 0"),
    ({"seed": -1}, "train.seed must be >= 0"),
    ({"torch_threads": 0}, "train.torch_threads must be positive"),
    ({"critic": "oracle"}, "train.critic must be one of 'actor', 'privileged'"),
    ({"checkpoint_every_steps": 0}, "train.checkpoint_every_steps must be positive"),
    ({"warm_start.teacher": "parrot"}, "train.warm_start.teacher must be one of"),
    ({"warm_start.episodes": 0}, "train.warm_start.episodes must be positive"),
    ({"warm_start.epochs": 0}, "train.warm_start.epochs must be positive"),
    ({"warm_start.log_std": float("inf")}, "train.warm_start.log_std must be a finite number"),
    ({"warm_start.critic_rollouts": -1}, "train.warm_start.critic_rollouts must be >= 0"),
    (
        {"warm_start.teacher": "aoa", "warm_start.sinr_span_db": 0.0},
        "train.warm_start.sinr_span_db must be positive",
    ),
    (
        {
            "warm_start.teacher": "aoa",
            "warm_start.shadow_gate_db": 0.5,
            "warm_start.shadow_estimator_episodes": 0,
        },
        "train.warm_start.shadow_estimator_episodes must be positive",
    ),
    (
        {"warm_start.teacher": "static", "warm_start.shadow_gate_db": 1.0},
        "train.warm_start.shadow_gate_db needs train.warm_start.teacher aoa",
    ),
    (
        {"warm_start.sinr_span_db": 2.0},
        "train.warm_start.sinr_span_db needs train.warm_start.teacher aoa",
    ),
    (
        {"warm_start.teacher": "static", "warm_start.shadow_estimator_episodes": 8},
        "train.warm_start.shadow_estimator_episodes needs train.warm_start.teacher aoa",
    ),
    (
        {"warm_start.teacher": "aoa", "warm_start.shadow_estimator_episodes": 8},
        "train.warm_start.shadow_estimator_episodes needs train.warm_start.shadow_gate_db",
    ),
    (
        {"warm_start.dagger_rounds": 2},
        "train.warm_start.dagger_rounds needs a train.warm_start.teacher",
    ),
    (
        {"warm_start.teacher": "aoa", "warm_start.dagger_rounds": -1},
        "train.warm_start.dagger_rounds must be",
    ),
]


@pytest.mark.parametrize(("changes", "message"), BAD)
def test_validate_refuses_with_one_line_naming_the_field(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        with_changes(TrainConfig(), changes).validate()
    assert str(info.value).startswith(message) and "\n" not in str(info.value)
    assert isinstance(info.value, UserError)


def test_validate_against_the_env() -> None:
    noisy = EnvConfig(radio=RadioConfig(aoa_noise_deg=10.0))
    assert TrainConfig(aoa_noise_max_deg=20.0).validate(noisy).aoa_noise_max_deg == 20.0
    with pytest.raises(
        ConfigError, match=r"^train.aoa_noise_max_deg must be 0 \(off\) or >= the env's"
    ):
        TrainConfig(aoa_noise_max_deg=5.0).validate(noisy)
    with pytest.raises(
        ConfigError,
        match=r"^radio.aoa_noise_max_deg is the training's .* set train.aoa_noise_max_deg",
    ):
        TrainConfig().validate(EnvConfig(radio=RadioConfig(aoa_noise_max_deg=30.0)))
    assert TrainConfig().validate(EnvConfig()) == TrainConfig()
    # the teacher against the env it flies: before any model is built, not in the teacher's factory
    fleet, one = EnvConfig(n_uavs=2), EnvConfig()
    for teacher in ("solo", "lead", "spread"):
        assert TrainConfig(warm_start=WarmStartConfig(teacher=teacher)).validate(fleet)
        with pytest.raises(
            ConfigError, match=rf"^train.warm_start.teacher {teacher} is a fleet's teacher"
        ):
            TrainConfig(warm_start=WarmStartConfig(teacher=teacher)).validate(one)
    gate = TrainConfig(warm_start=WarmStartConfig(teacher="aoa", shadow_gate_db=1.0))
    assert gate.validate(one)
    with pytest.raises(ConfigError, match="single-UAV aoa teacher's"):
        gate.validate(fleet)
    with pytest.raises(ConfigError, match="compares frames: it needs memory >= 2"):
        gate.validate(EnvConfig(memory=1))


def test_budget_follows_the_episode_length() -> None:
    assert TrainConfig(episodes=4).total_timesteps(EnvConfig()) == 4 * 128
    assert TrainConfig(episodes=4).total_timesteps(EnvConfig(episode_frames=16)) == 64


def test_what_trains_is_the_budget_in_whole_rollouts() -> None:
    """SB3 collects whole rollouts (n_envs rows x n_steps), so 64 episodes of 128 envs train 128;
    `train` announces and counts that figure (before, it announced 8,192 steps and trained 16,384)."""
    env = EnvConfig()
    assert TrainConfig(episodes=64).trained_timesteps(env) == 128 * 128
    assert TrainConfig(episodes=256).trained_timesteps(env) == 256 * 128  # two whole rollouts
    fleet = EnvConfig(n_uavs=3, fleet_slots=3)
    sized = TrainConfig(episodes=100, n_envs=32, fleet_sizes_up_to=4)  # rows: 32 x (2 + 3 + 4)
    assert sized.total_timesteps(fleet) == 100 * 128 * 3
    assert sized.trained_timesteps(fleet) == 2 * 32 * 9 * 128


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    add_options(parser, TrainConfig)
    return parser


def _leaves(cls: type = TrainConfig, prefix: str = "") -> list[tuple[str, dataclasses.Field]]:
    out = []
    for f, hint in config_fields(cls):
        if dataclasses.is_dataclass(hint):
            out += _leaves(hint, f"{prefix}{f.name}.")
        else:
            out.append((prefix + f.name, f))
    return out


def test_every_field_has_a_flag_with_its_default_and_help() -> None:
    actions = {a.option_strings[0]: a for a in _parser()._actions if a.option_strings}
    defaults = TrainConfig()
    for path, f in _leaves():
        action = actions.pop(flag_of(TrainConfig, path))
        owner = defaults.warm_start if path.startswith("warm_start.") else defaults
        assert action.default == getattr(owner, f.name) and action.help.startswith(
            f.metadata["help"]
        ), path
    assert set(actions) == {"-h"}
    assert from_options(TrainConfig, _parser().parse_args([])) == TrainConfig()


def test_the_flags_of_today_keep_their_meaning() -> None:
    args = [
        "--episodes",
        "40",
        "--learning-rate",
        "1e-4",
        "--seed",
        "3",
        "--n-envs",
        "8",
        "--batch-size",
        "64",
        "--n-epochs",
        "2",
        "--torch-threads",
        "2",
        "--aoa-noise-max-deg",
        "30",
        "--warm-start",
        "aoa",
        "--warm-start-episodes",
        "16",
        "--warm-start-epochs",
        "5",
        "--warm-start-log-std",
        "-2",
        "--warm-start-shadow-gate-db",
        "1.5",
        "--warm-start-sinr-span-db",
        "4",
        "--warm-start-shadow-estimator-episodes",
        "32",
    ]
    tc = from_options(TrainConfig, _parser().parse_args(args)).validate()
    assert tc == TrainConfig(
        episodes=40,
        learning_rate=1e-4,
        seed=3,
        n_envs=8,
        batch_size=64,
        n_epochs=2,
        torch_threads=2,
        aoa_noise_max_deg=30.0,
        warm_start=WarmStartConfig("aoa", 16, 5, -2.0, 10, 1.5, 4.0, 32),
    )
    more = [
        "--net-arch",
        "64",
        "64",
        "--no-normalize-reward",
        "--gamma",
        "0.9",
        "--warm-start-critic-rollouts",
        "0",
    ]
    other = from_options(TrainConfig, _parser().parse_args(more)).validate()
    assert other == TrainConfig(
        net_arch=(64, 64),
        normalize_reward=False,
        gamma=0.9,
        warm_start=WarmStartConfig(critic_rollouts=0),
    )


def test_cli_refuses_bad_values_in_one_line(tmp_path: Path, capsys) -> None:
    out = tmp_path / "p.zip"
    for args, named in (
        (["--episodes", "0"], "--episodes must be positive"),
        (["--warm-start-sinr-span-db", "2"], "--warm-start-sinr-span-db needs --warm-start aoa"),
        (["--warm-start-dagger-rounds", "1"], "--warm-start-dagger-rounds needs a --warm-start"),
        (["--aoa-noise-deg", "10", "--aoa-noise-max-deg", "5"], "--aoa-noise-max-deg must be 0"),
        (["--set", "radio.aoa_noise_max_deg=5"], "set --aoa-noise-max-deg instead"),
        (["--eval-episodes", "-1"], "--eval-episodes must be >= 0"),
    ):
        assert main(["train", "--out", str(out), *args]) == 2
        err = capsys.readouterr().err
        assert err.startswith("uavlink train: error: ") and named in err and err.count("\n") == 1, (
            err
        )
    assert not out.exists()


def test_old_and_new_manifests_load() -> None:
    for policy in sorted((ROOT / "policies").glob("*.zip")):  # each manifest, not a sweep record
        hyper = json.loads(policy.with_suffix(".json").read_text())["training"]["hyperparameters"]
        tc = TrainConfig.from_dict(hyper).validate()  # flat warm_start_* keys, or none (mixed.json)
        assert (
            tc.warm_start.teacher == hyper.get("warm_start_teacher", "")
            and tc.episodes == hyper["episodes"]
        )
        assert TrainConfig.from_dict(tc.to_dict()) == tc
        assert tc.to_dict()["warm_start"]["log_std"] == hyper.get("warm_start_log_std", -1.0)
    with pytest.raises(ConfigError, match="train.frobnicate"):
        TrainConfig.from_dict({"frobnicate": 1})


def test_paper_hyperparameters_are_marked_on_the_fields() -> None:
    assert set(PAPER_HYPERPARAMETERS) == {
        "learning_rate",
        "net_arch",
        "gamma",
        "gae_lambda",
        "max_grad_norm",
        "clip_range",
        "episodes",
    }


def test_config_imports_nothing_from_the_layers_above() -> None:
    """``import uavlink.config`` (package __init__ included) loads config and errors only; the env
    package resolves its names lazily, so registering the Gymnasium id pulls in no layer above."""
    code = (
        "import sys, uavlink.config\n"
        "print(sorted(m for m in sys.modules if m.startswith('uavlink.')))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    loaded = eval(out.stdout)
    allowed = ("uavlink.config", "uavlink.errors", "uavlink.env", "uavlink.env.registration")
    assert loaded and all(m.startswith(allowed[:2]) or m in allowed for m in loaded), loaded


def test_warm_start_off_is_the_empty_default_and_not_offered_as_a_choice(capsys) -> None:
    """`--warm-start ''` (off, the default) parses; a wrong rule's error lists the rules only."""
    parser = argparse.ArgumentParser()
    add_options(parser, TrainConfig)
    assert (
        from_options(TrainConfig, parser.parse_args(["--warm-start", ""])).warm_start.teacher == ""
    )
    assert from_options(TrainConfig, parser.parse_args([])).warm_start.teacher == ""
    with pytest.raises(SystemExit):
        parser.parse_args(["--warm-start", "nope"])
    err = capsys.readouterr().err
    assert "invalid choice: 'nope' (choose from 'static'" in err and "''" not in err
