"""The policy contract: a policy runs in the env its manifest records, with explicit overrides on top."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from support.cli import cli_json, run_uavlink_in_process

from uavlink.cli import main
from uavlink.config import EnvConfig, changed_settings, parse_settings
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.evaluation import evaluate_policy
from uavlink.policies.contract import (
    EnvOverrides,
    apply_overrides,
    check_policy_env,
    load_with_env,
    manifest_env,
    policy_env,
)
from uavlink.policies.manifest import (
    PolicyFileError,
    build_manifest,
    read_zip_manifest,
    write_zip_manifest,
)
from uavlink.policies.registry import baseline_env, make_baseline

ROOT = Path(__file__).resolve().parents[1]
POLAR = EnvConfig(scenario="straight", action_mapping="polar-v1", r_max_m=8.0)
SPELLED_OUT = ("--set", "action_mapping=polar-v1", "--set", "r_max_m=8")


def uavlink(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "uavlink.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )


def assert_refused(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    """Exit status 2, one line on stderr naming the problem, no traceback."""
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, (
        proc.stderr
    )
    assert all(fragment in proc.stderr for fragment in fragments), proc.stderr


def fake_policy(cfg: EnvConfig) -> SimpleNamespace:
    """What the contract reads of a loaded policy file: its manifest, layout and name."""
    return SimpleNamespace(
        manifest=build_manifest(cfg, {}),
        layout=ObservationLayout.for_config(cfg),
        name="fake",
        needs_truth=False,
    )


def test_the_manifest_decides_the_env_and_training_randomisation_stays_behind() -> None:
    trained = POLAR.replace(**{"radio.aoa_noise_deg": 2.0, "radio.aoa_noise_max_deg": 40.0})
    env = manifest_env(build_manifest(trained, {}))
    assert env == trained.replace(**{"radio.aoa_noise_max_deg": 0.0})
    asked = apply_overrides(
        env, EnvOverrides(settings={"radio.aoa_noise_max_deg": 40.0}), built_for="p.zip"
    )
    assert asked.radio.aoa_noise_max_deg == 40.0
    assert manifest_env(None) == EnvConfig()


def test_overrides_go_on_top_and_what_the_policy_was_built_for_is_refused() -> None:
    policy = fake_policy(POLAR)
    cfg = policy_env(
        policy, EnvOverrides("circular", 5.0, {"radio.shadowing": False, "tx_power_dbm": 25})
    )
    assert (cfg.scenario, cfg.radio.aoa_noise_deg, cfg.radio.shadowing, cfg.radio.tx_power_dbm) == (
        "circular",
        5.0,
        False,
        25,
    )
    assert (cfg.action_mapping, cfg.r_max_m) == ("polar-v1", 8.0)
    same = {
        "action_mapping": "polar-v1",
        "r_max_m": 8,
    }  # spelling out the policy's own values is fine
    assert policy_env(policy, EnvOverrides(settings=same)) == policy_env(policy, EnvOverrides())
    for key, value, built in [
        ("action_mapping", "cartesian-v1", "action_mapping='polar-v1'"),
        ("r_max_m", 12, "r_max_m=8.0"),
        ("memory", 2, "memory=4"),
        ("n_ues", 5, "n_ues=10"),
        ("half_width_m", 100, "area.half_width_m=200.0"),
    ]:
        with pytest.raises(UserError) as info:
            policy_env(policy, EnvOverrides(settings={key: value}), source="policies/x.zip")
        assert str(info.value) == (
            f"policy policies/x.zip was built for {built}; --set {key}={value} "
            f"conflicts (drop the --set)"
        )
    with pytest.raises(
        UserError, match="unknown action mapping"
    ):  # baselines: any mapping, if it exists
        apply_overrides(EnvConfig(), EnvOverrides(settings={"action_mapping": "spherical"}))
    with pytest.raises(
        UserError, match="ten"
    ):  # a value of the wrong type: still a one-line UserError
        apply_overrides(EnvConfig(), EnvOverrides(settings={"n_ues": "ten"}))


@pytest.mark.parametrize(
    ("change", "built", "asked"),
    [
        ({"r_max_m": 6}, "r_max_m=8.0", "6.0"),
        ({"action_mapping": "cartesian-v1"}, "action_mapping='polar-v1'", "'cartesian-v1'"),
    ],
)
def test_evaluate_policy_refuses_a_policy_file_outside_what_it_was_built_for(
    change, built, asked
) -> None:
    policy = fake_policy(POLAR)  # refused before it would fly a frame
    with pytest.raises(UserError) as info:
        evaluate_policy(policy, POLAR.replace(**change), episodes=1)
    assert str(info.value) == (
        f"policy 'fake' was built for {built}, not {asked}; evaluate it in the env its "
        f"manifest records: uavlink.policies.contract.load_with_env(['path'], "
        f"EnvOverrides()) gives (policy, env)"
    )
    # The contract's one check, as the CLI's: the world may change, what the policy reads may not.
    check_policy_env(
        policy,
        POLAR.replace(
            **{
                "scenario": "circular",
                "radio.shadowing_std_db": 4.0,
                "radio.aoa_noise_deg": 5.0,
                "r_max_m": 8,
            }
        ),
    )
    with pytest.raises(
        UserError,
        match=r"observation layout mismatch: policy 'fake' expects .*memory=4.*"
        r"memory=2.*; evaluate it in the env its manifest records",
    ):
        check_policy_env(policy, POLAR.replace(memory=2))
    policy.path = Path("policies/x.zip")  # a loaded file names its path
    with pytest.raises(UserError, match=r"load_with_env\(\['policies/x.zip'\], EnvOverrides\(\)\)"):
        check_policy_env(policy, POLAR.replace(r_max_m=6))


def test_evaluate_policy_points_a_baseline_to_its_env() -> None:
    cfg = EnvConfig(scenario="no_move")
    explore = make_baseline(
        "explore", cfg
    )  # built for baseline_env("explore", cfg): a memory of place
    with pytest.raises(UserError) as info:
        evaluate_policy(explore, cfg, episodes=1)
    message = str(info.value)
    assert (
        message.startswith("observation layout mismatch: policy 'explore' expects v3")
        and "\n" not in message
    )
    assert message.endswith(
        "; evaluate a baseline made for a world, make_baseline('explore', world), in "
        "uavlink.policies.registry.baseline_env('explore', world)"
    )
    check_policy_env(explore, baseline_env("explore", cfg))
    check_policy_env(
        make_baseline("aoa", cfg), cfg.replace(r_max_m=6)
    )  # no manifest: nothing built for
    check_policy_env(
        make_baseline("static", cfg), cfg.replace(memory=2)
    )  # reads no observation layout


def test_a_manifest_whose_layout_disagrees_with_its_env_is_a_policy_file_error() -> None:
    policy = fake_policy(POLAR)
    policy.layout = ObservationLayout.for_config(POLAR.replace(memory=3))
    with pytest.raises(PolicyFileError, match="x.zip: observation layout mismatch"):
        policy_env(policy, EnvOverrides(), source="x.zip")


def test_a_baseline_alone_gets_the_defaults_plus_the_overrides() -> None:
    [(policy, cfg)] = load_with_env(["aoa"], EnvOverrides("hotspot", 3.0, {"r_max_m": 6}))
    assert cfg == EnvConfig(scenario="hotspot", r_max_m=6).replace(aoa_noise_deg=3.0)
    assert policy.mapping.r_max_m == 6


def test_changed_settings_round_trip_through_set_pairs() -> None:
    cfg = POLAR.replace(
        **{"radio.shadowing": False, "area.uav_altitude_m": 80.5, "radio.aoa_noise_deg": 0.1}
    )
    pairs = changed_settings(cfg)
    assert sorted(pairs) == [
        'action_mapping="polar-v1"',
        "area.uav_altitude_m=80.5",
        "r_max_m=8.0",
        "radio.aoa_noise_deg=0.1",
        "radio.shadowing=false",
        'scenario="straight"',
    ]
    assert EnvConfig().replace(**parse_settings(pairs)) == cfg
    assert changed_settings(EnvConfig()) == []


@pytest.fixture(scope="module")
def polar_zip(tmp_path_factory) -> Path:
    """A tiny PPO policy trained with the polar mapping and r_max 8 m (about 15 s)."""
    folder = tmp_path_factory.mktemp("polar")
    out = folder / "polar.zip"
    # in this process: the CLI's own code path without a child's torch import
    assert (
        main(
            [
                "train",
                "--scenario",
                "straight",
                *SPELLED_OUT,
                "--out",
                str(out),
                "--episodes",
                "64",
                "--n-envs",
                "8",
                "--eval-episodes",
                "0",
                "--no-progress",
                "--run-dir",
                str(folder / "run"),
            ]
        )
        == 0
    )
    return out


def evaluate(policy: Path | str, *args: str, episodes: int = 8, seed: int = 5) -> dict:
    """``uavlink evaluate --json`` in this process (the CLI's own code path, without a torch import each)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(
            [
                "evaluate",
                "--policy",
                str(policy),
                "--scenario",
                "straight",
                "--episodes",
                str(episodes),
                "--seed",
                str(seed),
                "--json",
                *args,
            ]
        )
    assert rc == 0
    return json.loads(out.getvalue())


