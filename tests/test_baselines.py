"""Baselines and the simulator's calibration against the paper's static column (Table I).

The static column depends only on the radio and mobility models, so it calibrates the simulator.
To see the table:

    python -m pytest tests/test_baselines.py -s -k calibration
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from uavlink.config import BASELINE_NAMES, EnvConfig
from uavlink.env.core import BatchedUavEnv
from uavlink.env.observation import ObservationLayout
from uavlink.evaluation import EvalResult, evaluate_policy
from uavlink.mobility import SCENARIOS
from uavlink.policies.baselines import AoaPolicy
from uavlink.policies.registry import baseline_env, make_baseline

# Table I of the paper, "static" column (Mbps).
PAPER_STATIC = {
    "no_move": 7.95,
    "straight": 4.59,
    "circular": 3.59,
    "straight_90": 5.33,
    "straight_180": 5.31,
    "hotspot": 4.77,
}
STRAIGHT_FAMILY = ("straight", "straight_90", "straight_180")
CALIBRATION_EPISODES = 100
COMPARISON_EPISODES = 32  # paired comparisons: every policy meets the same UE trajectories
MOVING = ("straight", "circular", "straight_90", "hotspot")


def evaluate(policy: str, scenario: str, episodes: int, seed: int = 0) -> EvalResult:
    cfg = baseline_env(policy, EnvConfig(scenario=scenario))  # explore brings its memory of place
    return evaluate_policy(make_baseline(policy, cfg), cfg, episodes=episodes, seed=seed)


@pytest.fixture(scope="module")
def static_results() -> dict[str, EvalResult]:
    return {s: evaluate("static", s, CALIBRATION_EPISODES) for s in SCENARIOS}


@pytest.fixture(scope="module")
def paired() -> dict[str, dict[str, EvalResult]]:
    """Every baseline but the genie on the same seeded episodes of every scenario but no_move."""
    return {
        p: {s: evaluate(p, s, COMPARISON_EPISODES) for s in SCENARIOS if s != "no_move"}
        for p in BASELINE_NAMES
    }  # the genie has its own tests (tests/test_genie.py)


@pytest.mark.slow
def test_static_calibration_against_paper(static_results):
    lines = [
        "",
        f"static baseline, {CALIBRATION_EPISODES} episodes, seed 0 (Mbps)",
        f"| {'scenario':<13}| {'ours':>6} | {'±95%':>5} | {'paper':>5} | {'dev':>6} | {'check':<30} |",
        f"|{'-' * 14}|{'-' * 8}|{'-' * 7}|{'-' * 7}|{'-' * 8}|{'-' * 32}|",
    ]
    for scenario in SCENARIOS:
        ours, paper = static_results[scenario].mean_rate_mbps, PAPER_STATIC[scenario]
        check = "expected: see straight mean" if scenario == "straight" else "within 10 %"
        lines.append(
            f"| {scenario:<13}| {ours:6.3f} | {static_results[scenario].ci95_mbps:5.3f} | "
            f"{paper:5.2f} | {100 * (ours / paper - 1):+5.1f}% | {check:<30} |"
        )
    family = np.array([static_results[s].mean_rate_mbps for s in STRAIGHT_FAMILY])
    paper_family = np.mean([PAPER_STATIC[s] for s in STRAIGHT_FAMILY])
    lines.append(
        f"| {'straight mean':<13}| {family.mean():6.3f} | {'':>5} | {paper_family:5.2f} | "
        f"{100 * (family.mean() / paper_family - 1):+5.1f}% | {'3 straights: within 10 %':<30} |"
    )
    print("\n".join(lines))

    for scenario in SCENARIOS:
        if scenario == "straight":
            # EXPECTED DEVIATION. Our model gives ~5.1 Mbps for `straight`, the paper 4.59 (+11 %).
            # A UAV hovering at the centre sees the same distance-versus-time for `straight`,
            # `straight_90` and `straight_180`: every UE starts in the centre cluster and recedes
            # at 8 m/s whatever its direction, so the three static figures must agree. The paper's
            # straight (4.59) < straight_90 (5.33) contradicts that, so we check the symmetry and
            # the family's mean instead of `straight` alone.
            continue
        ours, paper = static_results[scenario].mean_rate_mbps, PAPER_STATIC[scenario]
        assert ours == pytest.approx(paper, rel=0.10), f"{scenario}: {ours:.3f} vs paper {paper}"
    assert family.max() / family.min() - 1 < 0.02, f"straight family disagrees: {family}"
    assert family.mean() == pytest.approx(paper_family, rel=0.10)


@pytest.mark.slow
def test_no_move_static_is_about_8_mbps(static_results):
    result = static_results["no_move"]
    assert 7.6 <= result.mean_rate_mbps <= 8.4
    assert result.episodes == CALIBRATION_EPISODES and len(result.episode_rate_mbps) == 100
    assert 0.0 < result.ci95_mbps < 0.5


@pytest.mark.slow
def test_circular_static_is_the_worst_moving_case(static_results):
    # The orbiting cluster stays ~195 m away: the lowest static throughput, as in the paper.
    rates = {s: r.mean_rate_mbps for s, r in static_results.items()}
    assert min(rates, key=rates.get) == "circular"
    assert max(rates, key=rates.get) == "no_move"


@pytest.mark.slow
@pytest.mark.parametrize("scenario", MOVING)
def test_oracle_beats_static_where_ues_move(paired, scenario):
    static, oracle = paired["static"][scenario], paired["oracle"][scenario]
    assert oracle.mean_rate_mbps > static.mean_rate_mbps + static.ci95_mbps
    # Paired episodes: the oracle is at least as good in (nearly) every single one.
    assert np.mean(oracle.episode_rate_mbps >= static.episode_rate_mbps - 0.01) > 0.9


@pytest.mark.slow
def test_oracle_hovers_on_straight_180(paired):
    # Two clusters leaving in opposite directions: hovering at the centre maximises R_fair, so the
    # oracle cannot beat static, and must not do worse.
    static, oracle = paired["static"]["straight_180"], paired["oracle"]["straight_180"]
    assert oracle.mean_rate_mbps >= static.mean_rate_mbps - static.ci95_mbps
    assert oracle.mean_rate_mbps == pytest.approx(static.mean_rate_mbps, rel=0.02)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["straight", "circular"])
def test_aoa_beats_static_and_stays_under_the_oracle(paired, scenario):
    static, aoa, oracle = (paired[p][scenario] for p in ("static", "aoa", "oracle"))
    assert aoa.mean_rate_mbps > 1.1 * static.mean_rate_mbps
    assert aoa.mean_rate_mbps < oracle.mean_rate_mbps + oracle.ci95_mbps


@pytest.mark.slow
def test_aoa_moves_while_shadowed_and_beats_static_on_no_move():
    """The SPEC's aoa rule speeds up as the SINRs fall below the hover level, so over a static cluster
    it keeps moving while the links are shadowed and stops when they are not; under the SPEC's
    memoryless AR(1) shadowing that re-draws bad shadow values and keeps good ones (docs/design/radio.md).
    Paired episodes: the gain is the rule's, not the draw's. Where the links start unshadowed the
    rule never moves, and that episode is exactly static's."""
    static, aoa = evaluate("static", "no_move", 48), evaluate("aoa", "no_move", 48)
    gain = aoa.episode_rate_mbps - static.episode_rate_mbps
    assert gain.mean() > 0.15 and (gain > 0).mean() > 0.3 and (gain < 0).mean() < 0.1
    assert (gain == 0).any()


