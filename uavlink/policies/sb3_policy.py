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
        from stable_baselines3 import PPO

        try:
            self.model = PPO.load(path, device="cpu")
        except Exception as exc:  # SB3 raises many kinds on a damaged archive
            raise PolicyFileError(f"{path}: cannot load the SB3 model ({type(exc).__name__}: {exc})") from None
        if self.model.observation_space.shape != (self.layout.size,):
            raise PolicyFileError(f"{path}: model input {self.model.observation_space.shape} does not "
                                  f"match its manifest's layout {self.layout.describe()}")

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        action, _ = self.model.predict(obs, deterministic=True)
        return action