@pytest.mark.slow
def test_evaluate_runs_the_policy_in_its_own_env(polar_zip: Path) -> None:
    implicit, spelled = evaluate(polar_zip), evaluate(polar_zip, *SPELLED_OUT)
    print(
        f"\npolar-v1 r_max 8 policy, 8 episodes seed 5: {implicit['mean_rate_mbps']:.3f} Mbps without "
        f"--set, {spelled['mean_rate_mbps']:.3f} Mbps with its settings spelled out"
    )
    assert implicit["episode_rate_mbps"] == spelled["episode_rate_mbps"]
    assert_refused(
        run_uavlink_in_process(
            "evaluate",
            "--policy",
            str(polar_zip),
            "--episodes",
            "2",
            "--set",
            "action_mapping=cartesian-v1",
        ),
        f"policy {polar_zip} was built for action_mapping='polar-v1'",
        "--set action_mapping=cartesian-v1 conflicts",
    )
    quiet = evaluate(polar_zip, "--set", "radio.shadowing=false", "--set", "fast_fading=false")
    assert quiet["episode_rate_mbps"] != implicit["episode_rate_mbps"]  # radio physics may change


@pytest.mark.slow
def test_baselines_under_against_fly_the_policy_env(polar_zip: Path) -> None:
    against = evaluate(polar_zip, "--against", "aoa")["results"][1]
    assert against["episode_rate_mbps"] == evaluate("aoa", *SPELLED_OUT)["episode_rate_mbps"]
    assert against["episode_rate_mbps"] != evaluate("aoa")["episode_rate_mbps"]  # r_max 8, not 12


