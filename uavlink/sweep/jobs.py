"""The job a worker runs: train PPO, evaluate it and the baselines, return bytes and figures.

``run_job`` takes and returns plain data (a job dict in; policy zip bytes, manifest and figures out),
so a worker needs no shared filesystem: the client writes ``runs/<sweep>/<job>/``. It pins torch to
one thread and seeds everything from the job, so the figures depend on the job's settings only, not
on the worker that ran it or how many ran beside it. ``write_job`` is the client's half.

Two environment variables, read on the worker, exist for tests and debugging and change no figure:
``UAVLINK_SWEEP_TRACE=DIR`` appends ``start|end KEY`` lines to ``DIR/<pid>.log``;
``UAVLINK_SWEEP_DELAY_S=S`` sleeps S seconds after the start line (to kill a worker mid-job).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import tempfile
import time
from pathlib import Path
from typing import Any

from uavlink.policies.manifest import file_sha256
from uavlink.sweep.spec import BASELINE_COLUMNS, Job

RESULT_FORMAT = "uavlink-sweep-result-v1"
# Result fields that describe the run, not its figures (they differ between workers and runs).
RUN_FIELDS = ("worker", "timing")


def run_job(job_data: dict[str, Any], snapshot_dir: str | None = None) -> dict[str, Any]:
    """Train and evaluate one job; returns the payload ``write_job`` stores. With ``snapshot_dir``
    (a folder this worker can write: the sweep's own on a local cluster) the training keeps a
    snapshot there, ``<job>.snapshot``, and a job that finds one continues from it to the same
    figures (uavlink/learn/snapshot.py): a sweep stopped mid-job loses a minute, not the job."""
    start, cpu_start = time.perf_counter(), time.process_time()
    job = Job.from_dict(job_data)
    _trace("start", job.key)
    delay = float(os.environ.get("UAVLINK_SWEEP_DELAY_S", "0") or 0)
    if delay > 0:
        time.sleep(delay)
    import torch

    torch.set_num_threads(1)
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.snapshot import can_snapshot
    from uavlink.learn.training import train
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.manifest import read_zip_manifest

    cfg, tc = job.env, job.train
    for name, digest in job.file_sha256.items():
        path = getattr(tc.warm_start, name)
        if file_sha256(Path(path)) != digest:
            raise RuntimeError(
                f"job {job.key}: {path} on this worker is not the warm_start.{name} file the "
                "job was made with"
            )
    with tempfile.TemporaryDirectory(prefix=f"uavlink-{job.key}-") as tmp:
        path = Path(tmp) / "policy.zip"
        t0 = time.perf_counter()
        snapshot = (
            Path(snapshot_dir) / f"{job.name}.snapshot"
            if snapshot_dir and can_snapshot(tc)
            else None
        )
        training = train(cfg, tc, path, run_dir=None, progress=False, snapshot=snapshot)
        train_s = time.perf_counter() - t0
        policy_bytes = path.read_bytes()
        manifest = read_zip_manifest(path)
        t0 = time.perf_counter()
        episodes, seed = job.eval["episodes"], job.eval["seed"]
        # The policy's env (its manifest's, without training-time randomisation); the baselines fly it too.
        columns = ("ppo", *BASELINE_COLUMNS)
        loaded = load_with_env([path, *BASELINE_COLUMNS], EnvOverrides())
        evaluation = {
            name: evaluate_policy(policy, env, episodes, seed).to_dict()
            for name, (policy, env) in zip(columns, loaded, strict=True)
        }
        eval_s = time.perf_counter() - t0
    _trace("end", job.key)
    return {
        "format": RESULT_FORMAT,
        "key": job.key,
        "name": job.name,
        "sweep": job.sweep,
        "scenario": job.scenario,
        "seed": job.seed,
        "point": job.point,
        "settings": job.settings(),
        "evaluation": evaluation,
        "training": {
            k: training[k]
            for k in ("total_timesteps", "steps_to_95pct_final", "learning_curve", "validation")
        },
        "versions": manifest.get("versions", {}),
        "worker": _worker_identity(),
        "timing": {
            "train_s": round(train_s, 3),
            "eval_s": round(eval_s, 3),
            "job_s": round(time.perf_counter() - start, 3),
            "cpu_s": round(time.process_time() - cpu_start, 3),
        },
        "policy_zip": policy_bytes,
    }


def figures(result: dict[str, Any]) -> dict[str, Any]:
    """The part of a result that must not depend on where or when the job ran."""
    return {k: v for k, v in result.items() if k not in (*RUN_FIELDS, "policy_zip")}


def write_job(sweep_dir: Path, payload: dict[str, Any]) -> Path:
    """Write ``<sweep_dir>/<job>/`` (policy.zip, policy.json manifest, result.json), atomically:
    the folder appears complete or not at all, and result.json marks it finished."""
    final = sweep_dir / payload["name"]
    tmp = sweep_dir / f".{payload['name']}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    (tmp / "policy.zip").write_bytes(payload["policy_zip"])
    from uavlink.policies.manifest import read_zip_manifest

    manifest = read_zip_manifest(tmp / "policy.zip")
    (tmp / "policy.json").write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    result = {k: v for k, v in payload.items() if k != "policy_zip"}
    (tmp / "result.json").write_text(json.dumps(result, indent=1) + "\n")
    if final.exists():
        shutil.rmtree(final)
    tmp.replace(final)
    return final


def result_path(sweep_dir: Path, job: Job) -> Path:
    """The job's result.json: once it is a file, the job is done (``write_job`` moves the whole folder
    into place)."""
    return sweep_dir / job.name / "result.json"


def read_result(sweep_dir: Path, job: Job) -> dict[str, Any] | None:
    path = result_path(sweep_dir, job)
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return None


def _worker_identity() -> dict[str, Any]:
    address = "in-process"
    try:
        from distributed import get_worker

        address = get_worker().address
    except (ImportError, ValueError):
        pass
    return {"address": address, "host": socket.gethostname(), "pid": os.getpid()}


def _trace(event: str, key: str) -> None:
    folder = os.environ.get("UAVLINK_SWEEP_TRACE")
    if folder:
        with open(Path(folder) / f"{os.getpid()}.log", "a") as handle:
            handle.write(f"{event} {key} {time.time():.3f}\n")
