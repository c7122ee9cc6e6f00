"""The research scripts under research/ that stand behind figures in README, the design pages (docs/design/) and
the experiment log (research/log/) run end to end (tiny budgets, each script's main in this
process) and keep the properties their figures rely on.

Their own lane, off `make test`'s critical path: `make research-test` (or `pytest research/tests`);
the suite's default paths (`testpaths = ["tests"]`) do not reach this folder, and every test here is
marked `research` (and `slow`) for runs that name it."""

from __future__ import annotations

import contextlib
import importlib
import io
import json
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.research, pytest.mark.slow]  # experiment scripts, some training

ROOT = Path(__file__).resolve().parents[2]
FOLDER = ROOT / "research"


def run_main(script: str, *args: str) -> str:
    """``python research/SCRIPT ARGS``: the script's ``main`` run whole in this process (without a
    child's torch and SB3 import: ~8 s each on a loaded 2-core machine); what it printed."""
    sys.path.insert(0, str(FOLDER))  # as for a script: its siblings are importable
    try:
        main = runpy.run_path(str(FOLDER / script), run_name=Path(script).stem)["main"]
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main(list(args)) == 0
    finally:
        sys.path.remove(str(FOLDER))
    return out.getvalue()


def run_json(script: str, *args: str) -> dict:
    """``python research/SCRIPT ARGS --json``, its JSON read (:func:`run_main`)."""
    return json.loads(run_main(script, *args, "--json"))


def research_module(name: str):
    """The research script ``name`` imported as a module (its siblings importable, as for a script)."""
    sys.path.insert(0, str(FOLDER))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(FOLDER))


def test_residual_ppo_starts_as_the_rule_and_trains() -> None:
    result = run_json(
        "residual_ppo.py",
        "--scenarios",
        "hotspot",
        "--train-episodes",
        "8",
        "--n-envs",
        "8",
        "--batch-size",
        "256",
        "--episodes",
        "6",
    )
    row = result["scenarios"]["hotspot"]
    # Before any update the action head outputs ~1e-3 of a full move: the policy is the rule.
    assert abs(row["residual_before"]["mbps"] - row["aoa"]["mbps"]) < 0.01
    assert abs(row["residual_before"]["r_fair"] - row["aoa"]["r_fair"]) < 0.01
    assert np.isfinite(row["residual_after"]["mbps"]) and row["train_wall_s"] > 0


def test_residual_composition_stays_a_legal_move() -> None:
    compose = research_module("residual_ppo").compose
    rule = np.array([[0.6, 0.8], [0.0, 0.0], [0.3, 0.0]])
    residual = np.array([[0.6, 0.8], [0.5, -0.25], [3.0, 0.0]])  # the last is clipped to 1.0
    action = compose(rule, residual)
    np.testing.assert_allclose(
        action[0], [0.6, 0.8], atol=1e-7
    )  # same direction, cut to a full move
    np.testing.assert_allclose(action[1], [0.5, -0.25], atol=1e-7)  # inside the disc: unchanged
    np.testing.assert_allclose(action[2], [1.0, 0.0], atol=1e-7)
    assert np.all(np.hypot(action[:, 0], action[:, 1]) <= 1.0 + 1e-6)


def test_teacher_search_compares_variants_with_the_rule_and_picks_one_that_loses_no_throughput() -> (
    None
):
    result = run_json(
        "aoa_teacher_search.py",
        "--scenarios",
        "straight_180",
        "--episodes",
        "8",
        "--spans-db",
        "10",
        "4",
        "--jump-gates-db",
        "0",
        "--estimate-gates-db",
        "1",
        "--estimator-episodes",
        "16",
        "--clone",
        "4x2",
    )
    row = result["scenarios"]["straight_180"]
    assert len(row["variants"]) == 6 and {v["gate_on"] for v in row["variants"]} == {
        "off",
        "jump",
        "estimate",
    }
    assert 0.0 < row["shadow_estimator_r2"] < 1.0
    baseline = next(v for v in row["variants"] if v["sinr_span_db"] == 10 and v["gate_on"] == "off")
    assert baseline["d_r_fair"] == [0.0, 0.0] and baseline["d_mbps_pct"] == [
        0.0,
        0.0,
    ]  # the rule itself
    assert (baseline["mbps"], baseline["r_fair"]) == (row["rule"]["mbps"], row["rule"]["r_fair"])
    gaining = [v for v in row["variants"] if v["d_mbps_pct"][0] - v["d_mbps_pct"][1] > 0.0]
    pick = row[
        "pick"
    ]  # with these settings a variant gains, so there is a pick (and its clone below)
    assert (
        gaining
        and pick in gaining
        and all(pick["d_r_fair"][0] >= v["d_r_fair"][0] for v in gaining)
    )
    assert set(row["true_shadow_gate_mbps_r_fair"]) == {"0", "1.5", "3", "4.5"}
    (clone,) = row["clones_of_pick"]
    assert (clone["teacher_episodes"], clone["epochs"]) == (4, 2) and np.isfinite(clone["mbps"])


@pytest.mark.slow
def test_map_sensitivity_puts_every_policy_over_static_on_each_channel() -> None:
    """research/map_sensitivity.py on no_move, 2 episodes: a row per (sigma, UAV-end
    decorrelation), the genie above static on every channel (it knows the field), each ratio
    inside its interval."""
    result = run_json("map_sensitivity.py", "--scenarios", "no_move", "--episodes", "2")
    assert [(r["shadowing_std_db"], r["uav_decorrelation_m"]) for r in result["rows"]] == [
        (s, d) for s in (4.0, 8.0) for d in (25.0, 50.0, 100.0)
    ]
    for row in result["rows"]:
        assert row["genie"]["over_static"] > 1, row
        for name in ("genie", "explore", "map", "spatial"):
            lo, hi = row[name]["ci95"]
            assert lo <= row[name]["over_static"] <= hi, row
    # a larger sigma leaves more to find: the genie's gain grows with it at every decorrelation
    by_cell = {
        (r["shadowing_std_db"], r["uav_decorrelation_m"]): r["genie"]["over_static"]
        for r in result["rows"]
    }
    assert all(by_cell[(8.0, d)] > by_cell[(4.0, d)] for d in (25.0, 50.0, 100.0))


