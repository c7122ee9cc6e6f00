"""The model of the sensed field (uavlink/env/field_model.py), its layout v5, and the kriging rule."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.env import field_model
from uavlink.env.field_model import FieldModel
from uavlink.env.observation import KRIGING_LAYOUT_VERSION, ObservationLayout
from uavlink.errors import ConfigError, UserError
from uavlink.evaluation import evaluate_policy
from uavlink.evaluation.core import paired_ratio_ci
from uavlink.policies.registry import baseline_env, make_baseline

SPATIAL = EnvConfig(scenario="no_move").replace(**{"radio.shadowing_model": "spatial"})
KRIGING = SPATIAL.replace(place_cell_m=12.0, place_model="kriging")


def _batch_posterior(
    x: np.ndarray, y: np.ndarray, spots: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The textbook GP posterior (Rasmussen & Williams eq. 2.25-2.26) with the model's covariance."""

    def cov(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(a[:, None] - b[None], axis=-1)
        return (
            field_model.SIGMA_BITS**2 * np.exp(-d / field_model.DECORRELATION_M)
            + field_model.MEAN_SIGMA_BITS**2
        )

    k = cov(x, x) + field_model.NUGGET_BITS**2 * np.eye(len(x))
    ks = cov(x, spots)
    mean = ks.T @ np.linalg.solve(k, y)
    var = cov(spots[:1], spots[:1])[0, 0] - np.einsum("nk,nk->k", ks, np.linalg.solve(k, ks))
    return mean, var


def test_the_incremental_posterior_is_the_textbook_one_row_by_row() -> None:
    rng = np.random.default_rng(0)
    model = FieldModel(n_rows=3, horizon_frames=20, r_max_m=12.0, half_width_m=200.0)
    model.reset()
    x = rng.uniform(-100, 100, (3, 12, 2))
    x[:, 5] = x[:, 4]  # a hover: the same spot twice
    y = rng.normal(5.0, 1.5, (3, 12))
    for t in range(12):
        model.update(x[:, t], y[:, t])
    for row in range(3):
        mean, var = _batch_posterior(x[row], y[row], model.spots_m)
        np.testing.assert_allclose(model.mean[row], mean, atol=1e-8)
        np.testing.assert_allclose(model.var[row], var, atol=1e-8)


def test_observations_from_other_places_pool_into_the_posterior_without_a_decision() -> None:
    """``observe`` (a listening UAV's reading) joins the posterior as one more observation: the
    textbook posterior of every reading, whichever place sensed it, and the frame count moves with
    the deciding UAV's updates alone; the model holds ``sensors`` readings a frame."""
    rng = np.random.default_rng(1)
    model = FieldModel(n_rows=2, horizon_frames=6, r_max_m=12.0, half_width_m=200.0, sensors=3)
    model.reset()
    x, y = rng.uniform(-100, 100, (2, 21, 2)), rng.normal(5.0, 1.5, (2, 21))
    for t in range(7):
        model.observe(x[:, 3 * t + 1], y[:, 3 * t + 1])
        model.observe(x[:, 3 * t + 2], y[:, 3 * t + 2])
        model.update(x[:, 3 * t], y[:, 3 * t])
    assert (model.frames, model.observed) == (7, 21)
    for row in range(2):
        order = np.concatenate([[3 * t + 1, 3 * t + 2, 3 * t] for t in range(7)])
        mean, var = _batch_posterior(x[row, order], y[row, order], model.spots_m)
        np.testing.assert_allclose(model.mean[row], mean, atol=1e-8)
        np.testing.assert_allclose(model.var[row], var, atol=1e-8)
    full = model.mean.copy()
    model.observe(x[:, 0], y[:, 0] + 3.0)  # past its room: the model is full and unchanged
    np.testing.assert_array_equal(model.mean, full)


def test_the_pick_looks_far_early_and_stays_on_a_known_good_spot_late() -> None:
    model = FieldModel(n_rows=1, horizon_frames=128, r_max_m=12.0)
    model.reset()
    q = model.update(np.zeros((1, 2)), np.array([4.0]))
    assert np.hypot(*q["place_pick_offset_m"][0]) > 12.0  # nothing known: a look away pays
    model.reset()
    for t in range(1, 128):  # late in the episode, on a good spot after poorer ones around it
        here = np.array([[0.0, 0.0]]) if t % 2 else np.array([[30.0 * np.cos(t), 30.0 * np.sin(t)]])
        q = model.update(here, np.array([8.0 if t % 2 else 4.0]))
    assert np.hypot(*q["place_pick_offset_m"][0]) <= field_model.SPACING_M
    assert q["place_pick_std_bits"][0] < field_model.SIGMA_BITS


def test_layout_v5_is_recorded_and_older_records_are_unchanged() -> None:
    layout = ObservationLayout.for_config(KRIGING)
    assert layout.version == KRIGING_LAYOUT_VERSION
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    assert {"place_model", "episode_frames", "r_max_m"} <= set(layout.to_dict())
    v3 = ObservationLayout.for_config(SPATIAL.replace(place_cell_m=12.0))
    assert v3.version == 3 and not {"place_model", "episode_frames", "r_max_m"} & set(v3.to_dict())
    assert layout.frame_size == v3.frame_size + 4
    assert layout.feature_names()[v3.frame_size : layout.frame_size] == [
        "t-0:place_pick_dx",
        "t-0:place_pick_dy",
        "t-0:place_pick_gain",
        "t-0:place_pick_std",
    ]


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"place_model": "gp"}, "unknown place_model"),
        ({"place_model": "kriging"}, "place_cell_m > 0"),
        ({"place_model": "kriging", "place_cell_m": 12.0, "n_uavs": 2}, "fleet_slots > 0"),
        ({"place_model": "pooled", "place_cell_m": 12.0}, "models a fleet's field"),
        ({"place_model": "pooled", "n_uavs": 2, "fleet_slots": 1}, "place_cell_m > 0"),
        ({"fleet_reuse": "solo"}, "unknown fleet_reuse"),
    ],
)
def test_bad_place_models_are_refused_in_one_line(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        SPATIAL.replace(**changes).validate()


def test_the_kriging_rule_refuses_a_fleet() -> None:
    with pytest.raises((UserError, ConfigError)):
        make_baseline("kriging", SPATIAL.replace(n_uavs=2))


def test_the_kriging_rule_beats_explore_on_no_move() -> None:
    """The model's point: it finds better spots than explore's fixed cross (seed 1, the validation
    episodes the constants were chosen on, so this guards the code, not the choice)."""
    kriging = evaluate_policy(
        make_baseline("kriging", SPATIAL), baseline_env("kriging", SPATIAL), 16, seed=1
    )
    explore = evaluate_policy(
        make_baseline("explore", SPATIAL), baseline_env("explore", SPATIAL), 16, seed=1
    )
    ratio, low, _ = paired_ratio_ci(kriging.episode_rate_mbps, explore.episode_rate_mbps)
    assert low > 1.0, ratio


def test_the_shipped_no_move_map_policy_sees_the_model_and_its_teacher_is_the_kriging_rule() -> (
    None
):
    """The report's "map vs its teacher" column flies the kriging rule for it, in its own env."""
    from support.cli import ROOT

    from uavlink.learn.teachers import policy_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env

    [(policy, cfg)] = load_with_env(
        [str(ROOT / "policies" / "map" / "no_move.zip")], EnvOverrides()
    )
    assert ObservationLayout.for_config(cfg).version == KRIGING_LAYOUT_VERSION
    teacher, label = policy_teacher(policy, cfg)
    assert label == "kriging" and teacher.name == "kriging"
    assert teacher.layout == ObservationLayout.for_config(cfg)  # reads the policy's observation
