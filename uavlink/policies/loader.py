"""Resolve what ``--policy`` names: a baseline, an SB3 zip, an ONNX file, or a folder of them."""

from __future__ import annotations

from pathlib import Path

from uavlink.config import MIXED, EnvConfig
from uavlink.policies.base import Policy
from uavlink.policies.manifest import PolicyFileError
from uavlink.policies.registry import BASELINES, make_baseline


def load_policy(spec: str | Path, cfg: EnvConfig) -> Policy:
    """A Policy for ``spec``; raises PolicyFileError / ValueError with a one-line message."""
    spec = str(spec)
    if spec in BASELINES:
        return make_baseline(spec, cfg)
    path = Path(spec)
    if path.is_dir():
        return load_policy(policy_for_scenario(path, cfg.scenario), cfg)
    if path.suffix == ".zip":
        from uavlink.policies.sb3_policy import SB3Policy

        return SB3Policy(path)
    if path.suffix == ".onnx":
        from uavlink.policies.onnx_policy import OnnxPolicy

        return OnnxPolicy(path)
    if not path.exists():
        raise PolicyFileError(
            f"{spec}: neither a baseline ({', '.join(BASELINES)}) nor an existing file"
        )
    raise PolicyFileError(f"{spec}: unknown policy file type (expected .zip or .onnx)")


def policy_for_scenario(folder: Path, scenario: str) -> Path:
    """``folder/<scenario>.zip`` (or .onnx), falling back to the mixed policy (``folder/mixed.zip``)."""
    found = policy_file(folder, scenario) or policy_file(folder, MIXED)
    if found is None:
        raise PolicyFileError(
            f"{folder}: no {scenario}.zip, {scenario}.onnx or {MIXED}.zip policy in this folder"
        )
    return found


def policy_file(folder: Path, name: str) -> Path | None:
    """``folder/<name>.zip``, else ``folder/<name>.onnx``; None when neither is a file."""
    return next((p for p in (folder / f"{name}.zip", folder / f"{name}.onnx") if p.is_file()), None)