@pytest.mark.slow
def test_genie_reach_keeps_each_plan_within_its_radius_below_the_next() -> None:
    """research/genie_reach.py on no_move, 2 episodes: a plan kept nearer the team is never better
    than one kept less near (the grids' cells are a superset), and none beats the genie."""
    result = run_json("genie_reach.py", "--scenarios", "no_move", "--episodes", "2")
    [row] = result["rows"]
    shares = [row["shares"][f"within {r:g} m"]["of_genie"] for r in result["radii_m"]]
    assert all(a <= b + 1e-6 for a, b in zip(shares, [*shares[1:], 1.0], strict=True)), shares
    assert shares[0] > 0 and row["genie_mbps"] > 0 and row["genie_mean_distance_from_team_m"] > 0
    for name in ("explore", "map", "spatial"):
        assert 0 < row["shares"][name]["of_genie"] <= 1.0, row["shares"][name]


def test_memory_worth_scores_the_remembered_spot_now_and_a_still_team_keeps_its_word(
    tmp_path: Path,
) -> None:
    """research/memory_worth.py, 3 episodes: where the team stands still a spot reads now what it
    read then (claimed == now, the SPEC's "identical value on return"); where it moves, what the whole
    episode's memory claims is more than its pick is worth now. --plot draws the figure."""
    figure = tmp_path / "memory_worth.png"
    result = run_json(
        "memory_worth.py",
        "--scenarios",
        "no_move",
        "straight",
        "--episodes",
        "3",
        "--plot",
        str(figure),
    )
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    still, moving = result["rows"]
    for row in (still, moving):
        for w in result["windows_frames"]:
            assert (
                row["windows"][str(w)]["claimed"]["ratio"] >= 1.0
            )  # the best of a window includes now
    for w in result["windows_frames"]:
        assert still["windows"][str(w)]["claimed"] == still["windows"][str(w)]["now"]
    whole = moving["windows"][str(max(result["windows_frames"]))]
    assert whole["now"]["ratio"] < whole["claimed"]["ratio"] and whole["mean_age_frames"] > 4


@pytest.mark.slow
def test_teacher_gain_rebuilds_each_policys_own_teacher_from_its_manifest() -> None:
    """research/teacher_gain.py: the map policy of straight_90 faces the aoa variant its manifest
    names (span 3 dB, gate 2 dB), no_move's the kriging rule; the gain is the ratio of the two."""
    result = run_json(
        "teacher_gain.py",
        str(ROOT / "policies" / "map" / "straight_90.zip"),
        str(ROOT / "policies" / "map" / "no_move.zip"),
        "--episodes",
        "3",
    )
    teachers = {row["scenario"]: row["teacher"] for row in result["rows"]}
    assert teachers == {"straight_90": "aoa (span 3, gate 2)", "no_move": "kriging"}
    for row in result["rows"]:
        lo, hi = row["ci95"]
        assert lo <= row["gain"] <= hi and row["beats_teacher"] == (lo > 0)
        assert abs(row["ppo_mbps"] / row["teacher_mbps"] - 1 - row["gain"]) < 1e-3


def test_explore_search_pairs_every_variant_with_explore_and_the_spatial_policy() -> None:
    result = run_json("explore_search.py", "--episodes", "4", "--cell-m", "12")
    rows = result["rows"]
    assert [r["variant"] for r in rows][0] == "explore" and len(rows) > 1
    assert rows[0]["mean_rate_mbps"] == pytest.approx(
        result["explore_mbps"], abs=1e-4
    )  # 12 m: the baseline
    for row in rows:
        for ref in ("vs_explore", "vs_spatial"):
            ratio, low, high = row[ref]
            assert low <= ratio <= high


def test_kriging_search_flies_the_chosen_rule_and_restores_the_model_s_optimism() -> None:
    """Its row at the chosen constants is `uavlink evaluate --policy kriging` on the same episodes;
    a varied beta is put back after the run (the script patches the model's module constant)."""
    from uavlink.env import field_model
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    result = run_json(
        "kriging_search.py", "--episodes", "3", "--seed", "0", "--beta", str(field_model.BETA), "1"
    )
    [(rule, cfg)] = load_with_env(
        ["kriging"],
        EnvOverrides.from_command_line("no_move", None, ["radio.shadowing_model=spatial"]),
    )
    chosen = evaluate_policy(
        rule, cfg, 3, 0
    ).mean_rate_mbps  # after the run: beta 1 was the last tried
    assert [r["beta"] for r in result["rows"]] == [field_model.BETA, 1.0]
    assert result["rows"][0]["mean_rate_mbps"] == pytest.approx(chosen, abs=1e-4)
    assert result["rows"][1]["mean_rate_mbps"] != result["rows"][0]["mean_rate_mbps"]
    for row in result["rows"]:
        for ref in ("vs_explore", "vs_spatial"):
            ratio, low, high = row[ref]
            assert low <= ratio <= high


@pytest.mark.timeout(300)
def test_spiral_ppo_trains_from_the_spiral_rule_and_pairs_it_with_the_spatial_policy() -> None:
    result = run_json("spiral_ppo.py", "--seeds", "0", "--train-episodes", "256", "--episodes", "2")
    assert [(r["motion"], r["policy"]) for r in result["rows"]] == [
        ("instant", "rule"),
        ("instant", "PPO seed 0"),
        ("px4", "rule"),
        ("px4", "PPO seed 0"),
    ]
    for row in result["rows"]:
        ratio, low, high = row["vs_spatial"]
        assert low <= ratio <= high