@pytest.mark.slow
def test_training_randomisation_is_not_carried_into_evaluation(
    polar_zip: Path, tmp_path: Path
) -> None:
    randomised = tmp_path / "randomised.zip"
    randomised.write_bytes(polar_zip.read_bytes())
    manifest = read_zip_manifest(randomised)
    manifest["env_config"]["radio"]["aoa_noise_max_deg"] = 60.0
    write_zip_manifest(randomised, manifest)
    plain = evaluate(polar_zip)["episode_rate_mbps"]
    assert evaluate(randomised)["episode_rate_mbps"] == plain
    assert evaluate(randomised, "--set", "radio.aoa_noise_max_deg=60")["episode_rate_mbps"] != plain


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_fly_and_the_embedded_sitl_run_the_policy_env(polar_zip: Path, tmp_path: Path) -> None:
    # fly's loop in this process (its vehicle is a child as always): no second torch import
    flown = cli_json(
        "fly",
        "--no-picture",
        "--policy",
        str(polar_zip),
        "--scenario",
        "straight",
        "--seed",
        "5",
        "--json",
        "--quiet",
        "--out",
        str(tmp_path),
    )
    simulated = evaluate(polar_zip, episodes=1)["mean_rate_mbps"]
    print(
        f"\npolar-v1 r_max 8 policy, straight seed 5: flown {flown['mean_rate_mbps']:.3f} Mbps, "
        f"evaluated {simulated:.3f} Mbps"
    )
    assert flown["frames"] == 128 and flown["guarded_actions"] == 0
    assert abs(flown["mean_rate_mbps"] - simulated) <= 0.05 * simulated
    assert_refused(
        run_uavlink_in_process(
            "fly", "--policy", str(polar_zip), "--set", "r_max_m=12", "--out", str(tmp_path)
        ),
        "was built for r_max_m=8",
        "--set r_max_m=12 conflicts",
    )


def test_the_sitl_radio_payload_simulates_the_set_pairs_fly_passes() -> None:
    from sitl_stub.__main__ import build_parser
    from sitl_stub.sim.payload import PayloadOptions
    from sitl_stub.sim.radio_payload import RadioPayload

    for changes in (
        {"radio.shadowing": False, "radio.tx_power_dbm": 25.0},
        {"radio.shadowing_model": "spatial"},
    ):  # a spatial-channel policy's embedded SITL
        cfg = POLAR.replace(**changes)
        args = build_parser().parse_args(
            [arg for pair in changed_settings(cfg) for arg in ("--set", pair)]
        )
        payload = RadioPayload(PayloadOptions("straight", 5, 0.0, tuple(args.settings)))
        assert payload.cfg == cfg


def test_a_plain_sb3_zip_without_a_manifest_is_refused(tmp_path: Path) -> None:
    """SB3Policy's docstring: a ``model.save()`` zip (here a shipped policy less its manifest) is refused."""
    import zipfile

    from uavlink.policies.sb3_policy import SB3Policy

    plain = tmp_path / "plain.zip"
    with (
        zipfile.ZipFile(ROOT / "policies/circular.zip") as shipped,
        zipfile.ZipFile(plain, "w") as out,
    ):
        for info in shipped.infolist():
            if info.filename != "uavlink_manifest.json":
                out.writestr(info, shipped.read(info))
    SB3Policy(ROOT / "policies/circular.zip")  # the same weights with their manifest load
    with pytest.raises(
        PolicyFileError, match="zip has no uavlink_manifest.json; not a uavlink policy"
    ):
        SB3Policy(plain)
