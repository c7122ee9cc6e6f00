"""``uavlink evaluate`` as users run it: a real subprocess of the installed console script (where a
test runs the same command twice, once through the CLI's main in this process)."""

from __future__ import annotations

import csv
import json
import shutil
import sys
from pathlib import Path

import pytest
from support.cli import assert_user_error, cli_json, run_uavlink_in_process
from support.cli import run_uavlink as uavlink

from uavlink.cli import main
from uavlink.mobility import SCENARIOS


def test_evaluate_json():
    proc = uavlink(
        "evaluate",
        "--scenario",
        "circular",
        "--policy",
        "static",
        "--episodes",
        "5",
        "--seed",
        "0",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["scenario"] == "circular"
    assert result["policy"] == "static"
    assert result["episodes"] == 5
    assert 3.0 < result["mean_rate_mbps"] < 5.0
    assert 0.0 < result["ci95_mbps"] < 1.0
    assert len(result["episode_rate_mbps"]) == 5
    assert result["mean_rate_mbps"] == pytest.approx(sum(result["episode_rate_mbps"]) / 5, abs=1e-5)


@pytest.mark.slow
def test_same_seed_same_json_other_seed_differs():
    args = ("evaluate", "--scenario", "hotspot", "--policy", "aoa", "--episodes", "4", "--json")
    first = uavlink(*args, "--seed", "3")
    second = uavlink(*args, "--seed", "3")
    other = uavlink(*args, "--seed", "4")
    assert first.returncode == second.returncode == other.returncode == 0
    assert first.stdout == second.stdout
    assert (
        json.loads(first.stdout)["episode_rate_mbps"]
        != json.loads(other.stdout)["episode_rate_mbps"]
    )


@pytest.mark.slow
def test_scenario_all_prints_six_rows():
    proc = uavlink("evaluate", "--scenario", "all", "--policy", "static", "--episodes", "3")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[0].split()[:2] == ["scenario", "policy"]  # header
    rows = lines[1:]
    assert [row.split()[0] for row in rows] == list(SCENARIOS)
    assert all(row.split()[1] == "static" and row.split()[2] == "3" for row in rows)
    as_json = uavlink(
        "evaluate", "--scenario", "all", "--policy", "static", "--episodes", "3", "--json"
    )
    assert [r["scenario"] for r in json.loads(as_json.stdout)] == list(SCENARIOS)


@pytest.mark.slow
def test_set_overrides_reach_the_env():
    base = ("evaluate", "--scenario", "no_move", "--policy", "static", "--episodes", "3", "--json")
    quiet = json.loads(
        uavlink(*base, "--set", "radio.shadowing=false", "--set", "fast_fading=false").stdout
    )
    # Hovering over the cluster with the mean channel: 8.08 Mbps in every episode.
    assert all(rate == pytest.approx(8.08, abs=0.02) for rate in quiet["episode_rate_mbps"])
    loud = json.loads(uavlink(*base, "--set", "tx_power_dbm=29").stdout)
    assert loud["mean_rate_mbps"] > quiet["mean_rate_mbps"] + 2.0
    # the AoA noise reaches the env: the aoa rule, which steers by the AoAs, flies other paths
    steered = ("evaluate", "--scenario", "circular", "--policy", "aoa", "--episodes", "3", "--json")
    clean, noisy = (
        json.loads(uavlink(*steered, "--aoa-noise-deg", deg).stdout) for deg in ("0", "30")
    )
    assert (
        noisy["aoa_noise_deg"] == 30.0 and noisy["episode_rate_mbps"] != clean["episode_rate_mbps"]
    )


@pytest.mark.parametrize(
    ("args", "fragments"),
    [
        (("--scenario", "zigzag"), ("unknown scenario 'zigzag'", "circular")),
        (
            ("--set", "warp_drive=1"),
            (
                "unknown config key 'warp_drive' (the keys: the fields of uavlink.config.env.EnvConfig)",
            ),
        ),
        (("--set", "r_max=10"), ("unknown config key 'r_max' (did you mean r_max_m?)",)),
        (("--set", "no_equals_sign"), ("--set expects key=value",)),
        (("--set", "radio.bandwidth_hz=-1"), ("radio.bandwidth_hz must be positive",)),
        (("--set", "n_ues=0"), ("env.n_ues must be positive",)),
        (("--aoa-noise-deg", "-2"), ("aoa_noise_deg must be >= 0",)),
        (("--episodes", "0"), ("episodes must be a positive integer",)),
        (("--workers", "2"), ("--workers goes with --out FOLDER",)),  # it was ignored in silence
    ],
)
def test_bad_arguments_exit_2_with_one_line(args, fragments):
    assert_user_error(
        uavlink("evaluate", "--policy", "static", "--episodes", "2", *args), *fragments
    )


@pytest.mark.slow
def test_a_policy_file_flies_its_own_scenario_unless_told_otherwise():
    """Without --scenario a policy file flies the scenario its manifest names (a no_move policy is
    not measured on circular by default), and a folder beside it gives its policy for that scenario;
    two files trained on different scenarios need one named."""
    own = cli_json(
        "evaluate",
        "--policy",
        "policies/map/no_move.zip",
        "--against",
        "static",
        "--episodes",
        "1",
        "--json",
    )
    assert [r["scenario"] for r in own["results"]] == ["no_move", "no_move"]
    told = cli_json(
        "evaluate",
        "--policy",
        "policies/map/no_move.zip",
        "--scenario",
        "straight",
        "--episodes",
        "1",
        "--json",
    )
    assert told["scenario"] == "straight"
    namesakes = cli_json(
        "evaluate",
        "--policy",
        "policies/map/no_move.zip",
        "--against",
        "policies/spatial/no_move.zip",
        "--episodes",
        "1",
        "--json",
    )  # told apart by path
    assert [r["policy"] for r in namesakes["results"]] == [
        "policies/map/no_move.zip",
        "policies/spatial/no_move.zip",
    ]
    folder = cli_json(
        "evaluate",
        "--policy",
        "policies/map/no_move.zip",
        "--against",
        "policies/spatial",
        "--episodes",
        "1",
        "--json",
    )  # the folder's policy for the file's scenario
    assert folder["results"][1]["episode_rate_mbps"] == namesakes["results"][1]["episode_rate_mbps"]
    assert_user_error(
        uavlink(
            "evaluate",
            "--policy",
            "policies/map/straight.zip",
            "--against",
            "policies/map/circular.zip",
            "--episodes",
            "1",
        ),
        "scenario='straight' vs 'circular'",
        "--scenario",
    )


@pytest.mark.parametrize("policy", ["missing.zip", "missing.onnx", "no_such_policy"])
def test_missing_policy_file_exits_2(policy, tmp_path):
    assert_user_error(
        uavlink("evaluate", "--policy", policy, "--episodes", "2", cwd=tmp_path), policy
    )


@pytest.mark.slow
def test_unusable_policy_files_exit_2(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("not a policy")
    assert_user_error(uavlink("evaluate", "--policy", str(text), "--episodes", "2"), "notes.txt")
    fake_zip = tmp_path / "circular.zip"
    fake_zip.write_text("not a zip")
    assert_user_error(
        uavlink("evaluate", "--policy", str(fake_zip), "--episodes", "2"), "circular.zip"
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_user_error(uavlink("evaluate", "--policy", str(empty), "--episodes", "2"), "circular")


def test_results_folder_with_an_unfinished_sweep_fails_before_evaluating(tmp_path):
    """The across-seed table needs the finished sweep (its runs, or the record shipped beside the
    policies): refused at once, and nothing is written."""
    root = Path(__file__).resolve().parents[1]
    policies = tmp_path / "policies"  # the shipped policies without a sweep record
    policies.mkdir()
    for zip_file in (root / "policies").glob("*.zip"):
        shutil.copyfile(zip_file, policies / zip_file.name)
    out = tmp_path / "results"
    proc = uavlink(
        "evaluate",
        "--scenario",
        "all",
        "--policy",
        str(policies),
        "--episodes",
        "2",
        "--out",
        str(out),
        "--sweep",
        str(root / "sweeps" / "table1.toml"),
        "--sweep-root",
        str(tmp_path / "runs"),
    )
    assert_user_error(proc, "sweep 'table1'", "not finished", "hotspot")
    assert not out.exists()  # refused before the evaluation, which would have written it


@pytest.mark.parametrize("args", [("--help",), ("evaluate", "--help")])
def test_help(args):
    proc = uavlink(*args)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: uavlink")
    if args[0] == "evaluate":
        for option in ("--scenario", "--policy", "--episodes", "--seed", "--json", "--set"):
            assert option in proc.stdout
    else:
        assert "evaluate" in proc.stdout


def test_version():
    proc = uavlink("--version")
    assert proc.returncode == 0 and proc.stdout.startswith("uavlink ")


@pytest.mark.slow
def test_results_folder_has_the_tables_and_figures_and_is_reproducible(tmp_path, monkeypatch):
    root = Path(__file__).resolve().parents[1]
    a, b = tmp_path / "a", tmp_path / "b"
    command = [
        "evaluate",
        "--scenario",
        "all",
        "--policy",
        str(root / "policies"),
        "--episodes",
        "2",
        "--seed",
        "0",
        # 16-frame episodes: the folder's tables, figures and reproducibility, at an eighth of the cost
        "--set",
        "episode_frames=16",
    ]
    # a through the CLI's main in this process (no second torch import), b as users run it: the
    # reproducibility below then also holds across processes.
    monkeypatch.setattr(
        sys, "argv", ["uavlink", *command, "--out", str(a)]
    )  # results.md records it
    assert main(sys.argv[1:]) == 0
    # the spatial part plans a genie per episode: more than the default 120 s on a loaded machine
    proc = uavlink(*command, "--out", str(b), "--spatial", str(root / "policies"), timeout=360)
    assert proc.returncode == 0, proc.stderr[-2000:]
    # stderr is a pipe here: no status line rewritten in place, a line per step of the report
    lines = [line for line in proc.stderr.splitlines() if line.startswith("evaluating ")]
    assert "\r" not in proc.stderr and len(lines) == len(set(lines)) >= len(SCENARIOS), lines
    table1 = (a / "table1.csv").read_text().splitlines()
    assert len(table1) == 1 + len(SCENARIOS) and all(
        row.split(",")[0] in SCENARIOS for row in table1[1:]
    )
    assert (
        len((a / "table2.csv").read_text().splitlines()) == 1 + 6
    )  # AoA noise 0, 1, 5, 10, 50, 100
    figures = [
        "throughput_per_episode.png",
        "throughput_vs_fairness.png",
        *(f"trajectory_{s}.png" for s in SCENARIOS),
    ]
    for figure in figures:
        assert (a / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", figure
    markdown = (a / "results.md").read_text()
    assert "--episodes 2" in markdown and all(f"]({figure})" in markdown for figure in figures)
    # seeded: the same command gives the same tables and raw results (the spatial part of b adds to them)
    for name in ("table1.csv", "table2.csv", "results.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    # --spatial: given the AR(1) folder as the "spatial" one, the transfer table's two spatial columns
    # fly the same policies on the same channel and must agree; the spatial Table I is another channel's.
    spatial = (b / "table1_spatial.csv").read_text().splitlines()
    assert len(spatial) == 1 + len(SCENARIOS) and spatial != table1
    assert "genie" in spatial[0].split(",") and "PPO / genie" in spatial[0].split(",")
    assert len((b / "table2_spatial.csv").read_text().splitlines()) == 1 + 6
    transfer = list(csv.reader((b / "transfer_spatial.csv").open()))
    assert [row[0] for row in transfer[1:]] == list(SCENARIOS)
    assert all(row[3:5] == row[5:7] for row in transfer[1:])
    spatial_markdown = (b / "results.md").read_text()
    assert (
        "## On the spatial channel" in spatial_markdown and "### What survives" in spatial_markdown
    )
    assert "## On the spatial channel" not in markdown


def test_report_progress_is_one_line_on_a_terminal_and_lines_or_quiet_elsewhere(
    monkeypatch, capsys
):
    from uavlink.cli.evaluate import StatusLine

    quiet = StatusLine()  # pytest captures stderr: not a terminal
    quiet.show("evaluating no_move: ppo")
    quiet.close()
    assert capsys.readouterr().err == ""
    logged = StatusLine(log_lines=True)  # the results report's, in a log: a line per message
    logged.show("evaluating no_move: ppo")
    logged.show("evaluating no_move: static")
    logged.close()
    assert capsys.readouterr().err == "evaluating no_move: ppo\nevaluating no_move: static\n"
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    live = StatusLine()
    live.show("evaluating no_move: ppo")
    live.show("evaluating no_move: static")
    live.close()
    err = capsys.readouterr().err
    assert "\n" not in err and err.count("\r") == 3 and err.endswith("\r\033[K")
    assert "evaluating no_move: static" in err


def test_results_folder_refuses_a_missing_spatial_folder_before_evaluating(tmp_path):
    root = Path(__file__).resolve().parents[1]
    out = tmp_path / "results"
    assert_user_error(
        uavlink(
            "evaluate",
            "--scenario",
            "all",
            "--policy",
            str(root / "policies"),
            "--out",
            str(out),
            "--spatial",
            str(tmp_path / "missing"),
        ),
        "--spatial",
    )
    assert not out.exists()


@pytest.mark.slow
def test_evaluate_against_pairs_two_policies_on_the_same_episodes():
    proc = uavlink(
        "evaluate",
        "--scenario",
        "hotspot",
        "--policy",
        "aoa",
        "--against",
        "static",
        "--episodes",
        "6",
        "--seed",
        "3",
        "--json",
    )
    assert proc.returncode == 0, proc.stderr
    payload = json.loads(proc.stdout)
    aoa, static = payload["results"]
    (comparison,) = payload["comparisons"]
    assert (aoa["policy"], static["policy"]) == ("aoa", "static") and comparison["episodes"] == 6
    assert comparison["throughput_ratio"] == pytest.approx(
        aoa["mean_rate_mbps"] / static["mean_rate_mbps"], rel=1e-5
    )
    lo, hi = comparison["throughput_ratio_ci95"]
    assert lo <= comparison["throughput_ratio"] <= hi
    assert comparison["fair_rate_difference"] == pytest.approx(
        aoa["mean_fair_rate"] - static["mean_fair_rate"], abs=1e-5
    )
    won = sum(
        a > s for a, s in zip(aoa["episode_rate_mbps"], static["episode_rate_mbps"], strict=True)
    )
    assert comparison["a_better_episodes"] == won

    # A policy against itself: the same episodes, so a ratio of exactly 1 and no spread.
    proc = uavlink(
        "evaluate",
        "--scenario",
        "straight",
        "--policy",
        "aoa",
        "--against",
        "aoa",
        "--episodes",
        "4",
    )
    assert proc.returncode == 0, proc.stderr
    assert "straight: aoa vs aoa: throughput +0.00 % [+0.00, +0.00]" in proc.stdout
    assert "better in 0 of 4 episodes" in proc.stdout


def test_evaluate_against_repeated_compares_the_policy_with_each():
    """Every --against is flown and paired with --policy (the last one used to win silently)."""
    args = (
        "evaluate",
        "--scenario",
        "hotspot",
        "--policy",
        "aoa",
        "--episodes",
        "3",
        "--seed",
        "5",
        "--json",
    )
    both = cli_json(*args, "--against", "static", "--against", "oracle")
    assert [r["policy"] for r in both["results"]] == ["aoa", "static", "oracle"]
    assert [(c["a"], c["b"]) for c in both["comparisons"]] == [("aoa", "static"), ("aoa", "oracle")]
    alone = cli_json(*args, "--against", "oracle")
    assert both["comparisons"][1] == alone["comparisons"][0]


def test_evaluate_against_refuses_the_results_folder(tmp_path: Path):
    assert_user_error(
        uavlink(
            "evaluate",
            "--scenario",
            "all",
            "--policy",
            "policies",
            "--against",
            "aoa",
            "--out",
            str(tmp_path / "out"),
        ),
        "--against",
    )
    assert not (tmp_path / "out").exists()


@pytest.mark.slow  # 4.2 s on an idle 2-core machine
def test_evaluate_against_pairs_a_fleet_with_one_uav_on_the_same_episodes():
    """A fleet policy against a single-UAV policy: the same UEs and channel with one UAV more (the
    fleet's "a second UAV never hurts" ratio); the single-UAV policy's episodes are those it flies
    alone. Policies built for another world (here the AR(1) channel) are still refused."""
    fleet, single = "policies/fleet_d2/straight.zip", "policies/spatial/straight.zip"
    args = ("evaluate", "--scenario", "straight", "--episodes", "3", "--seed", "5", "--json")
    payload = cli_json(*args, "--policy", fleet, "--against", single)
    (comparison,) = payload["comparisons"]
    alone = cli_json(*args, "--policy", single)
    assert payload["results"][1]["episode_rate_mbps"] == alone["episode_rate_mbps"]
    assert comparison["throughput_ratio"] == pytest.approx(
        payload["results"][0]["mean_rate_mbps"] / alone["mean_rate_mbps"], rel=1e-5
    )
    assert_user_error(
        run_uavlink_in_process(*args, "--policy", fleet, "--against", "policies/straight.zip"),
        "radio.shadowing_model",
    )


def test_a_fleets_table_adds_jain_the_cell_edge_rate_and_ues_per_uav(capsys):
    """The README promises these for a fleet; one UAV's table keeps its six columns."""
    fleet = [
        "evaluate",
        "--policy",
        "static",
        "--scenario",
        "no_move",
        "--set",
        "n_uavs=2",
        "--episodes",
        "2",
    ]
    assert main(fleet) == 0
    header, row = capsys.readouterr().out.strip().splitlines()[-2:]
    assert header.split()[-8:] == ["Jain", "p5", "Mbps", "UEs", "per", "UAV,", "busiest", "first"]
    result = cli_json(*fleet, "--json")
    assert row.split()[-4:] == [
        f"{result['jain_index']:.3f}",
        f"{result['p5_ue_rate_mbps']:.3f}",
        *(f"{n:.1f}" for n in result["ues_per_uav"]),
    ]
    assert main(["evaluate", "--policy", "static", "--scenario", "no_move", "--episodes", "2"]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-2].split()[-1] == "R_fair"