def test_map_table_gives_every_map_policy_and_mixed_its_row_as_json() -> None:
    result = run_json("map_table.py", "--episodes", "2", "--no-genie")
    scenarios = [row["scenario"] for row in result["rows"]]
    assert sorted(scenarios) == sorted(p.stem for p in (ROOT / "policies" / "map").glob("*.zip"))
    assert scenarios[-1] == "mixed" and result["episodes"] == 2
    assert all(
        "genie" not in row and row["map vs spatial PPO"].endswith("]") for row in result["rows"]
    )


def test_clone_gap_fits_then_adds_dagger_rounds_and_flies_each_copy() -> None:
    result = run_json(
        "clone_gap.py",
        "--sweep",
        str(ROOT / "sweeps" / "map.toml"),
        "--scenario",
        "straight_90",
        "--rounds",
        "1",
        "--epochs",
        "2",
        "--clone-episodes",
        "2",
        "--episodes",
        "3",
        "--policy",
        str(ROOT / "policies" / "map" / "straight_90.zip"),
    )
    stages = [row["stage"] for row in result["rows"]]
    assert stages == [
        "clone",
        "dagger 1",
        f"policy {ROOT / 'policies' / 'map' / 'straight_90.zip'}",
    ]
    clone, dagger, policy = result["rows"]
    assert (
        dagger["samples"] == 2 * clone["samples"] == 2 * 2 * 128
    )  # the copy's flying added to the teacher's
    assert clone["mbps"] != dagger["mbps"] or clone["mse"] != dagger["mse"]  # refitted
    for row in result["rows"]:
        lo, hi = row["ci95"]
        assert lo <= row["vs_teacher"] <= hi
    assert policy["mbps"] > 0 and result["teacher_mbps"] > 0


def test_fleet_bars_pair_every_size_with_kmeans_and_d2_with_the_teacher_and_the_per_size_policy() -> (
    None
):
    """research/fleet_bars.py: each shipped any-size policy at D = 2, 3, 4 against kmeans on the same
    episodes; at D = 2 also against its manifest's teacher and the per-size D = 2 policy."""
    result = run_json("fleet_bars.py", "--episodes", "2", "--seed", "3")
    rows = result["rows"]
    assert [(r["scenario"], r["n_uavs"]) for r in rows] == [
        (s, d)
        for s in ("no_move", "straight", "circular", "straight_90", "straight_180", "hotspot")
        for d in (2, 3, 4)
    ]
    for row in rows:
        r, lo, hi = row["vs_kmeans"]
        assert lo <= r <= hi and abs(r - row["ppo_mbps"] / row["kmeans_mbps"]) < 1e-3
        assert ("vs_teacher" in row) == ("vs_per_size" in row) == (row["n_uavs"] == 2)
    teachers = {r["scenario"]: r["teacher"] for r in rows if r["n_uavs"] == 2}
    assert teachers["no_move"] == "lead" and teachers["straight_90"] == "kmeans"
    alone = run_json("fleet_bars.py", "--episodes", "2", "--seed", "3", "--scenario", "hotspot")
    assert alone["rows"] == [r for r in rows if r["scenario"] == "hotspot"]


def test_fleet_input_sensitivity_evaluates_the_same_episodes_from_float64_and_float32_inputs() -> (
    None
):
    result = run_json("fleet_input_sensitivity.py", "--episodes", "1", "--seed", "1")
    assert result["n_uavs"] == 3 and result["scenario"] == "hotspot"
    assert result["float64_mbps"] > 0 and result["float32_inputs_mbps"] > 0
    change = abs(result["float32_inputs_mbps"] / result["float64_mbps"] - 1) * 100
    assert abs(change - result["per_episode_abs_change_pct"]) < 1e-2  # one episode: the same


@pytest.mark.parametrize("path", sorted((FOLDER / "sweeps").glob("*.toml")), ids=lambda p: p.name)
def test_research_sweep_files_load_and_name_their_own_runs(path: Path) -> None:
    """research/sweeps/: the log's sweep recipes (not shipped: benchmarks/train_throughput.py
    measures sweeps/ alone) still load with today's configs, and the command in each file's
    comment names the file where it now lies."""
    from uavlink.sweep.sweep_file import load_spec

    spec = load_spec(path)
    assert spec.name == path.stem and len(spec.jobs()) == len(spec.scenarios) * len(spec.seeds)
    assert f"uavlink sweep research/sweeps/{path.name}" in path.read_text()


def test_cell_teacher_shows_each_uav_its_own_cells_ues_and_pairs_the_rule_with_kmeans() -> None:
    """research/cell_teacher.py: the single-UAV view holds only the SINRs of the UEs this UAV
    serves (all of them for an empty cell), and each row flies the rule, kmeans and the fleet
    policy on the same episodes."""
    CellTeacher = research_module("cell_teacher").CellTeacher
    from uavlink.env.core import BatchedUavEnv
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.loader import load_policy

    [(_, cfg)] = load_with_env(["policies/fleet/straight_180.zip"], EnvOverrides())
    single = cfg.replace(n_uavs=1, fleet_slots=0).validate()
    rule = CellTeacher(cfg, load_policy("policies/spatial/straight_180.zip", single))
    env = BatchedUavEnv(cfg, n_envs=4, seed=5)
    obs = env.reset()
    for _ in range(6):
        obs = env.step(rule.act(obs)).observation
    view = rule.single.frames(rule.view(obs))  # (rows, memory, v1 frame)
    assert view.shape[1:] == (rule.single.memory, rule.single.frame_size)
    here = rule.layout.history(obs, "served_here")
    sinr = rule.layout.encoded_history(obs, "sinr_db")
    columns = rule.single.slices["sinr_db"]
    for row, frame in np.ndindex(here.shape[:2]):
        cell = here[row, frame] if here[row, frame].any() else np.ones(cfg.n_ues, bool)
        shown, served = (
            set(view[row, frame, columns].tolist()),
            set(sinr[row, frame, cell].tolist()),
        )
        assert shown == served  # every served UE's SINR, and nothing else
    result = run_json("cell_teacher.py", "--episodes", "2", "--seed", "3", "--sizes", "2", "3")
    assert [(r["scenario"], r["n_uavs"]) for r in result["rows"]] == [
        ("straight_180", 2),
        ("straight_180", 3),
    ]
    for row in result["rows"]:
        r, lo, hi = row["cell_vs_kmeans"]
        assert lo <= r <= hi and abs(r - row["cell_mbps"] / row["kmeans_mbps"]) < 1e-3


