"""Export a trained SB3 PPO policy zip to ONNX, for flying without torch (``uavlink export``).

The ONNX graph is the policy's deterministic actor as SB3's ``predict(deterministic=True)`` computes
it for a Box action space with ``squash_output=False``: actor MLP -> action_net (the Gaussian mean),
then clipped to the action space bounds, as SB3 does with ``np.clip`` after the network. It is the
zip runtime's own module (``SB3Policy.actor``, ``deterministic_actor``): float64 between a float32
input ``obs`` [batch, obs_size] and a float32 output ``action`` [batch, 2], so the two runtimes
return bit-identical actions and closed-loop evaluations of the two files coincide at every digit.
The batch dimension is dynamic. A policy trained with a privileged critic (``TrainConfig.critic``)
exports the same way: the graph is its actor alone, on the actor's observation. The policy manifest (observation layout, action mapping, env
config, training record) travels in the model's metadata under ``uavlink_manifest``, plus the
source zip's SHA-256.

Verification (on by default) rolls the SB3 policy itself through seeded episodes of the env its
manifest describes, collects the observations it met, and requires the runtime's actions
(``OnnxPolicy``, batched and one at a time) to equal SB3's float32 ``predict`` within ``TOLERANCE``
on every one of them; it also counts how many equal the zip runtime's (``SB3Policy.act``) exactly.
The file is written to a temporary name beside the target and renamed only after it verifies, so a
failed export leaves nothing behind (and an earlier file at the target intact).

Uses torch's TorchScript-based exporter (``dynamo=False``): the torch.export-based one needs
onnxscript, which the ``export`` extra does not install. Imports torch, SB3, onnx and onnxruntime.
"""

from __future__ import annotations

import io
import json
import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from uavlink.errors import UserError
from uavlink.policies.manifest import file_sha256
from uavlink.policies.onnx_policy import METADATA_KEY

__all__ = [
    "METADATA_KEY",
    "ExportVerificationError",
    "export_onnx",
    "format_report",
    "verification_observations",
    "verify_onnx",
]

INPUT_NAME = "obs"
OUTPUT_NAME = "action"
DEFAULT_OPSET = 17
TOLERANCE = 1e-5
SINGLE_CHECKS = 32  # observations also checked one at a time (batch 1, as the flight loop runs)


class ExportVerificationError(UserError):
    """The exported graph's actions differ from SB3's; nothing was written."""


def _to_onnx_bytes(actor: Any, obs_size: int, opset: int) -> bytes:
    """The torch module ``actor`` (``SB3Policy.actor``) as an ONNX model."""
    import torch

    buffer = io.BytesIO()
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore", DeprecationWarning)  # the TorchScript exporter's notice
        warnings.simplefilter("ignore", UserWarning)
        torch.onnx.export(
            actor,
            (torch.zeros(1, obs_size, dtype=torch.float32),),
            buffer,  # type: ignore[arg-type]  # typed as a path; the TorchScript exporter takes a file
            input_names=[INPUT_NAME],
            output_names=[OUTPUT_NAME],
            opset_version=opset,
            dynamic_axes={INPUT_NAME: {0: "batch"}, OUTPUT_NAME: {0: "batch"}},
            do_constant_folding=True,
            dynamo=False,
        )
    return buffer.getvalue()


def verification_observations(sb3_policy: Any, n: int, seed: int) -> np.ndarray:
    """``n`` observations (n, obs) float32 met by the policy itself in seeded episodes of its env
    (the ``EXPORT`` stream), step-major: every env's first observation, then every env's next one,
    so any prefix holds every env's first frames. Steps no further than it needs."""
    from uavlink.policies.contract import manifest_env
    from uavlink.rollout import chunks
    from uavlink.seeding import EXPORT

    cfg = manifest_env(sb3_policy.manifest)
    episodes = max(1, math.ceil(n / (cfg.episode_frames + 1)))
    batches, collected = [], 0
    for chunk in chunks(cfg, EXPORT, episodes, seed):
        batches.append(chunk.observation)
        collected += len(chunk.observation)
        frames = chunk.frames(sb3_policy)
        while collected < n and (frame := next(frames, None)) is not None:
            batches.append(frame.result.observation)
            collected += len(frame.result.observation)
        if collected >= n:
            break
    return np.concatenate(batches, axis=0)[:n].astype(np.float32)


def _sb3_input(model: Any, obs: np.ndarray) -> np.ndarray:
    """The actor's observations ``obs`` as SB3's ``predict`` takes them: a privileged critic's policy
    (uavlink/learn/privileged.py) reads more columns, its critic's, here zeros, which its actor
    never reads (its features are the first ``layout.size`` columns)."""
    extra = model.observation_space.shape[0] - obs.shape[1]
    return np.pad(obs, ((0, 0), (0, extra))) if extra else obs


