"""ONNX export (``uavlink export``) and the torch-free ONNX policy runtime."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper

from uavlink.cli import main
from uavlink.config import EnvConfig
from uavlink.evaluation import evaluate_policy
from uavlink.export import (
    METADATA_KEY,
    ExportVerificationError,
    export_onnx,
    verification_observations,
)
from uavlink.policies.loader import load_policy
from uavlink.policies.manifest import PolicyFileError, file_sha256, read_zip_manifest
from uavlink.policies.onnx_policy import OnnxPolicy
from uavlink.policies.sb3_policy import SB3Policy

ROOT = Path(__file__).resolve().parent.parent
pytestmark = pytest.mark.slow  # the tiny trained policy, ONNX exports of every shipped policy

CFG = EnvConfig(scenario="straight")  # the tiny policy's env

BLOCKER = '''
import os, sys

class _BlockTorch:
    """Refuse torch and stable_baselines3, and log who tried."""

    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "stable_baselines3"):
            with open(os.environ["UAVLINK_BLOCK_LOG"], "a") as log:
                log.write(name + "\\n")
            raise ImportError(f"{name} is blocked in this test")
        return None

sys.meta_path.insert(0, _BlockTorch())
'''


@pytest.fixture(scope="module")
def policy_zip(tiny_policy_zip: Path, tmp_path_factory) -> Path:
    """A copy of the session's tiny policy (tests/conftest.py), exported beside it."""
    out = tmp_path_factory.mktemp("policy") / "tiny.zip"
    shutil.copyfile(tiny_policy_zip, out)
    return out


@pytest.fixture(scope="module")
def exported(policy_zip: Path) -> tuple[Path, dict]:
    out = policy_zip.with_name("tiny.onnx")
    return out, export_onnx(policy_zip, out, verify=True, n_verify=1000, seed=0)


@pytest.mark.slow
def test_export_verifies_parity_on_1000_real_observations(policy_zip: Path, exported) -> None:
    path, report = exported
    check = report["verification"]
    assert report["verified"] and check["n_observations"] == 1000
    assert check["max_abs_diff"] <= 1e-5 and check["tolerance"] == 1e-5
    assert report["size_bytes"] == path.stat().st_size and report["opset"] >= 17
    # Independently: the runtime policy against SB3 on other real observations, batched and singly.
    sb3, onnx_policy = SB3Policy(policy_zip), OnnxPolicy(path)
    obs = verification_observations(sb3, 1000, seed=7)
    assert obs.shape == (1000, 60) and obs.dtype == np.float32
    expected = sb3.act(obs)
    got = onnx_policy.act(obs)
    assert got.shape == (1000, 2) and got.dtype == np.float32
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-5)
    singles = np.concatenate([onnx_policy.act(obs[i]) for i in range(50)])
    np.testing.assert_allclose(singles, expected[:50], rtol=0, atol=1e-5)


@pytest.mark.slow
def test_graph_signature(exported) -> None:
    model = onnx.load(str(exported[0]))
    onnx.checker.check_model(model)
    assert max(op.version for op in model.opset_import if op.domain in ("", "ai.onnx")) >= 17
    (given,), (out,) = model.graph.input, model.graph.output
    assert given.name == "obs" and out.name == "action"
    assert given.type.tensor_type.elem_type == TensorProto.FLOAT
    in_dims = [d.dim_param or d.dim_value for d in given.type.tensor_type.shape.dim]
    out_dims = [d.dim_param or d.dim_value for d in out.type.tensor_type.shape.dim]
    assert isinstance(in_dims[0], str) and in_dims[1] == 60  # dynamic batch
    assert isinstance(out_dims[0], str) and out_dims[1] == 2
    policy = OnnxPolicy(exported[0])
    batch = np.zeros((5, 60), dtype=np.float32)
    assert policy.act(batch).shape == (5, 2)