def test_fleet_memory_lead_flies_the_spatial_leader_alike_in_v6_and_v7() -> None:
    """research/fleet_memory_lead.py: the lead teacher whose leader reads no memory flies the same
    episodes in layout v6 and v7; the explore leader's row is paired with it and the fleet policy."""
    result = run_json("fleet_memory_lead.py", "--episodes", "2", "--seed", "3", "--sizes", "2")
    [row] = result["rows"]
    assert row["lead_spatial_v6_mbps"] == row["lead_spatial_v7_mbps"]
    r, lo, hi = row["lead_explore_vs_lead_spatial"]
    assert lo <= r <= hi
    assert abs(r - row["lead_explore_v7_mbps"] / row["lead_spatial_v6_mbps"]) < 1e-3
    # no_move's map policy reads a model of the field (v5): it leads in v8, each UAV its own model
    assert row["lead_map_layout"] == 8
    assert row["lead_map_dashed_mbps"] != row["lead_map_mbps"]  # the dash moves a searching leader
    r, lo, hi = row["lead_map_vs_ppo"]
    assert lo <= r <= hi and abs(r - row["lead_map_mbps"] / row["ppo_mbps"]) < 1e-3


def test_fleet_memory_lead_pairs_a_map_leader_where_the_map_policy_reads_the_memory() -> None:
    """research/fleet_memory_lead.py: on straight the map policy (v3) leads in v7, paired."""
    result = run_json(
        "fleet_memory_lead.py",
        "--scenario",
        "straight",
        "--episodes",
        "2",
        "--seed",
        "3",
        "--sizes",
        "2",
    )
    [row] = result["rows"]
    r, lo, hi = row["lead_map_vs_lead_spatial"]
    assert lo <= r <= hi
    assert row["lead_map_layout"] == 7
    assert abs(r - row["lead_map_mbps"] / row["lead_spatial_v6_mbps"]) < 1e-3


def test_fleet_field_worth_blinds_the_genie_to_the_field_alone() -> None:
    """The field-blind genie plans the same paths whatever the field (its plan reads none of it),
    and the report puts every column beside the genie on the same episodes."""
    import dataclasses

    field_blind_genie = research_module("fleet_field_worth").field_blind_genie
    from uavlink.config import EnvConfig
    from uavlink.env.core import BatchedUavEnv
    from uavlink.policies.registry import make_baseline

    cfg = EnvConfig(scenario="hotspot", n_uavs=2, episode_frames=8)
    cfg = cfg.replace(**{"radio.shadowing_model": "spatial"}).validate()
    env = BatchedUavEnv(cfg, n_envs=2, seed=3)
    env.reset()
    truth = env.ground_truth()
    assert truth.shadow_field is not None
    blind = field_blind_genie(make_baseline("genie", cfg))
    blind.plan(truth)
    with_field = blind.path_m.copy()
    blind.plan(dataclasses.replace(truth, shadow_field=None))
    np.testing.assert_array_equal(blind.path_m, with_field)

    result = run_json(
        "fleet_field_worth.py", "--scenario", "hotspot", "--sizes", "2", "--episodes", "2"
    )
    [row] = result["rows"]
    assert set(row["mbps"]) == {"genie", "field-blind genie", "kmeans", "PPO"}
    assert set(row["of_genie"]) == {"field-blind genie", "kmeans", "PPO"}
    ratio, low, high = row["of_genie"]["field-blind genie"]
    assert low <= ratio <= high < 1.0  # on hotspot the field is worth half the genie's throughput


def test_frozen_std_train_holds_the_std_that_plain_training_moves(tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    from uavlink.learn.training import train
    from uavlink.sweep.sweep_file import load_spec

    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        'name = "tiny"\nscenarios = ["straight_180"]\nseeds = [0]\n'
        "[env]\nn_uavs = 2\nfleet_slots = 1\n"
        "[train]\nepisodes = 64\nn_envs = 32\nlearning_rate = 0.05\n"
        'warm_start.teacher = "kmeans"\nwarm_start.episodes = 8\nwarm_start.epochs = 1\n'
        "warm_start.log_std = -2.0\nwarm_start.critic_rollouts = 0\n"
    )
    frozen = tmp_path / "frozen.zip"
    run_main(
        "frozen_std_train.py",
        str(sweep),
        "--scenario",
        "straight_180",
        "--seed",
        "0",
        "--out",
        str(frozen),
    )
    job = load_spec(sweep).jobs()[0]
    plain = tmp_path / "plain.zip"
    train(job.env, job.train, plain, progress=False)
    held = PPO.load(frozen, device="cpu").policy  # its optimizer state loads as any other's
    moved = PPO.load(plain, device="cpu").policy
    assert np.allclose(held.log_std.detach().numpy(), -2.0)
    assert not np.allclose(moved.log_std.detach().numpy(), -2.0)