def test_aoa_rule_is_the_specs_rule_without_teacher_knobs():
    """The SPEC's rule has no shadow gate, speed-span setting or privileged method (the warm start's
    variants are uavlink.learn.teachers)."""
    cfg = EnvConfig(scenario="straight_180")
    rule = AoaPolicy(cfg)
    assert (
        not rule.needs_truth
        and not hasattr(rule, "act_on_true_aoa")
        and not hasattr(rule, "shadow_gate_db")
    )
    with pytest.raises(TypeError):
        AoaPolicy(cfg, shadow_gate_db=1.0)


@pytest.mark.slow
def test_oracle_gain_is_large_where_the_paper_says(paired):
    # The paper's big PPO gains are on straight (+71 %) and circular (+97 %): the oracle's head room
    # over static must be large there, larger than on the two-cluster scenarios.
    gain = {
        s: paired["oracle"][s].mean_rate_mbps / paired["static"][s].mean_rate_mbps - 1
        for s in paired["static"]
    }
    assert gain["straight"] > 0.4 and gain["circular"] > 0.6
    assert min(gain["straight"], gain["circular"]) > max(gain["straight_90"], gain["straight_180"])


def test_evaluation_is_seeded_and_uses_common_random_numbers():
    cfg = EnvConfig(scenario="hotspot")
    a = evaluate_policy(make_baseline("aoa", cfg), cfg, episodes=3, seed=5, record_trajectory=True)
    b = evaluate_policy(make_baseline("aoa", cfg), cfg, episodes=3, seed=5, record_trajectory=True)
    c = evaluate_policy(make_baseline("aoa", cfg), cfg, episodes=3, seed=6)
    np.testing.assert_array_equal(a.episode_rate_mbps, b.episode_rate_mbps)
    assert not np.array_equal(a.episode_rate_mbps, c.episode_rate_mbps)
    # Another policy with the same seed meets the same UEs (its own flight differs).
    s = evaluate_policy(
        make_baseline("static", cfg), cfg, episodes=3, seed=5, record_trajectory=True
    )
    np.testing.assert_array_equal(s.trajectory.ue_xy_m, a.trajectory.ue_xy_m)
    assert not np.allclose(s.trajectory.uav_xy_m, a.trajectory.uav_xy_m)
    np.testing.assert_array_equal(s.trajectory.uav_xy_m, 0.0)  # static never leaves the centre
    assert a.trajectory.uav_xy_m.shape == (129, 1, 2) and a.trajectory.rate_mbps.shape == (128,)
    assert a.to_dict()["episode_rate_mbps"] == [round(float(x), 6) for x in a.episode_rate_mbps]


