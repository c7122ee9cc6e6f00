"""The warm start's teachers (uavlink/learn/teachers.py): the aoa rule's variants (speed span, shadow gate
on the SINR jump or on an estimate) and the privileged teacher that flies a rule on the true AoAs."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.evaluation import evaluate_policy
from uavlink.learn.teachers import AoaVariant, TrueAoaTeacher, make_teacher
from uavlink.policies.baselines import AoaPolicy, StaticPolicy
from uavlink.policies.registry import make_baseline
from uavlink.radio.aoa import circular_mean_std_deg, true_aoa_deg

CFG = EnvConfig(scenario="hotspot")


def test_aoa_shadow_gate_hovers_after_a_lucky_frame_only():
    """The gate (ours, not the SPEC's rule) replaces the rule's move by hover exactly where the
    newest frame's mean SINR beats the mean of the older frames by more than the gate."""
    cfg = EnvConfig(scenario="straight_180")
    plain, gated = AoaPolicy(cfg), AoaVariant(cfg, shadow_gate_db=1.0)
    layout = plain.layout
    env = BatchedUavEnv(cfg, n_envs=64, seed=5)
    obs = env.reset()
    for _ in range(6):
        obs = env.step(plain.act(obs)).observation
    mean_db = layout.sinr_db_history(obs).mean(axis=2)
    lucky = mean_db[:, 0] > mean_db[:, 1:].mean(axis=1) + 1.0
    assert 0 < lucky.sum() < len(lucky)  # both cases occur in this batch
    np.testing.assert_array_equal(gated.act(obs)[lucky], 0.0)
    np.testing.assert_array_equal(gated.act(obs)[~lucky], plain.act(obs)[~lucky])
    np.testing.assert_array_equal(AoaVariant(cfg).act(obs), plain.act(obs))  # no setting: the rule
    with pytest.raises(ValueError, match="memory >= 2"):
        AoaVariant(cfg.replace(memory=1), shadow_gate_db=0.0)


@pytest.mark.slow
def test_aoa_shadow_gate_beats_the_plain_rule_on_straight_180():
    """Two groups drifting apart: the plain rule moves at full speed all the time (its SINRs stay far
    below the hover level), the gated one keeps good shadowing draws (docs/design/learning.md). Paired episodes."""
    cfg = EnvConfig(scenario="straight_180")
    plain = evaluate_policy(AoaPolicy(cfg), cfg, episodes=32, seed=1)
    gated = evaluate_policy(AoaVariant(cfg, shadow_gate_db=0.0), cfg, episodes=32, seed=1)
    assert gated.mean_rate_mbps > plain.mean_rate_mbps + 0.02
    assert gated.mean_fair_rate > plain.mean_fair_rate


class FixedEstimate:
    """A unit's edge: an estimate that says what the test wants."""

    def __init__(self, values_db: np.ndarray) -> None:
        self.values_db = values_db

    def predict_db(self, obs: np.ndarray) -> np.ndarray:
        return self.values_db


def test_rule_hovers_where_the_estimate_is_above_the_gate() -> None:
    env = BatchedUavEnv(CFG, n_envs=4, seed=1)
    obs = env.reset()
    plain = AoaPolicy(CFG).act(obs)
    gated = AoaVariant(
        CFG, shadow_gate_db=2.0, shadow_estimator=FixedEstimate(np.array([5.0, 2.0, -1.0, 2.5]))
    )
    assert not gated.needs_truth  # an estimate from the observation: still GPS-free
    np.testing.assert_array_equal(gated.act(obs)[[0, 3]], np.tile(AoaPolicy(CFG).hover, (2, 1)))
    np.testing.assert_array_equal(gated.act(obs)[[1, 2]], plain[[1, 2]])
    with pytest.raises(ValueError, match="threshold"):
        AoaVariant(CFG, shadow_estimator=FixedEstimate(np.zeros(4)))


def test_true_aoa_teacher_reads_the_true_aoa_under_noise() -> None:
    """Privileged teacher: with 100 degrees of AoA noise the observation's AoA mean is garbage, but the
    teacher flies towards the UEs' true circular-mean AoA (at the speed the SINRs ask for), and says
    that it reads ground truth."""
    noisy = CFG.replace(aoa_noise_deg=100.0)
    env = BatchedUavEnv(noisy, n_envs=16, seed=3)
    rule, teacher = make_baseline("aoa", noisy), make_teacher(noisy, "aoa")
    assert isinstance(teacher, TrueAoaTeacher) and teacher.needs_truth and teacher.name == "aoa"
    env.reset()
    for _ in range(20):  # let the UEs spread out from the UAV
        obs = env.step(np.zeros((16, 2), np.float32)).observation
    truth = env.ground_truth()
    true_mean, _ = circular_mean_std_deg(true_aoa_deg(truth.uav_xy_m[:, None, :], truth.ue_xy_m))
    action = teacher.act(obs, truth)
    angle, distance = rule.mapping.to_polar(action)
    moving = distance > 0.5
    assert moving.sum() >= 8
    np.testing.assert_allclose(np.cos(np.radians(angle - true_mean))[moving], 1.0, atol=1e-4)
    assert np.abs(action - rule.act(obs)).max() > 0.1  # the rule on the noisy observation differs
    with pytest.raises(ValueError, match="ground truth"):
        teacher.act(obs, None)


def test_make_teacher_builds_what_train_config_names() -> None:
    cfg = EnvConfig(scenario="straight_180")
    assert isinstance(make_teacher(cfg, "static"), StaticPolicy)  # other baselines fly as they are
    variant = make_teacher(cfg, "aoa", shadow_gate_db=0.5, sinr_span_db=3.0).rule
    assert isinstance(variant, AoaVariant) and (variant.shadow_gate_db, variant.sinr_span_db) == (
        0.5,
        3.0,
    )
    assert make_teacher(cfg, "aoa", shadow_gate_db=0.5).rule.sinr_span_db == AoaPolicy.sinr_span_db
    for setting in ({"shadow_gate_db": 0.0}, {"sinr_span_db": 2.0}):
        with pytest.raises(ValueError, match="needs train.warm_start.teacher aoa"):
            make_teacher(cfg, "static", **setting)
    with pytest.raises(ValueError, match="needs the gate's threshold"):
        make_teacher(cfg, "aoa", shadow_estimator=object())
    with pytest.raises(ValueError, match="unknown teacher 'gps'"):
        make_teacher(cfg, "gps")


def test_a_fleets_aoa_teacher_takes_a_speed_span_only() -> None:
    """The fleet aoa rule with a shorter span reaches full speed nearer the hover SINR: it moves at
    least as far as the rule, farther where a cell sits between the two spans (ours: hotspot's teacher)."""
    from uavlink.policies.fleet_baselines import FleetAoaPolicy

    cfg = EnvConfig(scenario="hotspot", n_uavs=2)
    short, rule = make_teacher(cfg, "aoa", sinr_span_db=5.0), make_baseline("aoa", cfg)
    assert isinstance(short, FleetAoaPolicy) and short.sinr_span_db == 5.0
    obs = BatchedUavEnv(cfg, n_envs=32, seed=2).reset()
    far_short, far_rule = (
        short.mapping.to_polar(short.act(obs))[1],
        rule.mapping.to_polar(rule.act(obs))[1],
    )
    assert (far_short >= far_rule - 1e-9).all() and (far_short > far_rule + 0.1).any()
    with pytest.raises(ValueError, match="single-UAV aoa teacher's"):
        make_teacher(cfg, "aoa", shadow_gate_db=1.0)


def test_the_spread_teachers_distance_is_a_warm_start_setting() -> None:
    """``warm_start.spread_m`` builds the spread rule aiming that far from the other groups, names
    it in the teacher's label when rebuilt from a manifest, and is refused for any other teacher."""
    from uavlink.config import TrainConfig
    from uavlink.learn.teachers import SpreadTeacher, _manifest_teacher

    cfg = EnvConfig(scenario="hotspot", n_uavs=3)
    assert make_teacher(cfg, "spread").spread_m == 20.0
    assert make_teacher(cfg, "spread", spread_m=40.0).spread_m == 40.0
    manifest = {
        "training": {"hyperparameters": {"warm_start": {"teacher": "spread", "spread_m": 40}}}
    }
    teacher, label = _manifest_teacher(manifest, cfg, via=())
    assert isinstance(teacher, SpreadTeacher) and teacher.spread_m == 40.0
    assert label == "spread (spread_m 40)"
    wider = evaluate_policy(teacher, cfg, episodes=4, seed=1)
    rule = evaluate_policy(make_teacher(cfg, "spread"), cfg, episodes=4, seed=1)
    assert wider.mean_rate_mbps != rule.mean_rate_mbps  # another rule, not the default's
    with pytest.raises(ValueError, match="spread_m needs train.warm_start.teacher spread"):
        TrainConfig.from_dict({"warm_start": {"teacher": "kmeans", "spread_m": 40}}).validate()