def test_spread_search_pairs_each_pair_with_kmeans_and_no_spread_is_kmeans() -> None:
    """research/spread_search.py: every (spread_m, lead_frames) pair at every size flies beside
    kmeans on the same episodes; 0 m and no lead is kmeans itself (a ratio of exactly 1)."""
    result = run_json(
        "spread_search.py",
        *("--scenario", "straight_180", "--sizes", "2", "3"),
        *("--spread-m", "0", "20", "--lead-frames", "0", "1", "--episodes", "2", "--seed", "3"),
    )
    rows = result["rows"]
    assert [(r["n_uavs"], r["spread_m"], r["lead_frames"]) for r in rows] == [
        (d, s, lead) for d in (2, 3) for s in (0.0, 20.0) for lead in (0.0, 1.0)
    ]
    for row in rows:
        r, lo, hi = row["spread_vs_kmeans"]
        assert lo <= r <= hi and abs(r - row["spread_mbps"] / row["kmeans_mbps"]) < 1e-3
        if row["spread_m"] == 0 and row["lead_frames"] == 0:
            assert row["spread_vs_kmeans"] == [1.0, 1.0, 1.0]
        if (
            row["spread_m"] == 20 and row["lead_frames"] == 1
        ):  # the shipped rule, paired with itself
            assert row["spread_vs_shipped_rule"] == [1.0, 1.0, 1.0]
    assert len({r["spread_mbps"] for r in rows if r["n_uavs"] == 2}) > 1  # the knobs move the UAVs


def test_spread_search_nearest_is_the_mean_at_two_uavs_only() -> None:
    """research/spread_search.py --away nearest: with one other group its nearest is the mean, so
    D = 2 flies as the shipped teacher; with two others the targets differ."""
    common = ("--scenario", "hotspot", "--sizes", "2", "3", "--spread-m", "30")
    args = (*common, "--lead-frames", "1", "--episodes", "2", "--seed", "3")
    mean = run_json("spread_search.py", *args)
    nearest = run_json("spread_search.py", *args, "--away", "nearest")
    assert (mean["away"], nearest["away"]) == ("mean", "nearest")
    by_size = [
        (m["n_uavs"], m["spread_mbps"], n["spread_mbps"])
        for m, n in zip(mean["rows"], nearest["rows"], strict=True)
    ]
    assert [(d, a == b) for d, a, b in by_size] == [(2, True), (3, False)]


def test_field_critic_columns_hold_each_rows_probes_and_the_fleets_best_link() -> None:
    """research/field_critic.py: each agent row reads its own link shadowing (the first probe is the
    UAV itself, as the channel draws it) and its probes', UEs innermost, then every UE's best fleet
    link; the wrapper appends them after the shipped privileged columns, terminal rows included."""
    critic = research_module("field_critic")
    field_columns, field_critic_env_class = critic.field_columns, critic.field_critic_env_class
    field_width, probe_offsets_m = critic.field_width, critic.probe_offsets_m
    from uavlink.config import EnvConfig
    from uavlink.env.core import BatchedUavEnv
    from uavlink.env.vec_env import UavVecEnv
    from uavlink.learn.privileged import privileged_size

    cfg = EnvConfig(scenario="hotspot", n_uavs=3, fleet_slots=3, episode_frames=3)
    cfg = cfg.replace(**{"radio.shadowing_model": "spatial"}).validate()
    core = BatchedUavEnv(cfg, n_envs=2, seed=4)
    core.reset(4)
    truth = core.ground_truth()
    cols = field_columns(truth, cfg)
    u, d, p = cfg.n_ues, cfg.n_uavs, len(probe_offsets_m())
    assert cols.shape == (2 * d, field_width(u)) == (6, (p + 1) * u)
    links = truth.shadow_field.shadow_db(
        truth.uav_xy_m.reshape(2, d, 2), truth.ue_xy_m
    )  # (N, U, D)
    links = links / cfg.radio.shadowing_std_db
    own = links.transpose(0, 2, 1).reshape(2 * d, u)
    np.testing.assert_allclose(cols[:, :u], own, atol=1e-5)
    np.testing.assert_allclose(cols[:, -u:], np.repeat(links.max(axis=2), d, axis=0), atol=1e-5)
    assert not np.allclose(cols[:, u : 2 * u], cols[:, :u])  # a probe 20 m off reads another link

    wide = field_critic_env_class()(UavVecEnv(cfg, n_envs=2, seed=4))
    width = wide.observation_space.shape[0]
    obs = wide.reset()
    assert obs.shape == (6, width) and width - field_width(u) - privileged_size(cfg) > 0
    for _ in range(cfg.episode_frames):
        obs, _, dones, infos = wide.step(np.zeros((6, 2), np.float32))
    assert dones.all() and all(info["terminal_observation"].shape == (width,) for info in infos)


def test_field_critic_trains_a_policy_whose_critic_reads_the_field_and_actor_does_not(
    tmp_path: Path,
) -> None:
    """research/field_critic.py end to end on a tiny job: the saved policy's critic reads the field's
    columns after the shipped privileged ones, its actor the observation alone, and it evaluates as
    any policy file."""
    from stable_baselines3 import PPO

    from uavlink.env.observation import ObservationLayout
    from uavlink.learn.privileged import privileged_size
    from uavlink.sweep.sweep_file import load_spec

    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        'name = "tiny"\nscenarios = ["hotspot"]\nseeds = [0]\n'
        '[env]\nn_uavs = 2\nfleet_slots = 1\n"radio.shadowing_model" = "spatial"\n'
        '[train]\nepisodes = 64\nn_envs = 32\ncritic = "privileged"\n'
    )
    out = tmp_path / "field.zip"
    args = ("--scenario", "hotspot", "--seed", "0", "--out", str(out))
    printed = run_main("field_critic.py", str(sweep), *args)
    assert "learning curve in sixths" in printed
    cfg = load_spec(sweep).jobs()[0].env
    policy = PPO.load(out, device="cpu").policy
    actor = ObservationLayout.for_config(cfg).size
    assert policy.actor_obs_size == actor
    field_width = research_module("field_critic").field_width
    wide = actor + privileged_size(cfg) + field_width(cfg.n_ues)
    assert policy.observation_space.shape == (wide,)
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    [(flown, env)] = load_with_env([str(out)], EnvOverrides())
    assert evaluate_policy(flown, env, 1, 0).mean_rate_mbps > 0  # the actor alone flies


