"""The downlink channel of D UAV base stations to U ground UEs, batched over N environments.

Shapes: UAV positions (N, D, 2), UE positions (N, U, 2), metres in the env frame (x east, y north).
Per frame the channel advances the shadowing and draws fast fading, then reports per-UE effective
SINR, round-robin rate and measured AoA. One UAV (the paper's evaluation) serves every UE alone.
A fleet (SPEC "A fleet") forms cells (``uavlink.radio.cells``: strongest mean power, per-cell round
robin) and, with ``fleet_reuse = "full"``, every UAV with UEs interferes on every RB (the paper's
SINR); with ``"orthogonal"`` each UAV has 1/D of the band to itself; with ``"listen"`` one UAV
serves every UE and the others listen (``Cells.listen``). Each UAV also senses every
UE's uplink reference signal (its SNR and AoA), the per-UAV observation. Shadowing follows
``RadioConfig.shadowing_model``: per-link AR(1) (the paper's) or a spatial field.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import AreaConfig, RadioConfig
from uavlink.config.env import REUSE_LISTEN, REUSE_ORTHOGONAL, SHADOWING_SPATIAL
from uavlink.radio.aoa import measured_aoa_deg, true_aoa_deg
from uavlink.radio.cells import Cells
from uavlink.radio.fading import mean_rician_power_gain, tabulated_rician_power_gain
from uavlink.radio.noise import noise_power_dbm
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm
from uavlink.radio.rates import rate_bps, round_robin_rbs
from uavlink.radio.shadowing import initial_shadowing_db, update_shadowing_db
from uavlink.radio.spatial_shadowing import SpatialShadowField


@dataclass
class RadioReadings:
    """One frame's readings per environment and UE.

    ``sinr_db`` and ``aoa_deg`` are what the base station senses; ``rate_bps`` is the scored truth.
    """

    sinr_db: np.ndarray  # (N, U) effective downlink SINR over the UE's RBs
    rate_bps: np.ndarray  # (N, U) round-robin Shannon rate
    aoa_deg: np.ndarray  # (N, U) measured AoA at the serving UAV, [-180, 180)
    heard_sinr_db: np.ndarray  # (N, D, U) each UAV's SNR of each UE's reference signal
    heard_aoa_deg: np.ndarray  # (N, D, U) each UAV's measured AoA of each UE
    serving: np.ndarray  # (N, U) each UE's UAV


class RadioChannel:
    """Stateful (shadowing) channel; the random generator is passed to every call that draws."""

    def __init__(
        self, radio: RadioConfig, area: AreaConfig, n_ues: int, fleet_reuse: str = "full"
    ) -> None:
        radio.validate()
        area.validate()
        self.radio = radio
        self.altitude_m = area.uav_altitude_m
        self.n_ues = n_ues
        self.fleet_reuse = fleet_reuse
        self.rbs_per_ue = round_robin_rbs(radio.n_resource_blocks, n_ues)
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

    @property
    def field(self) -> SpatialShadowField | None:
        """The episode's shadowing field (spatial model; None otherwise): for privileged baselines
        only (the genie), never part of an observation. Immutable, so shared, not copied."""
        return self._field

    def reset(
        self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray
    ) -> RadioReadings:
        """Draw fresh shadowing for every link and return the readings of the first frame."""
        n_envs, n_uavs = uav_xy_m.shape[0], uav_xy_m.shape[1]
        if self.radio.shadowing and self.radio.shadowing_model == SHADOWING_SPATIAL:
            self._field = SpatialShadowField.draw(rng, n_envs, self.radio)
            self._shadow_db = self._field.shadow_db(uav_xy_m, ue_xy_m)
        else:
            self._field = None
            self._shadow_db = initial_shadowing_db(rng, (n_envs, self.n_ues, n_uavs), self.radio)
        self._aoa_std_deg: float | np.ndarray = self.radio.aoa_noise_deg  # or per episode
        if self.radio.aoa_noise_max_deg > self.radio.aoa_noise_deg:  # per-episode std, (N, 1)
            self._aoa_std_deg = rng.uniform(
                self.radio.aoa_noise_deg, self.radio.aoa_noise_max_deg, size=(n_envs, 1)
            )
        self._uav_prev, self._ue_prev = uav_xy_m.copy(), ue_xy_m.copy()
        return self._readings(rng, uav_xy_m, ue_xy_m)

    def step(
        self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray
    ) -> RadioReadings:
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

    def _readings(
        self, rng: np.random.Generator, uav_xy_m: np.ndarray, ue_xy_m: np.ndarray
    ) -> RadioReadings:
        radio = self.radio
        rx_dbm = mean_rx_power_dbm(distance_3d_m(uav_xy_m, ue_xy_m, self.altitude_m), radio)
        rx_dbm += self._shadow_db  # (N, U, D)
        if uav_xy_m.shape[1] > 1:
            return self._fleet_readings(rng, uav_xy_m, ue_xy_m, rx_dbm)
        sinr = 10.0 ** ((rx_dbm[..., 0] - self.noise_dbm) / 10.0)
        if radio.fast_fading:
            sinr *= mean_rician_power_gain(rng, sinr.shape, self.rbs_per_ue, radio.rician_k_db)
        sinr_db = 10.0 * np.log10(sinr)
        aoa = measured_aoa_deg(rng, true_aoa_deg(uav_xy_m, ue_xy_m), self._aoa_std_deg)
        return RadioReadings(
            sinr_db=sinr_db,
            rate_bps=rate_bps(sinr, radio.bandwidth_hz, self.n_ues),
            aoa_deg=aoa,
            heard_sinr_db=sinr_db[:, None, :],
            heard_aoa_deg=aoa[:, None, :],
            serving=np.zeros(sinr.shape, dtype=np.intp),
        )

    def _fleet_readings(
        self,
        rng: np.random.Generator,
        uav_xy_m: np.ndarray,
        ue_xy_m: np.ndarray,
        rx_dbm: np.ndarray,
    ) -> RadioReadings:
        radio = self.radio
        # one cell while the others listen: full reuse's SINR, with no other cell active
        cells = (
            Cells.listen(rx_dbm) if self.fleet_reuse == REUSE_LISTEN else Cells.associate(rx_dbm)
        )
        if self.fleet_reuse == REUSE_ORTHOGONAL:
            sinr, bandwidth_hz = self._orthogonal_sinr(rng, rx_dbm, cells)
        else:
            sinr, bandwidth_hz = self._full_reuse_sinr(rng, rx_dbm, cells)
        # What each UAV senses of every UE's uplink reference signal: SNR over the UE's share of
        # RBs (no other cell's downlink in the uplink band), and the AoA.
        heard = 10.0 ** ((rx_dbm - self.noise_dbm) / 10.0)
        if radio.fast_fading:
            heard *= mean_rician_power_gain(
                rng, heard.shape, self.rbs_per_ue[:, None], radio.rician_k_db
            )
        std = (
            self._aoa_std_deg
            if np.ndim(self._aoa_std_deg) == 0
            else np.asarray(self._aoa_std_deg)[:, :, None]  # an array here: asarray is a no-op
        )
        heard_aoa = measured_aoa_deg(
            rng, true_aoa_deg(uav_xy_m[:, :, None, :], ue_xy_m[:, None, :, :]), std
        )
        at_server = np.take_along_axis(heard_aoa, cells.serving[:, None, :], axis=1)[:, 0]
        return RadioReadings(
            sinr_db=10.0 * np.log10(sinr),
            rate_bps=bandwidth_hz * np.log2(1.0 + sinr),
            aoa_deg=at_server,
            heard_sinr_db=10.0 * np.log10(heard.transpose(0, 2, 1)),
            heard_aoa_deg=heard_aoa,
            serving=cells.serving,
        )

    def _full_reuse_sinr(
        self, rng: np.random.Generator, rx_dbm: np.ndarray, cells: Cells
    ) -> tuple[np.ndarray, np.ndarray]:
        """Effective SINR (N, U), the linear mean over the UE's RBs of signal / (interference +
        noise) with every active UAV on every RB and per-RB fading, and the bandwidth B / U_d.

        Only the RBs each UE is scheduled on are drawn (K per active cell, not K per UE and UAV),
        one gain per RB and UAV from the tabulated Rician law (``tabulated_rician_power_gain``):
        column 0 for the serving UAV, the rest for the others (silent cells at zero power). A UE of
        a cell with more UEs than RBs is scored on one RB (its average share stays B / U_d).
        """
        radio = self.radio
        n_envs, n_ues, n_uavs = rx_dbm.shape
        n_rb = np.maximum(cells.rbs_per_ue(radio.n_resource_blocks), 1).ravel()  # (N U,)
        rx_rb_mw = (10.0 ** (rx_dbm / 10.0) / radio.n_resource_blocks).reshape(-1, n_uavs)
        serving = cells.serving.ravel()[:, None] == np.arange(n_uavs)  # (N U, D)
        signal_mw = np.repeat(rx_rb_mw[serving], n_rb)  # one entry per (UE, scheduled RB)
        active = np.repeat(cells.active, n_ues, axis=0)  # (N U, D): each UE's view of the cells
        others_mw = np.repeat((rx_rb_mw * active)[~serving].reshape(-1, n_uavs - 1), n_rb, axis=0)
        if radio.fast_fading:
            gain = tabulated_rician_power_gain(rng, (len(signal_mw), n_uavs), radio.rician_k_db)
            signal_mw = signal_mw * gain[:, 0]
            others_mw = others_mw * gain[:, 1:]
        noise_rb_mw = 10.0 ** (noise_power_dbm(radio.rb_bandwidth_hz, radio) / 10.0)
        sinr_rb = signal_mw / (others_mw.sum(axis=1) + noise_rb_mw)
        first_rb = np.cumsum(n_rb) - n_rb  # every UE has at least one row
        sinr = (np.add.reduceat(sinr_rb, first_rb) / n_rb).reshape(n_envs, n_ues)
        return sinr, radio.bandwidth_hz / cells.ues_in_cell()

    def _orthogonal_sinr(
        self, rng: np.random.Generator, rx_dbm: np.ndarray, cells: Cells
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each UAV alone on K // D RBs at full power: no interference; the bandwidth B_d / U_d."""
        radio = self.radio
        rbs_per_uav = radio.rbs_per_cell(rx_dbm.shape[2])
        serving_dbm = np.take_along_axis(rx_dbm, cells.serving[:, :, None], axis=2)[..., 0]
        noise_rb_dbm = noise_power_dbm(radio.rb_bandwidth_hz, radio)
        sinr = 10.0 ** ((serving_dbm - 10.0 * np.log10(rbs_per_uav) - noise_rb_dbm) / 10.0)
        if radio.fast_fading:
            n_rb = np.maximum(cells.rbs_per_ue(rbs_per_uav), 1)
            sinr *= mean_rician_power_gain(rng, sinr.shape, n_rb, radio.rician_k_db)
        return sinr, rbs_per_uav * radio.rb_bandwidth_hz / cells.ues_in_cell()