def test_oracle_needs_ground_truth_and_unknown_baseline_is_rejected():
    cfg = EnvConfig()
    with pytest.raises(ValueError, match="ground truth"):
        make_baseline("oracle", cfg).act(np.zeros((1, 60)), None)
    with pytest.raises(ValueError, match="unknown baseline 'kamikaze'"):
        make_baseline("kamikaze", cfg)
    with pytest.raises(ValueError, match="episodes must be a positive integer"):
        evaluate_policy(make_baseline("static", cfg), cfg, episodes=0)


def test_the_registry_holds_every_teacher_config_names_then_the_genie() -> None:
    """Config names the warm start's teachers without importing policies; the registry builds them."""
    from uavlink.policies.registry import BASELINES

    assert (*BASELINE_NAMES, "genie") == BASELINES


@pytest.mark.parametrize("name", [*BASELINE_NAMES, "genie"])
def test_every_rule_takes_a_single_observation_as_a_batch_of_one(name: str) -> None:
    """A Gymnasium env's observation (obs,) is a batch of one: actions (1, 2), as SB3Policy and
    OnnxPolicy return for it (``uavlink.policies.base.RulePolicy``)."""
    cfg = baseline_env(name, EnvConfig(scenario="straight", episode_frames=4))
    env = BatchedUavEnv(cfg, n_envs=1, seed=0)
    obs = env.reset()
    truth = env.ground_truth() if make_baseline(name, cfg).needs_truth else None
    one = make_baseline(name, cfg).act(obs[0], truth)
    batch = make_baseline(name, cfg).act(obs, truth)
    assert obs.shape == (
        1,
        ObservationLayout.for_config(cfg).size,
    ) and one.shape == batch.shape == (1, 2)
    np.testing.assert_array_equal(one, batch)


def test_a_teachers_variant_of_a_rule_takes_a_single_observation_too() -> None:
    from uavlink.learn.teachers import AoaVariant

    cfg = EnvConfig(scenario="straight")
    obs = BatchedUavEnv(cfg, n_envs=1, seed=0).reset()
    assert AoaVariant(cfg, shadow_gate_db=0.0).act(obs[0]).shape == (1, 2)
    fleet = cfg.replace(n_uavs=2)  # a fleet's (N D, obs) rows stay as they are
    rows = BatchedUavEnv(fleet, n_envs=1, seed=0).reset()
    assert rows.ndim == 2 and make_baseline("aoa", fleet).act(rows).shape == (2, 2)


@pytest.mark.slow
def test_a_rule_answers_a_single_observation_in_the_shape_sb3policy_does() -> None:
    from uavlink.policies.sb3_policy import SB3Policy

    policy = SB3Policy("policies/circular.zip")
    obs = np.zeros(policy.layout.size, np.float32)
    assert make_baseline("aoa", EnvConfig()).act(obs).shape == policy.act(obs).shape


def test_eval_result_says_each_field_and_r_fair_is_the_sum_of_log10_rates() -> None:
    doc = EvalResult.__doc__
    for field in dataclasses.fields(EvalResult):
        assert f"``{field.name}``" in doc, field.name
    assert "Mbit/s" in doc and "log10" in doc and "bit/s" in doc
    cfg = EnvConfig(scenario="hotspot", episode_frames=3)
    env = BatchedUavEnv(cfg, n_envs=2, seed=0)
    env.reset()
    fair = [env.step(np.zeros((2, 2))).fair_rate for _ in range(3)]
    np.testing.assert_allclose(fair[-1], np.log10(env.readings.rate_bps).sum(axis=1))
    result = evaluate_policy(make_baseline("static", cfg), cfg, episodes=2, seed=0)
    np.testing.assert_allclose(result.episode_fair_rate, np.mean(fair, axis=0))
    assert result.mean_fair_rate == pytest.approx(np.mean(fair))
