"""Training snapshots: a PPO run stopped between two rollouts continues to the same weights.

``uavlink train``'s checkpoint (``RUN_DIR/checkpoint.zip``, for ``--resume``) keeps the model and
its optimizer; a resumed run starts fresh episodes and fresh random streams, so it trains on
(statistically equal) other data. A snapshot keeps everything the next rollout depends on, so a
run continued from it is the uninterrupted run, weight for weight:

- the model (SB3's zip in memory: policy, optimizer, step counts, the last observation);
- the env stack as it stands between rollouts (the batched cores with their random streams and
  episodes under way, the privileged columns' wrappers, ``VecNormalize``'s reward statistics and
  its running returns);
- the global random states SB3 draws from (torch's for the actions, numpy's for the minibatches,
  Python's);
- what the callbacks carry (the learning curve, the critic warm-up's count of rollouts) and the
  warm start's report, which the manifest records.

It is taken where a rollout starts (the last update done, the rollout buffer empty) and only after
the first update. A sweep's jobs write one (``uavlink.sweep.jobs``), so a sweep stopped mid-job
(Ctrl-C, a killed worker, a machine taken away) loses a minute rather than the job. Not for a run that keeps its best
validated weights (``TrainConfig.validation_episodes``), whose selection state it does not hold.
"""

from __future__ import annotations

import io
import json
import pickle
import random
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from uavlink.config import EnvConfig, TrainConfig
from uavlink.errors import UserError

__all__ = [
    "SNAPSHOT_FORMAT",
    "can_snapshot",
    "check_can_snapshot",
    "read_snapshot",
    "restore_model",
    "save_snapshot",
    "snapshot_callback",
]

SNAPSHOT_FORMAT = "uavlink-train-snapshot-v1"


def can_snapshot(tc: TrainConfig, resume: Path | None = None) -> bool:
    """Whether a snapshot can hold this run: not one started from a ``--resume`` checkpoint (whose
    random streams are gone), one keeping its best validated weights (selection state not held) nor
    one exploring with gSDE (whose noise distribution SB3's zip does not rebuild)."""
    return resume is None and not tc.validation_episodes and tc.gsde_log_std is None


def check_can_snapshot(tc: TrainConfig, resume: Path | None = None) -> None:
    """``can_snapshot``, refused in one line."""
    if not can_snapshot(tc, resume):
        raise UserError(
            "--snapshot continues a run exactly; it cannot start from --resume, keep the "
            "--validation-episodes selection's state or explore with --gsde-log-std"
        )


def _training_key(cfg: EnvConfig, tc: TrainConfig) -> str:
    return json.dumps({"env": cfg.to_dict(), "train": tc.to_dict()}, sort_keys=True, default=str)


def read_snapshot(path: Path, cfg: EnvConfig, tc: TrainConfig) -> dict[str, Any] | None:
    """The snapshot at ``path`` (None when there is none); a snapshot of another training, or a
    file that is not one, is refused in one line rather than continued or overwritten."""
    if not path.is_file():
        return None
    try:
        with path.open("rb") as f:
            state = pickle.load(f)  # noqa: S301 - our own file, written by save_snapshot
    except Exception as exc:  # noqa: BLE001 - a truncated or foreign file
        raise UserError(f"{path}: not a training snapshot ({type(exc).__name__})") from None
    if not isinstance(state, dict) or state.get("format") != SNAPSHOT_FORMAT:
        raise UserError(f"{path}: not a training snapshot")
    if state.get("key") != _training_key(cfg, tc):
        raise UserError(
            f"{path}: a snapshot of another training (other env or train settings): "
            "remove it to start afresh"
        )
    return state


def save_snapshot(
    path: Path, model: Any, cfg: EnvConfig, tc: TrainConfig, extra: dict[str, Any]
) -> None:
    """Write ``model``'s run as it stands to ``path`` (whole: to a partial file, then renamed)."""
    import torch

    buffer = io.BytesIO()
    model.save(buffer)
    normalize = model.get_vec_normalize_env()
    env = model.get_env()
    inner = normalize.venv if normalize is not None else env
    state = {
        "format": SNAPSHOT_FORMAT,
        "key": _training_key(cfg, tc),
        "model": buffer.getvalue(),
        # VecNormalize pickles its statistics without the env under it or its running returns
        "normalize": pickle.dumps(normalize) if normalize is not None else None,
        "returns": normalize.returns.copy() if normalize is not None else None,
        "env": pickle.dumps(inner),
        "torch_rng": torch.get_rng_state(),
        "numpy_rng": np.random.get_state(),
        "python_rng": random.getstate(),
        **extra,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(path.name + ".partial")
    with partial.open("wb") as f:
        pickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
    partial.replace(path)


def restore_model(state: dict[str, Any], tensorboard_log: str | None) -> Any:
    """The PPO model of ``state`` on its env, logging to ``tensorboard_log`` (this run's folder, not
    the stopped one's), with the global random states as they were; call it after building anything
    that draws from torch or numpy, which would move them."""
    import torch
    from stable_baselines3 import PPO

    model = PPO.load(io.BytesIO(state["model"]), env=None, device="cpu")
    model.tensorboard_log = tensorboard_log
    env = pickle.loads(state["env"])  # noqa: S301 - our own snapshot
    if state["normalize"] is not None:
        normalize = pickle.loads(state["normalize"])  # noqa: S301 - our own snapshot
        normalize.set_venv(env)
        normalize.returns = state["returns"]
        env = normalize
    model.set_env(env, force_reset=False)  # keeps the last observation: no new episodes
    torch.set_rng_state(state["torch_rng"])
    np.random.set_state(state["numpy_rng"])
    random.setstate(state["python_rng"])
    return model


def snapshot_callback(
    path: Path,
    cfg: EnvConfig,
    tc: TrainConfig,
    extra: Callable[[], dict[str, Any]],
    every_s: float,
):
    """An SB3 callback that writes a snapshot where a rollout starts, at most every ``every_s``
    seconds of wall time and never before the first update (nor again at the step it resumed at);
    ``extra()`` gives what the other callbacks and the warm start carry."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Snapshots(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self._last = time.perf_counter()
            self._resumed_at = -1

        def _on_training_start(self) -> None:
            self._resumed_at = self.model.num_timesteps

        def _on_rollout_start(self) -> None:
            now = time.perf_counter()
            steps = self.model.num_timesteps
            if steps > 0 and steps != self._resumed_at and now - self._last >= every_s:
                save_snapshot(path, self.model, cfg, tc, extra())
                self._last = now

        def _on_step(self) -> bool:
            return True

    return Snapshots()
