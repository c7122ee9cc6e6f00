"""Resolve what ``--policy`` names: a baseline, an SB3 zip, an ONNX file, or a folder of them."""

from __future__ import annotations

from pathlib import Path

from uavlink.config import EnvConfig
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
        raise PolicyFileError(f"{spec}: neither a baseline ({', '.join(BASELINES)}) nor an existing file")
    raise PolicyFileError(f"{spec}: unknown policy file type (expected .zip or .onnx)")


def policy_for_scenario(folder: Path, scenario: str) -> Path:
    """``folder/<scenario>.zip`` (or .onnx), falling back to ``folder/mixed.zip``."""
    for name in (scenario, "mixed"):
        for suffix in (".zip", ".onnx"):
            candidate = folder / f"{name}{suffix}"
            if candidate.is_file():
                return candidate
    raise PolicyFileError(f"{folder}: no {scenario}.zip, {scenario}.onnx or mixed.zip policy in this folder")