def test_paired_ppo_advantage_is_each_copys_own_less_the_others_mean() -> None:
    """research/paired_ppo.py: returns to go stop at an episode's start; a term every copy of a row
    shares (the episode's luck) cancels, each copy keeps its own less the others' mean."""
    paired = research_module("paired_ppo")
    rewards = np.array([[1.0], [2.0], [3.0], [4.0]])
    starts = np.array([[1.0], [0.0], [1.0], [0.0]])
    assert paired.returns_to_go(rewards, starts, 1.0)[:, 0].tolist() == [3.0, 2.0, 7.0, 4.0]
    rng = np.random.default_rng(0)
    edges = np.array([0, 2, 4, 6, 9, 12, 15])  # two sizes, three copies each (2 and 3 rows)
    shared = rng.normal(size=(5, 5))  # per time step and row of a copy, sizes side by side
    own = rng.normal(size=(5, 15))
    luck = np.concatenate([np.tile(shared[:, :2], 3), np.tile(shared[:, 2:], 3)], axis=1)
    out = paired.leave_one_out(luck + own, edges, 3)
    for a, b in ((0, 6), (6, 15)):
        block = own[:, a:b].reshape(5, 3, -1)
        expected = block - (block.sum(axis=1, keepdims=True) - block) / 2
        assert np.allclose(out[:, a:b], expected.reshape(5, -1))


def test_paired_ppo_copies_fly_the_same_ues_wherever_their_uavs_go() -> None:
    from uavlink.config import EnvConfig, TrainConfig

    paired = research_module("paired_ppo")
    cfg = EnvConfig(scenario="hotspot", n_uavs=2, fleet_slots=3, episode_frames=8)
    cfg = cfg.replace(**{"radio.shadowing_model": "spatial"}).validate()
    tc = TrainConfig(
        n_envs=4, n_steps=8, batch_size=16, fleet_sizes_up_to=3, critic="privileged", seed=5
    )
    env = paired.paired_env(cfg, tc.validate(cfg), copies=2)
    env.reset()
    rng = np.random.default_rng(1)
    apart_m = 0.0
    for _ in range(2 * cfg.episode_frames):  # past an episode's end and the batch's reset
        env.step(rng.uniform(-1, 1, (env.num_envs, 2)).astype(np.float32))
        paired.check_copies_agree(env, 2)  # SystemExit where they part
        uavs = [part.venv.core.uav_xy_m for part in env.parts[:2]]
        apart_m = max(apart_m, float(np.abs(uavs[0] - uavs[1]).max()))
    assert apart_m > 10.0  # while the UAVs flew apart


def test_paired_ppo_trains_a_policy_that_evaluates_as_any_other(tmp_path: Path) -> None:
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        'name = "tiny"\nscenarios = ["hotspot"]\nseeds = [0]\n'
        '[env]\nn_uavs = 2\nfleet_slots = 3\n"radio.shadowing_model" = "spatial"\n'
        '[train]\nepisodes = 96\nn_envs = 8\nfleet_sizes_up_to = 3\ncritic = "privileged"\n'
    )
    out = tmp_path / "paired.zip"
    printed = run_main(
        "paired_ppo.py", str(sweep), "--scenario", "hotspot", "--seed", "0", "--out", str(out)
    )
    assert "4 copies of each world" in printed and "paired / Monte-Carlo advantage std" in printed
    [(flown, env)] = load_with_env([str(out)], EnvOverrides())
    assert evaluate_policy(flown, env, 1, 0).mean_rate_mbps > 0
    job = ("--scenario", "hotspot", "--seed", "0", "--measure", str(out))
    measured = run_main("paired_ppo.py", str(sweep), *job)
    rollouts = [line.split("std ")[1].split() for line in measured.splitlines()]
    assert len(rollouts) == 3  # past the first episode: the pairing holds there too
    assert all(0 < float(p) < float(mc) for mc, _, p, _ in rollouts)  # the episodes' luck gone


def test_sde_ppo_trains_a_policy_the_product_loads_and_flies(tmp_path: Path) -> None:
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        'name = "tiny"\nscenarios = ["hotspot"]\nseeds = [0]\n'
        '[env]\nn_uavs = 2\nfleet_slots = 1\n"radio.shadowing_model" = "spatial"\n'
        '[train]\nepisodes = 64\nn_envs = 32\ncritic = "privileged"\n'
        'warm_start.teacher = "kmeans"\nwarm_start.episodes = 8\nwarm_start.epochs = 1\n'
    )
    out = tmp_path / "sde.zip"
    args = ("--scenario", "hotspot", "--seed", "0", "--log-std", "-2", "--out", str(out))
    assert "with gSDE" in run_main("sde_ppo.py", str(sweep), *args)
    [(flown, env)] = load_with_env([str(out)], EnvOverrides())
    assert evaluate_policy(flown, env, 1, 0).mean_rate_mbps > 0


