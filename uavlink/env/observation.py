"""The observation: what the base station senses, stacked over the last M frames.

One piece of code, shared by the env and the flight loop. Per frame (newest first):
  UAV x, y / half-width; per-UE effective SINR, (dB - offset) / scale, clipped;
  sin and cos of the circular-mean AoA; circular std of the AoAs (radians / pi, at most 2).
Never UE positions. The layout is versioned and saved with every policy.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from uavlink.config import EnvConfig
from uavlink.radio.aoa import circular_mean_std_deg

OBS_LAYOUT_VERSION = 1


@dataclass(frozen=True)
class ObservationLayout:
    """Describes the observation vector; a policy file carries it and env and policy must agree."""

    version: int = OBS_LAYOUT_VERSION
    n_ues: int = 10
    memory: int = 4
    half_width_m: float = 200.0
    sinr_offset_db: float = 10.0
    sinr_scale_db: float = 20.0
    sinr_clip_db: tuple[float, float] = (-30.0, 50.0)
    aoa_std_max_rad: float = 2 * np.pi

    @classmethod
    def for_config(cls, cfg: EnvConfig) -> ObservationLayout:
        return cls(n_ues=cfg.n_ues, memory=cfg.memory, half_width_m=cfg.area.half_width_m)

    @property
    def frame_size(self) -> int:
        return 2 + self.n_ues + 3

    @property
    def size(self) -> int:
        return self.memory * self.frame_size

    def feature_names(self) -> list[str]:
        frame = ["uav_x", "uav_y", *(f"sinr_{u}" for u in range(self.n_ues)),
                 "aoa_mean_sin", "aoa_mean_cos", "aoa_std"]
        return [f"t-{lag}:{name}" for lag in range(self.memory) for name in frame]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-feature (low, high) of the observation vector, float32."""
        lo_db, hi_db = self.sinr_clip_db
        sinr = ((lo_db - self.sinr_offset_db) / self.sinr_scale_db, (hi_db - self.sinr_offset_db) / self.sinr_scale_db)
        std_max = self.aoa_std_max_rad / np.pi
        low = [-1.0, -1.0, *([sinr[0]] * self.n_ues), -1.0, -1.0, 0.0]
        high = [1.0, 1.0, *([sinr[1]] * self.n_ues), 1.0, 1.0, std_max]
        return (np.tile(np.array(low, np.float32), self.memory), np.tile(np.array(high, np.float32), self.memory))

    def to_dict(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["sinr_clip_db"] = list(self.sinr_clip_db)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ObservationLayout:
        data = dict(data)
        data["sinr_clip_db"] = tuple(data.get("sinr_clip_db", cls.sinr_clip_db))
        return cls(**data)

    def check_matches(self, other: ObservationLayout, what: str = "policy") -> None:
        """Raise a one-line ValueError naming both layouts when they differ."""
        if self != other:
            raise ValueError(f"observation layout mismatch: {what} expects {self.describe()}, "
                             f"env provides {other.describe()}")

    def describe(self) -> str:
        return (f"v{self.version} (n_ues={self.n_ues}, memory={self.memory}, "
                f"half_width_m={self.half_width_m:g}, size={self.size})")

    def encode_frame(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        """One frame's features (N, frame_size) from UAV position (N, 2), SINR and AoA (N, U)."""
        lo, hi = self.sinr_clip_db
        mean_deg, std_deg = circular_mean_std_deg(aoa_deg)
        mean_rad = np.radians(mean_deg)
        return np.concatenate([
            uav_xy_m / self.half_width_m,
            (np.clip(sinr_db, lo, hi) - self.sinr_offset_db) / self.sinr_scale_db,
            np.sin(mean_rad)[:, None],
            np.cos(mean_rad)[:, None],
            np.minimum(np.radians(std_deg), self.aoa_std_max_rad)[:, None] / np.pi,
        ], axis=1)

    def frames(self, obs: np.ndarray) -> np.ndarray:
        """Observations (N, size) as (N, memory, frame_size) float64, newest frame first."""
        return obs.reshape(obs.shape[0], self.memory, self.frame_size).astype(float)

    def sinr_db_history(self, obs: np.ndarray) -> np.ndarray:
        """Per-UE SINRs (N, memory, U) in dB, newest frame first, decoded from observations (N, size)."""
        return self.frames(obs)[:, :, 2:2 + self.n_ues] * self.sinr_scale_db + self.sinr_offset_db

    def uav_xy_m_history(self, obs: np.ndarray) -> np.ndarray:
        """UAV positions (N, memory, 2) in m, newest frame first."""
        return self.frames(obs)[:, :, :2] * self.half_width_m

    def aoa_feature_history(self, obs: np.ndarray) -> np.ndarray:
        """The encoded AoA features (N, memory, 3): sin and cos of the circular mean, scaled std."""
        return self.frames(obs)[:, :, 2 + self.n_ues:]

    def newest_frame(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        """Decode the newest frame of observations (N, size) back to physical units."""
        frame = obs[:, : self.frame_size].astype(float)
        u = self.n_ues
        return {
            "uav_xy_m": frame[:, :2] * self.half_width_m,
            "sinr_db": frame[:, 2:2 + u] * self.sinr_scale_db + self.sinr_offset_db,
            "aoa_mean_deg": np.degrees(np.arctan2(frame[:, 2 + u], frame[:, 3 + u])),
            "aoa_std_deg": np.degrees(frame[:, 4 + u] * np.pi),
        }


class ObservationBuilder:
    """Keeps the last M frames per env and returns the flattened observation (N, size), float32."""

    def __init__(self, layout: ObservationLayout, n_envs: int) -> None:
        self.layout = layout
        self._history = np.zeros((n_envs, layout.memory, layout.frame_size), dtype=np.float32)

    def reset(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        """Start a new episode: every memory slot holds the first frame."""
        self._history[:] = self.layout.encode_frame(uav_xy_m, sinr_db, aoa_deg)[:, None, :]
        return self.observation()

    def push(self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray) -> np.ndarray:
        self._history[:, 1:] = self._history[:, :-1]
        self._history[:, 0] = self.layout.encode_frame(uav_xy_m, sinr_db, aoa_deg)
        return self.observation()

    def observation(self) -> np.ndarray:
        return self._history.reshape(self._history.shape[0], -1).copy()
