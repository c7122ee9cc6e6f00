"""A policy grown from another (uavlink/learn/policy_transfer.py): a map policy started from a shipped
spatial policy acts and values as that policy does, whatever its memory of place reads."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.fields import with_changes
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import ObservationLayout
from uavlink.errors import ConfigError, UserError

ROOT = Path(__file__).resolve().parents[1]
SPATIAL_HOTSPOT = ROOT / "policies" / "spatial" / "hotspot.zip"
MAP_ENV = EnvConfig(scenario="hotspot", place_cell_m=12.0).replace(
    **{"radio.shadowing_model": "spatial"}
)


def _ppo(cfg: EnvConfig):
    from uavlink.learn.training import make_model

    return make_model(cfg, TrainConfig(n_envs=2, n_steps=128, batch_size=64), None)


@pytest.mark.slow  # builds PPO and loads a policy (torch)
def test_a_map_policy_started_from_a_spatial_one_acts_and_values_as_it_does() -> None:
    import torch
    from stable_baselines3 import PPO

    from uavlink.learn.policy_transfer import start_from_policy

    model = _ppo(MAP_ENV)
    report = start_from_policy(model.policy, MAP_ENV, SPATIAL_HOTSPOT)
    source = PPO.load(SPATIAL_HOTSPOT, device="cpu").policy
    target, old = ObservationLayout.for_config(MAP_ENV), ObservationLayout.for_config(EnvConfig())
    assert report["inputs_kept"] == old.size and report["inputs_new"] == target.size - old.size > 0

    env = BatchedUavEnv(MAP_ENV, n_envs=16, seed=3)
    obs = env.reset()
    rng = np.random.default_rng(0)
    for _ in range(40):  # the memory fills: its fields read far from zero
        obs = env.step(rng.uniform(-1, 1, (16, 2))).observation
    names = target.feature_names()
    old_obs = obs[:, [names.index(n) for n in old.feature_names()]]
    assert np.abs(obs[:, [i for i, n in enumerate(names) if "place" in n]]).max() > 0.1
    with torch.no_grad():
        actions_new, values_new, _ = model.policy(torch.as_tensor(obs), deterministic=True)
        actions_old, values_old, _ = source(torch.as_tensor(old_obs), deterministic=True)
    np.testing.assert_allclose(actions_new.numpy(), actions_old.numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(values_new.numpy(), values_old.numpy(), rtol=1e-5, atol=1e-5)
    assert torch.equal(model.policy.log_std, source.log_std)  # no log_std given: the file's


@pytest.mark.slow
def test_a_start_policy_of_another_observation_is_refused_in_one_line() -> None:
    from uavlink.learn.policy_transfer import start_from_policy

    fleet = (
        ROOT / "policies" / "fleet_d2" / "hotspot.zip"
    )  # two UAVs' observation: not this env's minus fields
    with pytest.raises(
        UserError, match=r"warm_start.policy .*fleet_d2/hotspot.zip: its observation"
    ) as info:
        start_from_policy(_ppo(MAP_ENV).policy, MAP_ENV, fleet)
    assert "\n" not in str(info.value)


def test_a_start_policy_takes_no_teacher() -> None:
    with pytest.raises(ConfigError, match="warm_start.policy .* takes no train.warm_start.teacher"):
        with_changes(
            TrainConfig(), {"warm_start.policy": str(SPATIAL_HOTSPOT), "warm_start.teacher": "aoa"}
        ).validate(MAP_ENV)


def test_a_policy_started_from_weights_has_its_starts_teacher_and_says_whose() -> None:
    """The teacher column of the map table and of research/fleet_bars.py: a cloned rule is that rule;
    a start from a policy file is a stage of training, not a new teacher, so its teacher is the
    start's, named with the file it came through (followed back along the chain); a start file that
    copied no rule, or is not there, is named as the weights it gave; no warm start says so."""
    from types import SimpleNamespace

    from uavlink.learn.teachers import policy_teacher

    cfg = EnvConfig().replace(place_cell_m=12.0)
    fleet = EnvConfig(scenario="circular", n_uavs=2, fleet_slots=3)
    solo_start = ROOT / "policies" / "fleet_start" / "circular.zip"

    def policy(**warm_start) -> SimpleNamespace:
        tc = with_changes(TrainConfig(), {f"warm_start.{k}": v for k, v in warm_start.items()})
        return SimpleNamespace(manifest={"training": {"hyperparameters": tc.to_dict()}})

    teacher, label = policy_teacher(policy(policy=str(solo_start)), fleet)
    assert label == f"solo via {solo_start}" and type(teacher).__name__ == "SoloTeacher"
    missing = ROOT / "never.zip"
    assert policy_teacher(policy(policy=str(missing)), cfg) == (None, f"the weights of {missing}")
    no_rule = ROOT / "policies" / "mixed.zip"  # PPO from scratch: its chain ends in no rule
    assert policy_teacher(policy(policy=str(no_rule)), cfg) == (None, f"the weights of {no_rule}")
    teacher, label = policy_teacher(policy(teacher="explore"), cfg)
    assert label == "explore" and teacher.name == "explore"
    assert policy_teacher(policy(), cfg) == (None, "no warm start")