def verify_onnx(
    onnx_path: Path, sb3_policy: Any, n: int = 1000, seed: int = 0, tolerance: float = TOLERANCE
) -> dict[str, Any]:
    """Compare the runtime's actions (``OnnxPolicy``, as flight loads it) with SB3's ``predict`` on
    ``n`` real observations, batched and the first ``SINGLE_CHECKS`` one at a time; raise
    ExportVerificationError beyond ``tolerance``. Also count the actions bit-identical to the zip's
    runtime (``SB3Policy.act``, what ``uavlink evaluate/fly`` run for the zip)."""
    from uavlink.policies.onnx_policy import OnnxPolicy

    obs = verification_observations(sb3_policy, n, seed)
    expected, _ = sb3_policy.model.predict(_sb3_input(sb3_policy.model, obs), deterministic=True)
    runtime = OnnxPolicy(onnx_path)
    got = runtime.act(obs)
    if got.shape != expected.shape or got.dtype != np.float32:
        raise ExportVerificationError(
            f"exported graph returns {got.dtype} {got.shape}, expected float32 {expected.shape}"
        )
    diff = np.abs(got.astype(np.float64) - expected)
    singles = min(SINGLE_CHECKS, n)
    single = np.concatenate([runtime.act(obs[i]) for i in range(singles)])
    max_diff = max(
        float(diff.max()), float(np.abs(single.astype(np.float64) - expected[:singles]).max())
    )
    if not np.isfinite(got).all() or max_diff > tolerance:
        worst = int(np.argmax(diff.max(axis=1)))
        raise ExportVerificationError(
            f"ONNX actions differ from SB3's by up to {max_diff:.3g} (tolerance {tolerance:g}) on "
            f"{n} observations; worst observation #{worst}: onnx {got[worst].tolist()} vs "
            f"sb3 {expected[worst].tolist()}"
        )
    identical = int(np.all(got == sb3_policy.act(obs), axis=1).sum())
    return {
        "n_observations": n,
        "n_single": singles,
        "max_abs_diff": max_diff,
        "tolerance": tolerance,
        "seed": seed,
        "n_identical_to_zip_runtime": identical,
    }


def export_onnx(
    zip_path: str | Path,
    out_path: str | Path,
    verify: bool = True,
    n_verify: int = 1000,
    seed: int = 0,
    opset: int = DEFAULT_OPSET,
) -> dict[str, Any]:
    """Write the policy zip's deterministic actor to ``out_path`` as ONNX; return what was done.

    Raises PolicyFileError for an unusable zip, ExportVerificationError when the graph's actions
    differ from SB3's; in both cases ``out_path`` is left untouched.
    """
    import onnx

    from uavlink.policies.sb3_policy import SB3Policy

    zip_path, out_path = Path(zip_path), Path(out_path)
    if opset < DEFAULT_OPSET:
        raise ValueError(f"opset must be {DEFAULT_OPSET} or newer, got {opset}")
    if verify and n_verify < 1:
        raise ValueError(f"n_verify must be a positive integer, got {n_verify}")
    sb3 = SB3Policy(zip_path)
    model = onnx.load_from_string(_to_onnx_bytes(sb3.actor, sb3.layout.size, opset))
    manifest = dict(sb3.manifest)
    manifest["exported_from"] = zip_path.name
    manifest["source_policy_sha256"] = file_sha256(zip_path)
    manifest["export"] = {
        "opset": opset,
        "input": INPUT_NAME,
        "output": OUTPUT_NAME,
        "action": "SB3 deterministic: Gaussian mean clipped to the action box",
        "precision": "float64 inside, float32 input and output",
    }
    del model.metadata_props[:]
    onnx.helper.set_model_props(model, {METADATA_KEY: json.dumps(manifest, sort_keys=True)})
    model.doc_string = (
        f"uavlink policy {zip_path.name}: obs [batch, {sb3.layout.size}] -> action [batch, 2]"
    )
    onnx.checker.check_model(model)

    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(f".{out_path.name}.{os.getpid()}.partial")
    try:
        with tmp.open("wb") as handle:
            handle.write(model.SerializeToString())
        check = verify_onnx(tmp, sb3, n_verify, seed) if verify else None
        tmp.replace(out_path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return {
        "source": str(zip_path),
        "out": str(out_path),
        "opset": opset,
        "size_bytes": out_path.stat().st_size,
        "obs_size": sb3.layout.size,
        "layout": sb3.layout.describe(),
        "source_policy_sha256": manifest["source_policy_sha256"],
        "verified": check is not None,
        "verification": check,
    }


def format_report(report: dict[str, Any]) -> str:
    """The lines ``uavlink export`` prints."""
    lines = [
        f"exported {report['source']} -> {report['out']} "
        f"(ONNX opset {report['opset']}, {report['size_bytes']:,} bytes)",
        f"  input obs float32 [batch, {report['obs_size']}], layout {report['layout']}; "
        f"output action float32 [batch, 2]",
    ]
    check = report["verification"]
    if check is None:
        lines.append("  not verified (--no-verify)")
    else:
        lines.append(
            f"  verified: {check['n_observations']} observations from seeded episodes "
            f"(seed {check['seed']}) batched, {check['n_single']} one at a time; "
            f"max |onnx - sb3 predict| = {check['max_abs_diff']:.2e} <= tolerance "
            f"{check['tolerance']:g}; {check['n_identical_to_zip_runtime']} of "
            f"{check['n_observations']} bit-identical to the zip's runtime (both float64)"
        )
    return "\n".join(lines)