@pytest.mark.slow
def test_clip_to_the_action_box_is_in_the_graph(policy_zip: Path, tmp_path: Path) -> None:
    """SB3 clips the Gaussian mean to [-1, 1] after the network; the graph must do the same."""
    import torch
    from stable_baselines3 import PPO

    from uavlink.policies.manifest import write_zip_manifest

    model = PPO.load(policy_zip, device="cpu")
    with torch.no_grad():
        model.policy.action_net.bias += torch.tensor(
            [1.0, -1.0]
        )  # push part of the means out of the box
    biased = tmp_path / "biased.zip"
    model.save(biased)
    write_zip_manifest(biased, read_zip_manifest(policy_zip))
    report = export_onnx(biased, tmp_path / "biased.onnx", n_verify=300)
    assert report["verification"]["max_abs_diff"] <= 1e-5
    obs = verification_observations(SB3Policy(biased), 300, seed=1)
    actions = OnnxPolicy(tmp_path / "biased.onnx").act(obs)
    assert actions.min() >= -1.0 and actions.max() <= 1.0
    assert (np.abs(actions) == 1.0).any() and (np.abs(actions) < 1.0).any()


@pytest.mark.slow
def test_evaluation_throughput_equals_the_zip(policy_zip: Path, exported) -> None:
    zipped = evaluate_policy(SB3Policy(policy_zip), CFG, episodes=8, seed=3)
    onnxed = evaluate_policy(load_policy(exported[0], CFG), CFG, episodes=8, seed=3)
    # Both runtimes compute the actor in float64: identical actions, identical trajectories.
    np.testing.assert_array_equal(onnxed.episode_rate_mbps, zipped.episode_rate_mbps)
    np.testing.assert_array_equal(onnxed.episode_fair_rate, zipped.episode_fair_rate)


@pytest.mark.slow
def test_manifest_round_trips_through_metadata(policy_zip: Path, exported) -> None:
    path, report = exported
    source = read_zip_manifest(policy_zip)
    meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    embedded = json.loads(meta[METADATA_KEY])
    assert (
        embedded["source_policy_sha256"]
        == file_sha256(policy_zip)
        == report["source_policy_sha256"]
    )
    assert embedded["exported_from"] == "tiny.zip"
    for key, value in source.items():
        assert embedded[key] == value, key
    policy = OnnxPolicy(path)
    assert policy.manifest == embedded and policy.name == "tiny" and not policy.needs_truth
    assert policy.layout == SB3Policy(policy_zip).layout


@pytest.mark.slow
def test_not_onnx_files_are_refused(policy_zip: Path, tmp_path: Path) -> None:
    noise = tmp_path / "noise.onnx"
    noise.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(PolicyFileError, match="noise.onnx: not a loadable ONNX model"):
        OnnxPolicy(noise)
    renamed = tmp_path / "renamed.onnx"
    renamed.write_bytes(policy_zip.read_bytes())
    with pytest.raises(PolicyFileError, match="renamed.onnx: is a zip archive, not an ONNX model"):
        load_policy(renamed, CFG)
    with pytest.raises(PolicyFileError, match="missing.onnx: no such file$"):
        load_policy(tmp_path / "missing.onnx", CFG)


