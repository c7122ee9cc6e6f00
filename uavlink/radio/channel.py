"""The downlink channel of D UAV base stations to U ground UEs, batched over N environments.

Shapes: UAV positions (N, D, 2), UE positions (N, U, 2), metres in the env frame (x east, y north).
Each UE is served by one UAV (``serving``, default UAV 0) and interfered by the others on every RB
(full frequency reuse). Per frame the channel draws fast fading and advances the shadowing, then
reports per-UE effective SINR, round-robin rate and measured AoA at the serving UAV. Shadowing
follows ``RadioConfig.shadowing_model``: per-link AR(1) (the paper's) or a spatial field.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import AreaConfig, RadioConfig
from uavlink.radio.aoa import measured_aoa_deg, true_aoa_deg
from uavlink.radio.fading import mean_rician_power_gain, rician_power_gain
from uavlink.radio.noise import noise_power_dbm
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
from uavlink.radio.rates import rate_bps, round_robin_mask, round_robin_rbs
from uavlink.radio.shadowing import initial_shadowing_db, update_shadowing_db
from uavlink.radio.spatial_shadowing import SpatialShadowField


@dataclass
class RadioReadings:
    """One frame's readings per environment and UE.

    ``sinr_db`` and ``aoa_deg`` are what the base station senses; ``rate_bps`` is the scored truth.
    """

    sinr_db: np.ndarray  # (N, U) effective SINR over the UE's RBs
    rate_bps: np.ndarray  # (N, U) round-robin Shannon rate
    aoa_deg: np.ndarray  # (N, U) measured AoA at the serving UAV, [-180, 180)


class RadioChannel:
    """Stateful (shadowing) channel; the random generator is passed to every call that draws."""

    def __init__(self, radio: RadioConfig, area: AreaConfig, n_ues: int,
                 serving: np.ndarray | None = None) -> None:
        radio.validate()
        area.validate()
        self.radio = radio
        self.altitude_m = area.uav_altitude_m
        self.n_ues = n_ues
        self.serving = np.zeros(n_ues, dtype=np.intp) if serving is None else np.asarray(serving)
        self.rbs_per_ue = round_robin_rbs(radio.n_resource_blocks, n_ues)
        self.rb_mask = round_robin_mask(radio.n_resource_blocks, n_ues)
        self.noise_dbm = noise_power_dbm(radio.bandwidth_hz, radio)
        self._shadow_db: np.ndarray | None = None
        self._field: SpatialShadowField | None = None  # the episode's field (spatial model)
        self._uav_prev: np.ndarray | None = None
        self._ue_prev: np.ndarray | None = None

    @property
    def shadow_db(self) -> np.ndarray:
        """The links' current shadowing (N, U, D) in dB, a copy: for analysis and privileged
        experiments only; nothing a base station senses (never part of an observation)."""
        if self._shadow_db is None:
            raise RuntimeError("RadioChannel.shadow_db read before reset()")
        return self._shadow_db.copy()

    def reset(self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> RadioReadings:
        """Draw fresh shadowing for every link and return the readings of the first frame."""
        n_envs, n_uavs = uav_xy_m.shape[0], uav_xy_m.shape[1]
        if self.radio.shadowing and self.radio.shadowing_model == "spatial":
            self._field = SpatialShadowField.draw(rng, n_envs, self.radio)
            self._shadow_db = self._field.shadow_db(uav_xy_m, ue_xy_m)
        else:
            self._field = None
            self._shadow_db = initial_shadowing_db(rng, (n_envs, self.n_ues, n_uavs), self.radio)
        self._aoa_std_deg = self.radio.aoa_noise_deg
        if self.radio.aoa_noise_max_deg > self.radio.aoa_noise_deg:  # per-episode std, (N, 1)
            self._aoa_std_deg = rng.uniform(self.radio.aoa_noise_deg, self.radio.aoa_noise_max_deg,
                                            size=(n_envs, 1))
        self._uav_prev, self._ue_prev = uav_xy_m.copy(), ue_xy_m.copy()
        return self._readings(rng, uav_xy_m, ue_xy_m)

    def step(self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> RadioReadings:
        """Advance the shadowing (AR(1): by each link's displacement since the last call; spatial:
        the episode's field at the new positions), then read the frame."""
        if self._shadow_db is None:
            raise RuntimeError("RadioChannel.step() called before reset()")
        if self._field is not None:
            self._shadow_db = self._field.shadow_db(uav_xy_m, ue_xy_m)
        elif self.radio.shadowing:
            ue_moved = np.linalg.norm(ue_xy_m - self._ue_prev, axis=-1)  # (N, U)
            uav_moved = np.linalg.norm(uav_xy_m - self._uav_prev, axis=-1)  # (N, D)
            displacement = ue_moved[:, :, None] + uav_moved[:, None, :]
            self._shadow_db = update_shadowing_db(rng, self._shadow_db, displacement, self.radio)
        self._uav_prev, self._ue_prev = uav_xy_m.copy(), ue_xy_m.copy()
        return self._readings(rng, uav_xy_m, ue_xy_m)

    def _readings(self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray) -> RadioReadings:
        radio = self.radio
        rx_dbm = mean_rx_power_dbm(distance_3d_m(uav_xy_m, ue_xy_m, self.altitude_m), radio)
        rx_dbm += self._shadow_db  # (N, U, D)
        if uav_xy_m.shape[1] == 1:
            sinr = 10.0 ** ((rx_dbm[..., 0] - self.noise_dbm) / 10.0)
            if radio.fast_fading:
                sinr *= mean_rician_power_gain(rng, sinr.shape, self.rbs_per_ue, radio.rician_k_db)
        else:
            sinr = self._multi_uav_sinr(rng, rx_dbm)
        sinr_db = 10.0 * np.log10(sinr)
        true_deg = true_aoa_deg(uav_xy_m[:, self.serving, :], ue_xy_m)  # from each UE's server
        aoa = measured_aoa_deg(rng, true_deg, self._aoa_std_deg)
        return RadioReadings(sinr_db=sinr_db, rate_bps=rate_bps(sinr, radio.bandwidth_hz, self.n_ues),
                             aoa_deg=aoa)

    def _multi_uav_sinr(self, rng: np.random.Generator, rx_dbm: np.ndarray) -> np.ndarray:
        """Per-RB SINR with co-channel interference, averaged over each UE's round-robin RBs."""
        radio = self.radio
        n_rbs = radio.n_resource_blocks
        rx_rb_mw = np.broadcast_to((10.0 ** (rx_dbm / 10.0) / n_rbs)[..., None],
                                   (*rx_dbm.shape, n_rbs))  # (N, U, D, K), power split over RBs
        if radio.fast_fading:
            rx_rb_mw = rx_rb_mw * rician_power_gain(rng, rx_rb_mw.shape, radio.rician_k_db)
        ue_idx = np.arange(self.n_ues)
        signal = rx_rb_mw[:, ue_idx, self.serving, :]  # (N, U, K)
        interference = rx_rb_mw.sum(axis=2) - signal
        noise_rb_mw = 10.0 ** (noise_power_dbm(radio.rb_bandwidth_hz, radio) / 10.0)
        sinr_rb = signal / (interference + noise_rb_mw)
        return (sinr_rb * self.rb_mask).sum(axis=-1) / self.rbs_per_ue
