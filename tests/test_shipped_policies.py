"""The shipped policies as a user meets them: ``--policy`` by name (an existing file first, then a
baseline, then a shipped policy; one line says which file), the closest names for a typo,
``uavlink policies`` listing every one, and each zip's ONNX twin acting as the zip does."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support.cli import ROOT, assert_user_error, run_uavlink_in_process

from uavlink.config import EnvConfig
from uavlink.policies.loader import locate, shipped_note, shipped_policies, shipped_root
from uavlink.policies.manifest import PolicyFileError

SHIPPED_ZIPS = sorted((ROOT / "policies").rglob("*.zip"))


def test_the_checkout_ships_every_zip_with_an_onnx_twin_and_a_manifest() -> None:
    assert shipped_root() == ROOT / "policies"
    assert len(SHIPPED_ZIPS) == len(shipped_policies()) >= 27
    for path in SHIPPED_ZIPS:
        assert path.with_suffix(".onnx").is_file(), path
        assert path.with_suffix(".json").is_file(), path


def test_a_zip_runs_as_the_twin_exported_from_its_bytes_and_only_that_one(tmp_path) -> None:
    """Every shipped zip loads as its ONNX twin (the twin's manifest records the zip's sha256), so
    flying or evaluating one needs no torch; a zip beside a twin of other bytes runs in SB3, and
    `uavlink policies` lists that twin as stale."""
    from uavlink.cli.policies import policy_row
    from uavlink.policies.loader import load_policy
    from uavlink.policies.onnx_policy import OnnxPolicy
    from uavlink.policies.sb3_policy import SB3Policy

    cfg = EnvConfig()
    for path in SHIPPED_ZIPS:
        policy = load_policy(path, cfg)
        assert isinstance(policy, OnnxPolicy) and policy.name == path.stem, path
    (tmp_path / "circular.zip").write_bytes((ROOT / "policies" / "circular.zip").read_bytes())
    (tmp_path / "circular.onnx").write_bytes((ROOT / "policies" / "straight.onnx").read_bytes())
    assert isinstance(load_policy(tmp_path / "circular.zip", cfg), SB3Policy)
    (tmp_path / "circular.json").write_bytes((ROOT / "policies" / "circular.json").read_bytes())
    listed = policy_row("circular", tmp_path / "circular.zip")["runtimes"]
    assert listed == ["onnx: stale, uavlink export again", "sb3 [train]"]


@pytest.mark.parametrize(
    ("name", "file"),
    [
        ("circular", "circular.zip"),
        ("circular.zip", "circular.zip"),
        ("circular.onnx", "circular.onnx"),
        ("spatial/circular", "spatial/circular.zip"),
        ("map/no_move", "map/no_move.zip"),
        ("fleet/straight_180", "fleet/straight_180.zip"),
        ("policies/hotspot.zip", "hotspot.zip"),
        ("spatial", "spatial"),
    ],
)
def test_a_shipped_policy_by_name_from_any_folder(
    name: str, file: str, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    assert locate(name) == ROOT / "policies" / file
    assert capsys.readouterr().err == ""  # a Python caller gets the path, nothing on stderr
    line = shipped_note([name], [locate(name)])
    assert line == f"uavlink: --policy {name}: the shipped {ROOT / 'policies' / file}"


def test_an_existing_file_and_a_baseline_come_before_a_shipped_name(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "circular.zip").write_bytes(b"mine")
    assert locate("circular.zip") == "circular.zip"
    assert locate("aoa") == "aoa"
    assert capsys.readouterr().err == ""


def test_an_unknown_name_gets_the_closest_shipped_ones(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(PolicyFileError, match=r"closest: circular, map/circular, fleet/circular"):
        locate("circulr")
    proc = run_uavlink_in_process("fly", "--policy", "fleet/hotspt", "--out", str(tmp_path / "o"))
    assert_user_error(proc, "fleet/hotspt: no such file", "closest: fleet/hotspot")
    assert not (tmp_path / "o").exists()


def test_bad_input_beside_a_shipped_name_is_still_one_line(tmp_path: Path) -> None:
    """Which file a name became is said once the other inputs pass: before, `fly --policy circular
    --set nonsense=1` printed that line and then the error."""
    for command in ("fly", "evaluate"):
        args = [command, "--policy", "circular", "--set", "nonsense=1"]
        out = ["--out", str(tmp_path / "o")] if command == "fly" else []
        assert_user_error(run_uavlink_in_process(*args, *out), "unknown config key 'nonsense'")


def test_a_missing_path_is_no_such_file_and_no_name_is_guessed(tmp_path: Path) -> None:
    """A path (absolute, ./ or ~) is not looked up among the shipped names: before, /tmp/nope.zip
    was told its closest shipped policy was map/no_move."""
    for spec in (tmp_path / "nope.zip", "./nope.zip", "~/nope.zip"):
        with pytest.raises(PolicyFileError, match=r"nope.zip: no such file$"):
            locate(spec)


def test_uavlink_policies_lists_every_shipped_policy_with_its_manifest_figure() -> None:
    proc = run_uavlink_in_process("policies", "--json")
    assert proc.returncode == 0, proc.stderr
    rows = {row["name"]: row for row in json.loads(proc.stdout)}
    assert set(rows) == set(shipped_policies())
    hotspot = rows["fleet/hotspot"]
    manifest = json.loads((ROOT / "policies/fleet/hotspot.json").read_text())
    assert hotspot["n_uavs"] == 3 and hotspot["channel"] == "spatial"
    assert hotspot["fleet_sizes"] == [2, 3, 4] and rows["fleet_d2/hotspot"]["fleet_sizes"] is None
    assert hotspot["mean_rate_mbps"] == manifest["evaluation"]["hotspot"]["mean_rate_mbps"]
    assert hotspot["runtimes"] == ["onnx [fly]", "sb3 [train]"]
    assert rows["map/no_move"]["layout"] == 5
    table = run_uavlink_in_process("policies").stdout
    assert all(name in table for name in rows)


@pytest.mark.slow
@pytest.mark.parametrize("zip_path", SHIPPED_ZIPS, ids=lambda p: str(p.relative_to(ROOT)))
def test_each_onnx_twin_acts_as_its_zip(zip_path: Path) -> None:
    """On observations of the policy's own env (seeded episodes, random moves), the twin's actions
    equal the zip's to the last bit: both runtimes compute the actor in float64."""
    from uavlink.env.core import BatchedUavEnv
    from uavlink.policies.onnx_policy import OnnxPolicy
    from uavlink.policies.sb3_policy import SB3Policy

    zipped, twin = SB3Policy(zip_path), OnnxPolicy(zip_path.with_suffix(".onnx"))
    assert twin.layout == zipped.layout
    manifest = json.loads(zip_path.with_suffix(".json").read_text())
    cfg = EnvConfig.from_dict(manifest["env_config"])
    env = BatchedUavEnv(cfg, n_envs=16, seed=11)
    rng = np.random.default_rng(11)
    obs = env.reset()
    for _ in range(8):
        np.testing.assert_array_equal(twin.act(obs), zipped.act(obs))
        obs = env.step(rng.uniform(-1, 1, (obs.shape[0], 2)).astype(np.float32)).observation