def _tiny_model(n_inputs: int, metadata: dict[str, str]) -> onnx.ModelProto:
    obs = helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", n_inputs])
    action = helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", 2])
    weight = helper.make_tensor("w", TensorProto.FLOAT, [n_inputs, 2], [0.0] * (2 * n_inputs))
    graph = helper.make_graph(
        [helper.make_node("MatMul", ["obs", "w"], ["action"])], "tiny", [obs], [action], [weight]
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    helper.set_model_props(model, metadata)
    return model


def test_foreign_onnx_without_manifest_is_refused(tmp_path: Path) -> None:
    onnx.save(_tiny_model(60, {}), str(tmp_path / "foreign.onnx"))
    with pytest.raises(PolicyFileError, match="no 'uavlink_manifest' metadata"):
        OnnxPolicy(tmp_path / "foreign.onnx")


@pytest.mark.slow
def test_wrong_input_shape_is_refused(exported, tmp_path: Path) -> None:
    manifest = OnnxPolicy(exported[0]).session.get_modelmeta().custom_metadata_map[METADATA_KEY]
    onnx.save(_tiny_model(60, {METADATA_KEY: manifest}), str(tmp_path / "right.onnx"))
    assert OnnxPolicy(tmp_path / "right.onnx").act(np.zeros((1, 60), np.float32)).shape == (1, 2)
    onnx.save(_tiny_model(59, {METADATA_KEY: manifest}), str(tmp_path / "wrong.onnx"))
    with pytest.raises(
        PolicyFileError, match=r"wrong.onnx: model input 'obs' .*59.* layout .*size=60"
    ):
        OnnxPolicy(tmp_path / "wrong.onnx")


@pytest.mark.slow
@pytest.mark.parametrize("change", [{"n_ues": 5}, {"memory": 3}])
def test_layout_mismatch_is_refused_naming_both(exported, change: dict) -> None:
    policy = OnnxPolicy(exported[0])
    cfg = CFG.replace(**change)
    with pytest.raises(ValueError, match="observation layout mismatch") as info:
        evaluate_policy(policy, cfg, episodes=1)
    message = str(info.value)
    assert policy.layout.describe() in message
    from uavlink.env.observation import ObservationLayout

    assert ObservationLayout.for_config(cfg).describe() in message


@pytest.mark.slow
def test_failed_verification_leaves_nothing(policy_zip: Path, tmp_path: Path, monkeypatch) -> None:
    import torch

    import uavlink.export as export

    original = export._to_onnx_bytes

    def skewed(actor, obs_size, opset):
        class Skewed(torch.nn.Module):
            def __init__(self) -> None:
                super().__init__()
                self.actor = actor

            def forward(self, obs):
                return self.actor(obs) + 1e-3

        return original(Skewed().eval(), obs_size, opset)

    monkeypatch.setattr(export, "_to_onnx_bytes", skewed)
    out = tmp_path / "kept.onnx"
    out.write_bytes(b"previous export")
    with pytest.raises(
        ExportVerificationError, match=r"differ from SB3's by up to .* \(tolerance 1e-05\)"
    ):
        export_onnx(policy_zip, out, n_verify=100)
    assert out.read_bytes() == b"previous export"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.onnx"]


@pytest.mark.slow
def test_cli_default_out_and_help(policy_zip: Path, tmp_path: Path, capsys) -> None:
    copy = tmp_path / "copy.zip"
    copy.write_bytes(policy_zip.read_bytes())
    assert main(["export", str(copy), "--no-verify"]) == 0
    assert (tmp_path / "copy.onnx").is_file() and "not verified" in capsys.readouterr().out
    assert main(["export", str(copy), "--out", str(tmp_path / "x.zip")]) == 2
    assert "must end in .onnx" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        main(["export", "--help"])
    assert info.value.code == 0 and "--no-verify" in capsys.readouterr().out


def _run(
    args: list[str], env: dict | None = None, cwd: Path | None = None
) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *args],
        capture_output=True,
        text=True,
        timeout=180,
        env=env,
        cwd=cwd or ROOT,
    )


