"""The developer checks under tools/ run end to end (tiny budgets, each script's main in this
process): the figures fingerprint a refactor is checked with, the shipped manifests' re-evaluation
and the flown-against-evaluated parity."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest
from support import scripts

pytestmark = pytest.mark.slow  # each evaluates shipped policies or flies

ROOT = Path(__file__).resolve().parents[1]


def run_json(script: str, *args: str) -> dict | list:
    """``python tools/SCRIPT ARGS --json``, its main run in this process."""
    return scripts.run_json("tools", script, *args)


def test_manifest_check_gives_back_a_paper_channel_policys_figure_to_the_last_digit(
    tmp_path: Path,
) -> None:
    """tools/manifest_check.py on a folder with one paper-channel policy: its recorded figure
    comes back exactly (no transcendental numpy kernel in its loop differs between CPUs)."""
    import shutil

    for suffix in (".zip", ".onnx", ".json"):  # as shipped: the zip runs as its twin
        shutil.copy(ROOT / "policies" / f"no_move{suffix}", tmp_path / f"no_move{suffix}")
    [row] = run_json("manifest_check.py", "--policies", str(tmp_path))
    assert row["channel"] == "ar1" and row["episodes"] == 100
    assert row["now_mbps"] == row["recorded_mbps"] and row["diff_pct"] == 0.0


@pytest.mark.timeout(240)
def test_flight_parity_flies_a_seed_in_lockstep_onto_its_px4_motion_evaluation() -> None:
    result = run_json("flight_parity.py", "--seeds", "2")
    [row] = result["rows"]
    assert set(row) == {
        "seed",
        "evaluated_instant",
        "evaluated_px4",
        "flown_lockstep",
        "lockstep_timeouts",
    }
    assert row["lockstep_timeouts"] == 0
    assert result["summary"]["lockstep_vs_px4"]["equal"] == 1  # to the summary's six decimals


def test_figures_fingerprint_finds_the_same_figures_and_a_moved_one(tmp_path: Path) -> None:
    main = scripts.load_script("tools", "figures_fingerprint.py")["main"]
    assert len(main.__globals__["commands"]()) >= 40  # every shipped policy and baseline
    main.__globals__["commands"] = lambda: [
        ["--policy", "policies/circular.zip"],
        ["--policy", "aoa", "--scenario", "no_move"],
        ["--policy", "nowhere.zip"],
    ]  # a refusal is an output too
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["--out", str(tmp_path / "a"), "--json"]) == 0
        assert main(["--out", str(tmp_path / "b"), "--against", str(tmp_path / "a"), "--json"]) == 0
    first, again = (
        json.loads(chunk) for chunk in out.getvalue().replace("}\n{", "}\n\x00{").split("\x00")
    )
    assert first["commands"] == again["commands"] == 3 and again["differ"] == []
    figures = json.loads((tmp_path / "a" / "00.txt").read_text().split("\n--- stderr\n")[0])
    assert figures["episodes"] == 3 and figures["seed"] == 0 and figures["mean_rate_mbps"] > 0
    assert "uavlink evaluate: error" in (tmp_path / "a" / "02.txt").read_text()
    moved = tmp_path / "a" / "01.txt"
    moved.write_text(moved.read_text().replace('"mean_rate_mbps": ', '"mean_rate_mbps": 1'))
    with contextlib.redirect_stdout(io.StringIO()) as out:
        assert main(["--out", str(tmp_path / "c"), "--against", str(tmp_path / "a"), "--json"]) == 1
    assert json.loads(out.getvalue())["differ"] == ["01.txt"]
