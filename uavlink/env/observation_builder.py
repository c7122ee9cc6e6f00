"""The observation builder: the last M frames per row (env, or env and UAV), newest first, and the
memory of place and model of the field when the layout has them. One builder serves the env and the
flight loop, so what flies is encoded by the code that trained."""

from __future__ import annotations

import numpy as np

from uavlink.config.env import PLACE_POOLED
from uavlink.env.field_model import FieldModel
from uavlink.env.observation import ObservationLayout
from uavlink.env.place_memory import PlaceMemory, sensed_value_bits


class ObservationBuilder:
    """Keeps the last M frames per row (env, or env and UAV), and the memory of place when the
    layout has one, and returns the flattened observation (rows, size), float32."""

    def __init__(self, layout: ObservationLayout, n_rows: int, n_uavs: int = 1) -> None:
        """``n_rows`` agent rows, ``n_uavs`` consecutive rows to an env (a fleet's model of the
        field, v9, is one per env)."""
        self.layout = layout
        self._history = np.zeros((n_rows, layout.memory, layout.frame_size), dtype=np.float32)
        self.place = (
            PlaceMemory(layout.place_cell_m, layout.half_width_m, n_rows)
            if layout.place_cell_m > 0
            else None
        )
        shared_by = n_uavs if layout.place_model == PLACE_POOLED else 1
        self.field = (
            FieldModel(
                n_rows // shared_by,
                layout.episode_frames,
                layout.r_max_m,
                layout.half_width_m,
                shared_by=shared_by,
            )
            if layout.models_field
            else None
        )

    def _encode(
        self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray, **fleet: np.ndarray
    ) -> np.ndarray:
        place = self.place.update(uav_xy_m, sinr_db) if self.place is not None else {}
        if self.field is not None:
            place |= self.field.update(uav_xy_m, sensed_value_bits(sinr_db))
        return self.layout.encode_frame(uav_xy_m, sinr_db, aoa_deg, **fleet, **place)

    def reset(
        self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray, **fleet: np.ndarray
    ) -> np.ndarray:
        """Start a new episode: every memory slot holds the first frame; the place memory is empty
        before it."""
        if self.place is not None:
            self.place.reset()
        if self.field is not None:
            self.field.reset()
        self._history[:] = self._encode(uav_xy_m, sinr_db, aoa_deg, **fleet)[:, None, :]
        return self.observation()

    def push(
        self, uav_xy_m: np.ndarray, sinr_db: np.ndarray, aoa_deg: np.ndarray, **fleet: np.ndarray
    ) -> np.ndarray:
        self._history[:, 1:] = self._history[:, :-1]
        self._history[:, 0] = self._encode(uav_xy_m, sinr_db, aoa_deg, **fleet)
        return self.observation()

    def observation(self) -> np.ndarray:
        return self._history.reshape(self._history.shape[0], -1).copy()