def test_spread_start_ppo_copies_and_pairs_the_spread_teacher_at_the_distance_asked(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from uavlink.learn import teachers

    built: list[float] = []

    class Recorded(teachers.SpreadTeacher):
        def __init__(self, *args: object, **kwargs: object) -> None:
            super().__init__(*args, **kwargs)  # type: ignore[arg-type]
            built.append(self.spread_m)

    monkeypatch.setattr(teachers, "SpreadTeacher", Recorded)
    sweep = tmp_path / "tiny.toml"
    sweep.write_text(
        'name = "tiny"\nscenarios = ["hotspot"]\nseeds = [0]\n'
        '[env]\nn_uavs = 2\nfleet_slots = 1\n"radio.shadowing_model" = "spatial"\n'
        '[train]\nepisodes = 64\nn_envs = 32\ncritic = "privileged"\n'
        'warm_start.teacher = "spread"\nwarm_start.episodes = 8\nwarm_start.epochs = 1\n'
    )
    out = tmp_path / "spread5.zip"
    job = ("--scenario", "hotspot", "--seed", "0", "--spread-m", "5", "--sizes", "2")
    printed = run_main(
        "spread_start_ppo.py", str(sweep), *job, "--episodes", "2", "--out", str(out)
    )
    assert "spread 5 m ->" in printed and printed.count("D = 2:") == 1
    assert built and set(built) == {5.0}  # the copy's teacher and the pairing's, both at 5 m


@pytest.mark.parametrize(
    "args",
    [
        ("aoa_teacher_search.py", "--scenarios", "nosuch"),
        ("explore_search.py", "--set", "nosuch=1"),
        ("fleet_bars.py", "--fleet", "/nonexistent", "--episodes", "1"),
        ("map_table.py", "--map", "/nonexistent", "--episodes", "2"),
        (
            "ppo_from.py",
            "sweeps/fleet.toml",
            "--scenario",
            "hotspot",
            "--seed",
            "0",
            "--start-from",
            "/nonexistent.zip",
            "--out",
            "/tmp/never.zip",
        ),
    ],
)
def test_bad_input_to_a_research_script_is_one_line_and_exit_2(args: tuple[str, ...]) -> None:
    import subprocess

    done = subprocess.run(
        [sys.executable, str(FOLDER / args[0]), *args[1:]],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    last = done.stderr.strip().splitlines()[-1]
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert last.startswith(f"{args[0]}: error: "), last


def test_genie_check_finds_the_genie_at_or_above_every_policy() -> None:
    result = run_json("genie_check.py", "--episodes", "1", "--scenarios", "straight", "--uavs", "1")
    [row] = result["rows"]
    assert (row["scenario"], row["n_uavs"]) == ("straight", 1)
    assert {"static", "aoa", "ppo"} <= set(row["genie_vs"])
    assert row["genie_at_least_every_other"] and result["all_met"]
    assert all(v["ratio"] >= 1.0 for v in row["genie_vs"].values())


def test_aoa_rule_effects_measures_the_rules_and_a_close_copy_of_aoa() -> None:
    result = run_json("aoa_rule_effects.py", "--episodes", "1")
    for rates in result["shadowing_mbps"].values():
        assert set(rates) == {"static", "zigzag", "aoa"} and all(r > 0 for r in rates.values())
    for rates in result["clone_before_ppo_mbps"].values():
        # The warm start's copy flies within a few percent of the rule it copies.
        assert abs(rates["clone"] / rates["aoa"] - 1) < 0.05, rates


def test_link_faults_flies_clean_and_lossy_rows_through_the_relay() -> None:
    result = run_json("link_faults.py", "--quick", "--runs", "1", "--speed", "50")
    clean, *lossy = result["rows"]
    assert clean["condition"] == "clean" and clean["frames"] == 128 and clean["runs"] == 1
    assert [row["condition"] for row in lossy] == ["10% loss", "30% loss"]
    assert all(0 < row["mean_rate_mbps"] <= clean["mean_rate_mbps"] * 1.1 for row in lossy)


@pytest.mark.parametrize("objective", ["mbps", "fair"])
def test_es_actor_steps_a_shipped_fleet_policy_and_pairs_the_result(
    tmp_path: Path, objective: str
) -> None:
    out = tmp_path / "es.zip"
    args = ("--iterations", "1", "--pairs", "1", "--episodes", "2", "--sizes", "2")
    args += ("--objective", objective)
    printed = run_main(
        "es_actor.py", str(ROOT / "policies/fleet/straight_180.zip"), *args, "--check-episodes", "2",
        "--out", str(out),
    )  # fmt: skip
    rows = json.loads(printed)
    assert set(rows) == {"D2", "D3", "D4"} and rows["D2"]["teacher"] == "spread"
    assert all(len(row["vs_start"]) == 3 and row["mbps"] > 0 for row in rows.values())
    # One small step moved the head: the written policy is not the start.
    from uavlink.policies.sb3_policy import SB3Policy

    obs = np.random.default_rng(0).normal(size=(4, SB3Policy(out).layout.size)).astype(np.float32)
    start = SB3Policy(ROOT / "policies/fleet/straight_180.zip")
    assert not np.array_equal(SB3Policy(out).act(obs), start.act(obs))


def test_es_actor_action_noise_is_shared_by_a_pairs_members_and_moves_the_score() -> None:
    """``--action-noise`` scores PPO's noisy policy; a pair's difference must hold no noise luck, so
    the same weights on the same seed score alike, and the noise changes what is scored."""
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.sb3_policy import SB3Policy

    es = research_module("es_actor")
    path = ROOT / "policies/fleet/straight_180.zip"
    [(_, cfg)] = load_with_env([path], EnvOverrides())
    envs = [cfg.replace(n_uavs=2).validate()]
    policy = SB3Policy(path)
    noisy = es.NoisyActions(policy, log_std=-1.0)
    first, again = (es.fitness(noisy, envs, 3, seed=5) for _ in range(2))
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, es.fitness(policy, envs, 3, seed=5))


def test_ppo_from_lowers_the_learning_rate_to_zero_over_the_run() -> None:
    """``--anneal``'s callback: SB3's updates read a rate falling linearly from the one set to zero
    (a real PPO on a small Gymnasium task, eight rollouts: the rate of each update after one)."""
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Rates(BaseCallback):
        seen: list[float] = []

        def _on_rollout_start(self) -> None:  # after the previous rollout's update
            self.seen.append(self.model.policy.optimizer.param_groups[0]["lr"])

        def _on_step(self) -> bool:
            return True

    annealed, rates = research_module("ppo_from").annealed_lr_callback(), Rates()
    model = PPO("MlpPolicy", gym.make("Pendulum-v1"), learning_rate=1e-3, n_steps=64,
                batch_size=64, n_epochs=1, seed=0, device="cpu")  # fmt: skip
    model.learn(total_timesteps=64 * 8, callback=[annealed, rates])
    # the k-th update ran with 1 - k/8 of the run remaining; the last with none
    np.testing.assert_allclose(rates.seen[1:], [1e-3 * (1 - k / 8) for k in range(1, 8)])
    assert model.policy.optimizer.param_groups[0]["lr"] == 0.0


def test_ppo_from_trains_from_a_policy_and_pairs_it_with_its_start(tmp_path: Path) -> None:
    out = tmp_path / "annealed.zip"
    start = ROOT / "policies/fleet/straight_180.zip"
    printed = run_main(
        "ppo_from.py", "sweeps/fleet.toml", "--scenario", "straight_180", "--seed", "0",
        "--start-from", str(start), "--episodes", "64", "--anneal", "--check-episodes", "2",
        "--out", str(out),
    )  # fmt: skip
    rows = json.loads(printed)
    assert set(rows) == {"curve_sixths_mbps", "D2", "D3", "D4"} and out.is_file()
    assert all(len(rows[d]["vs_kmeans"]) == 3 and rows[d]["mbps"] > 0 for d in ("D2", "D3", "D4"))


def test_es_actor_per_agent_weights_move_only_their_own_uavs_rows() -> None:
    """``--per-agent``: UAV d flies its own weights on agent rows d, d + D, ...; the same weights
    for every UAV act as the policy itself."""
    import torch

    from uavlink.policies.sb3_policy import SB3Policy

    es = research_module("es_actor")
    policy = SB3Policy(ROOT / "policies/fleet/straight_180.zip")
    params = es.head_parameters(policy.actor, 1)
    start = [p.detach().clone() for p in params]

    def set_params(values):  # type: ignore[no-untyped-def]
        with torch.no_grad():
            for p, x in zip(params, values, strict=True):
                p.copy_(x)

    obs = np.random.default_rng(0).normal(size=(6, policy.layout.size)).astype(np.float32)
    plain = policy.act(obs)
    wrapped = es.PerAgentWeights(policy, set_params)
    wrapped.n_uavs, wrapped.values = 3, [start, start, start]
    np.testing.assert_array_equal(wrapped.act(obs), plain)
    wrapped.values = [start, [x + 0.5 for x in start], start]
    moved = wrapped.act(obs)
    set_params(start)
    changed = np.abs(moved - plain).sum(axis=1) > 0
    assert changed.tolist() == [False, True, False, False, True, False]


def test_silent_sensor_a_second_uav_near_the_team_takes_ues_and_hears_them_louder() -> None:
    """research/silent_sensor.py's table: 40 m from the first UAV the second serves a UE in some
    frames and not in others; in the far corner it is silent more often and hears the UEs fainter."""
    rows = run_json(
        "silent_sensor.py", "--scenario", "no_move", "--distances", "40", "-1", "--episodes", "16"
    )["rows"]
    near, corner = rows
    assert (near["distance_m"], corner["distance_m"]) == (40.0, "corner")
    assert 0.0 < near["silent_share"] < 1.0
    assert corner["silent_share"] > near["silent_share"]
    assert corner["heard_snr_db"] < near["heard_snr_db"] - 10.0


def test_pooled_field_flies_as_evaluation_alone_and_its_listener_senses_what_the_server_would() -> (
    None
):
    """research/pooled_field.py: without a listener its loop is evaluation's, episode for episode;
    a listener over the serving UAV hears the value the serving UAV senses (fast fading off); and
    its table pairs each fleet size's pooled flight with the policy alone."""
    from uavlink.env.core import BatchedUavEnv
    from uavlink.env.place_memory import sensed_value_bits
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    pooled = research_module("pooled_field")
    [(policy, cfg)] = load_with_env(["policies/map/no_move.zip"], EnvOverrides())
    alone = pooled.fly(policy, cfg, "none", 0, 3, 5)
    np.testing.assert_allclose(alone, evaluate_policy(policy, cfg, 3, 5).episode_rate_mbps)
    still = cfg.replace(**{"radio.fast_fading": False}).validate()
    env = BatchedUavEnv(still, n_envs=4, seed=2)
    env.reset()
    env.step(np.full((4, 2), 0.5, dtype=np.float32))
    heard = pooled.heard_value_bits(env, env.uav_xy_m, np.random.default_rng(0))
    np.testing.assert_allclose(heard, sensed_value_bits(env.readings.sinr_db), rtol=1e-6)
    rows = run_json("pooled_field.py", "--leaders", "kriging", "--sizes", "2", "--episodes", "4")[
        "rows"
    ]
    assert [(r["listener"], r["n_uavs"]) for r in rows] == [("spiral", 2), ("ucb", 2)]
    assert all(r["pooled_mbps"] != r["alone_mbps"] for r in rows)


def test_fleet_listeners_table_pairs_the_listening_fleet_with_the_shipped_one() -> None:
    """research/fleet_listeners.py: its table's runs and ratios for one fleet size, kmeans gaining
    in the listening world (its second UAV no longer interferes)."""
    [row] = run_json("fleet_listeners.py", "--sizes", "2", "--episodes", "4")["rows"]
    assert row["n_uavs"] == 2
    assert {"ppo_v8_mbps", "lead_v8_mbps", "hold_mbps", "sense_mbps"} <= set(row)
    assert row["kmeans_listen_mbps"] > row["kmeans_full_mbps"]
    low, high = row["sense_vs_hold"][1:]
    assert low <= row["sense_vs_hold"][0] <= high
