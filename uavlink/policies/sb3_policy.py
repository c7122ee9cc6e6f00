"""A trained SB3 PPO policy (zip) behind the Policy interface. Imports torch and SB3."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.policies.manifest import PolicyFileError, read_zip_manifest


class SB3Policy:
    needs_truth = False

    def __init__(self, path: str | Path) -> None:
        path = Path(path)
        self.manifest = read_zip_manifest(path)
        self.layout = ObservationLayout.from_dict(self.manifest["observation_layout"])
        self.name = path.stem
        import torch
        from stable_baselines3 import PPO

        # One thread: a 3 x 128 MLP on one observation gains nothing from more, and in flight the
        # loop shares the CPU with the vehicle (and, in SITL, the simulator).
        torch.set_num_threads(1)
        self._torch = torch

        try:
            self.model = PPO.load(path, device="cpu")
        except Exception as exc:  # SB3 raises many kinds on a damaged archive
            raise PolicyFileError(f"{path}: cannot load the SB3 model ({type(exc).__name__}: {exc})") from None
        if self.model.observation_space.shape != (self.layout.size,):
            raise PolicyFileError(f"{path}: model input {self.model.observation_space.shape} does not "
                                  f"match its manifest's layout {self.layout.describe()}")

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        """SB3's ``predict(obs, deterministic=True)`` for a Box action space (the Gaussian mean,
        clipped to the box), without its per-call input checks: the flight loop's hot path."""
        with self._torch.inference_mode():
            action = self.model.policy._predict(self._torch.as_tensor(obs, dtype=self._torch.float32),
                                                deterministic=True).numpy()
        return np.clip(action, -1.0, 1.0)