@pytest.mark.slow
def test_cli_export_prints_what_it_checked(policy_zip: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "cli.onnx"
    assert (
        main(["export", str(policy_zip), "--out", str(out)]) == 0
    )  # in this process: no torch import
    done = capsys.readouterr()
    assert "verified: 1000 observations" in done.out and "tolerance 1e-05" in done.out
    assert "opset 17" in done.out and f"{out.stat().st_size:,} bytes" in done.out
    missing = _run(["-m", "uavlink.cli", "export", str(tmp_path / "missing.zip")])
    assert missing.returncode == 2
    assert missing.stderr.strip().count("\n") == 0 and "Traceback" not in missing.stderr
    assert missing.stderr.rstrip().endswith("missing.zip: no such file")


@pytest.mark.slow
def test_onnx_policy_runs_with_torch_and_sb3_blocked(exported, tmp_path: Path) -> None:
    path = exported[0]
    (tmp_path / "sitecustomize.py").write_text(BLOCKER)
    log = tmp_path / "blocked.log"
    env = {
        **os.environ,
        "PYTHONPATH": f"{tmp_path}{os.pathsep}{ROOT}",
        "UAVLINK_BLOCK_LOG": str(log),
    }
    snippet = textwrap.dedent(f"""
        import sys
        import numpy as np
        try:
            import torch
        except ImportError:
            pass
        else:
            raise SystemExit("the import blocker is not active")
        open({str(log)!r}, "w").close()  # from here on, any attempt is a failure
        from uavlink.config import EnvConfig
        from uavlink.evaluation import evaluate_policy
        from uavlink.policies.loader import load_policy
        from uavlink.policies.onnx_policy import OnnxPolicy
        policy = OnnxPolicy({str(path)!r})
        action = policy.act(np.zeros(60, dtype=np.float32))
        assert action.shape == (1, 2) and np.abs(action).max() <= 1
        cfg = EnvConfig(scenario="no_move")
        result = evaluate_policy(load_policy({str(path)!r}, cfg), cfg, episodes=2)
        assert "torch" not in sys.modules and "stable_baselines3" not in sys.modules
        print("ok", round(result.mean_rate_mbps, 3))
    """)
    done = _run(["-c", snippet], env=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("ok ")
    assert log.read_text() == "", f"tried to import: {log.read_text()}"

    script = Path(sys.executable).with_name("uavlink")  # the installed console script
    command = [str(script)] if script.is_file() else [sys.executable, "-m", "uavlink.cli"]
    cli = subprocess.run(
        [
            *command,
            "evaluate",
            "--policy",
            str(path),
            "--scenario",
            "no_move",
            "--episodes",
            "2",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=180,
        env=env,
        cwd=tmp_path,
    )
    assert cli.returncode == 0, cli.stderr
    assert json.loads(cli.stdout)["policy"] == "tiny"
    assert log.read_text() == "", f"tried to import: {log.read_text()}"


SHIPPED = sorted((Path(__file__).resolve().parents[1] / "policies").glob("*.zip"))


@pytest.mark.slow
@pytest.mark.parametrize("zip_path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_every_shipped_policy_exports_with_parity(zip_path: Path, tmp_path: Path) -> None:
    """Each committed policy: ONNX agrees with SB3's predict to 1e-5 on 1,000 real observations and
    with the zip's runtime bit for bit (both compute in float64), so the 100-episode evaluation of
    the two files is the same at every digit, not just the printed ones."""
    report = export_onnx(zip_path, tmp_path / "p.onnx", verify=True, n_verify=1000)
    check = report["verification"]
    assert check["max_abs_diff"] <= 1e-5 and check["n_identical_to_zip_runtime"] == 1000
    cfg = EnvConfig.from_dict(read_zip_manifest(zip_path)["env_config"])
    if cfg.scenario == "mixed":
        cfg = cfg.replace(scenario="hotspot")
    onnx_result = evaluate_policy(OnnxPolicy(tmp_path / "p.onnx"), cfg, episodes=100, seed=0)
    zip_result = evaluate_policy(SB3Policy(zip_path), cfg, episodes=100, seed=0)
    print(
        f"\n{zip_path.stem}: zip {zip_result.mean_rate_mbps:.3f} Mbps, onnx {onnx_result.mean_rate_mbps:.3f} "
        f"Mbps, max |onnx - sb3 predict| {check['max_abs_diff']:.1e}"
    )
    np.testing.assert_array_equal(onnx_result.episode_rate_mbps, zip_result.episode_rate_mbps)
    np.testing.assert_array_equal(onnx_result.episode_fair_rate, zip_result.episode_fair_rate)


@pytest.mark.slow
def test_verification_observations_are_the_export_streams_frames_step_major() -> None:
    """Every env's first observation, then every env's next one, from the EXPORT stream's episodes
    flown by the policy itself; n = 300 with 128-frame episodes takes 3 envs and 99 steps."""
    from uavlink.env.core import BatchedUavEnv
    from uavlink.seeding import EXPORT

    sb3 = SB3Policy(ROOT / "policies" / "circular.zip")
    obs = verification_observations(sb3, 300, seed=4)
    env = BatchedUavEnv(
        EnvConfig.from_dict(sb3.manifest["env_config"]), n_envs=3, seed=EXPORT.seed(4)
    )
    first = env.reset()
    np.testing.assert_array_equal(obs[:3], first)
    np.testing.assert_array_equal(obs[3:6], env.step(sb3.act(first)).observation)
    assert obs.shape == (300, sb3.layout.size) and obs.dtype == np.float32
    assert not np.array_equal(verification_observations(sb3, 3, seed=5), obs[:3])
