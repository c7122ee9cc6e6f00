"""An exported ONNX policy behind the Policy interface, run by onnxruntime alone.

Needs neither torch nor stable-baselines3 (the ``fly`` extra installs numpy and onnxruntime only),
and must not import them, even indirectly. The model comes from ``uavlink export``: input ``obs``
float32 [batch, obs_size], output ``action`` float32 [batch, 2] in [-1, 1], the policy manifest in
the model metadata under ``uavlink_manifest``. The session is tuned for one observation per
decision: one thread, sequential execution, names pre-bound.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import numpy as np

from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.policies.manifest import PolicyFileError, check_manifest

METADATA_KEY = "uavlink_manifest"  # where `uavlink export` stores the manifest
_ZIP_MAGIC = b"PK\x03\x04"


def session_options():
    """onnxruntime options for low-latency single-observation inference on one core."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.enable_cpu_mem_arena = True
    options.log_severity_level = 3  # errors only: no warnings on stderr in flight
    return options


class OnnxPolicy:
    """A policy exported with ``uavlink export``; clear PolicyFileErrors for unusable files."""

    needs_truth = False

    def __init__(self, path: str | Path) -> None:
        import onnxruntime as ort

        path = Path(path)
        if not path.is_file():
            raise PolicyFileError(f"{path}: no such policy file")
        with path.open("rb") as handle:
            head = handle.read(4)
        if head == _ZIP_MAGIC:
            raise PolicyFileError(
                f"{path}: is a zip archive, not an ONNX model (an SB3 policy zip? "
                f"load it as .zip or convert it with `uavlink export`)"
            )
        try:
            self.session = ort.InferenceSession(
                str(path), session_options(), providers=["CPUExecutionProvider"]
            )
        except Exception as exc:  # onnxruntime raises its own Fail/InvalidProtobuf/... kinds
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise PolicyFileError(f"{path}: not a loadable ONNX model ({reason})") from None
        self.manifest = self._read_manifest(path)
        self.layout = ObservationLayout.from_dict(self.manifest["observation_layout"])
        self.name = path.stem
        self._check_signature(path)
        self._input_name = self.session.get_inputs()[0].name
        self._output_names = [self.session.get_outputs()[0].name]
        self._run = self.session.run
        # Batch-1 fast path (the flight loop): input and output buffers bound once; a call copies
        # the observation in, runs, and copies the two numbers out. The lock keeps it thread-safe.
        self._obs1 = np.zeros((1, self.layout.size), dtype=np.float32)
        self._action1 = np.zeros((1, 2), dtype=np.float32)
        self._bound = (
            ort.OrtValue.ortvalue_from_numpy(self._obs1),  # views of the buffers
            ort.OrtValue.ortvalue_from_numpy(self._action1),
        )
        self._binding = self.session.io_binding()
        self._binding.bind_ortvalue_input(self._input_name, self._bound[0])
        self._binding.bind_ortvalue_output(self._output_names[0], self._bound[1])
        self._run_bound = self.session.run_with_iobinding
        self._lock = threading.Lock()

    def _read_manifest(self, path: Path) -> dict[str, Any]:
        raw = self.session.get_modelmeta().custom_metadata_map.get(METADATA_KEY)
        if raw is None:
            raise PolicyFileError(
                f"{path}: ONNX model has no {METADATA_KEY!r} metadata; not a "
                f"uavlink policy (export one with `uavlink export POLICY.zip`)"
            )
        try:
            manifest = json.loads(raw)
        except json.JSONDecodeError as exc:
            raise PolicyFileError(
                f"{path}: {METADATA_KEY} metadata is not valid JSON ({exc})"
            ) from None
        return check_manifest(manifest, str(path))

    def _check_signature(self, path: Path) -> None:
        """One float input [batch, layout.size], one float output [batch, 2]."""
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or len(outputs) < 1:
            raise PolicyFileError(
                f"{path}: expected one input and one output, model has "
                f"{len(inputs)} inputs and {len(outputs)} outputs"
            )
        given, out = inputs[0], outputs[0]
        want = f"[batch, {self.layout.size}]"
        if (
            given.type != "tensor(float)"
            or len(given.shape) != 2
            or given.shape[1] != self.layout.size
        ):
            raise PolicyFileError(
                f"{path}: model input {given.name!r} is {given.type} {given.shape}, "
                f"but its manifest's layout {self.layout.describe()} needs "
                f"tensor(float) {want}"
            )
        if out.type != "tensor(float)" or len(out.shape) != 2 or out.shape[1] != 2:
            raise PolicyFileError(
                f"{path}: model output {out.name!r} is {out.type} {out.shape}, "
                f"expected tensor(float) [batch, 2]"
            )

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        """Actions (N, 2) float32 in [-1, 1] for observations (N, obs); a single (obs,) is taken as N=1."""
        if not isinstance(obs, np.ndarray):
            obs = np.asarray(obs, dtype=np.float32)
        if obs.size == self._obs1.size and obs.shape[-1] == obs.size:  # (obs,) or (1, obs)
            with self._lock:
                self._obs1[0] = obs.reshape(-1)  # copies and casts to float32
                self._run_bound(self._binding)
                return self._action1.copy()
        if obs.ndim != 2 or obs.shape[1] != self._obs1.size:
            raise ValueError(
                f"observations must have shape (N, {self._obs1.size}), got {obs.shape}"
            )
        if obs.dtype != np.float32 or not obs.flags.c_contiguous:
            obs = np.ascontiguousarray(obs, dtype=np.float32)
        return self._run(self._output_names, {self._input_name: obs})[0]
