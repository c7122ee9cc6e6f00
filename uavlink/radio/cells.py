"""A fleet's cells: which UAV serves each UE and how a cell shares its resource blocks (SPEC "A fleet").

Association: each UE attaches to the UAV with the strongest mean received power (path loss and
shadowing, no fast fading), re-decided every frame (3GPP's RSRP-based cell selection, TS 38.304
5.2.3 in the small). Scheduling: per-cell round robin, RB k of cell d to its UE of rank k mod U_d
(ranks by UE index), so a UE of a cell with U_d UEs gets B / U_d on average. A cell without UEs
sends no data and interferes with nobody (the full-buffer system-level convention).

A listening fleet (``fleet_reuse = "listen"``) has one cell: the UAV that is the strongest for the
most UEs serves them all on the whole band, and the others are barred to attachment (TS 38.304
5.3.1, ``cellBarred``) and send nothing, yet still hear every UE's uplink reference signal, as
the non-serving base stations of NR's uplink positioning measure a UE's SRS (TS 38.305 8.13).
Where a team stays together one serving UAV is what the best fleet flies anyway (the genie's own
shape on no_move); the others then sense the field for it (research/log/fleet.md, "What listening
UAVs would add to the serving UAV's model of the field").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import RadioConfig
from uavlink.config.env import REUSE_LISTEN, REUSE_ORTHOGONAL
from uavlink.radio.noise import noise_power_dbm


@dataclass(frozen=True)
class Cells:
    """One frame's association, batched over N envs (or any leading axes) with U UEs and D UAVs."""

    serving: np.ndarray  # (N, U) index of each UE's UAV
    size: np.ndarray  # (N, D) UEs per cell
    rank: np.ndarray  # (N, U) each UE's rank in its cell, by UE index

    @classmethod
    def associate(cls, rx_dbm: np.ndarray) -> Cells:
        """Cells from the mean received power (N, U, D) in dBm; ties go to the lower UAV index."""
        serving = rx_dbm.argmax(axis=-1)
        member = serving[..., None] == np.arange(rx_dbm.shape[-1])  # (N, U, D)
        rank = (np.cumsum(member, axis=-2) - 1)[member].reshape(serving.shape)
        return cls(serving, member.sum(axis=-2), rank)

    @classmethod
    def listen(cls, rx_dbm: np.ndarray) -> Cells:
        """One cell (``fleet_reuse = "listen"``): every UE served by the UAV that is the strongest
        for the most UEs (a tie to the one the UEs receive more power from in all, then the lower
        index), ranked by UE index; the others listen."""
        server = listening_server(rx_dbm)  # (N,)
        n_ues, n_uavs = rx_dbm.shape[-2:]
        serving = np.repeat(server[..., None], n_ues, axis=-1)
        size = np.where(server[..., None] == np.arange(n_uavs), n_ues, 0)
        rank = np.broadcast_to(np.arange(n_ues), serving.shape).copy()
        return cls(serving, size, rank)

    @property
    def active(self) -> np.ndarray:
        """(N, D) True for a cell with at least one UE (it transmits)."""
        return self.size > 0

    def ues_in_cell(self) -> np.ndarray:
        """(N, U) the size of each UE's cell, U_d."""
        return np.take_along_axis(self.size, self.serving, axis=-1)

    def rbs_per_ue(self, n_rbs: int) -> np.ndarray:
        """(N, U) RBs each UE gets per frame when its cell's ``n_rbs`` go round robin."""
        cell = self.ues_in_cell()
        return n_rbs // cell + (self.rank < n_rbs % cell)


def listening_server(rx_dbm: np.ndarray) -> np.ndarray:
    """(...,) the serving UAV of a listening fleet for mean received powers (..., U, D), dBm: the
    strongest for the most UEs, a tie to the larger total received power, then the lower index."""
    n_uavs = rx_dbm.shape[-1]
    strongest = rx_dbm.argmax(axis=-1)  # (..., U)
    votes = (strongest[..., None] == np.arange(n_uavs)).sum(axis=-2)  # (..., D)
    power = (10.0 ** (rx_dbm / 10.0)).sum(axis=-2)  # (..., D), mW
    return (votes + 0.5 * power / power.sum(axis=-1, keepdims=True)).argmax(axis=-1)


def mean_channel_rate_bps(
    rx_dbm: np.ndarray, radio: RadioConfig, fleet_reuse: str = "full"
) -> np.ndarray:
    """Each UE's Shannon rate (..., U) at the mean-fading SINR, for mean received powers (..., U, D)
    in dBm (path loss and shadowing): strongest-UAV cells, per-cell B / U_d, interference from every
    active cell (``"full"`` reuse) or none (``"orthogonal"``: 1/D of the band each; ``"listen"``:
    one cell, ``Cells.listen``'s). With one UAV it is the SPEC's (B / U) log2(1 + SNR). What the GPS
    baselines and the genie plan on; the env's rate averages the fading over RBs instead, which
    this equals when fast fading is off."""
    n_uavs = rx_dbm.shape[-1]
    if fleet_reuse == REUSE_LISTEN and n_uavs > 1:
        server = listening_server(rx_dbm)  # (...,)
        signal = np.take_along_axis(rx_dbm, server[..., None, None], axis=-1)[..., 0]
        snr = 10.0 ** ((signal - noise_power_dbm(radio.bandwidth_hz, radio)) / 10.0)
        return radio.bandwidth_hz / rx_dbm.shape[-2] * np.log2(1.0 + snr)
    serving = rx_dbm.argmax(axis=-1)  # as Cells.associate, without the ranks a scheduler needs
    member = serving[..., None] == np.arange(n_uavs)
    size = member.sum(axis=-2)  # (..., D)
    ues_in_cell = np.take_along_axis(size, serving, axis=-1)
    rx_mw = 10.0 ** (rx_dbm / 10.0)
    signal = np.take_along_axis(rx_mw, serving[..., None], axis=-1)[..., 0]
    noise_mw = 10.0 ** (noise_power_dbm(radio.bandwidth_hz, radio) / 10.0)
    if fleet_reuse == REUSE_ORTHOGONAL:
        share = radio.orthogonal_share(n_uavs)
        return share * radio.bandwidth_hz / ues_in_cell * np.log2(1.0 + signal / share / noise_mw)
    interference = (rx_mw * (size > 0)[..., None, :]).sum(axis=-1) - signal if n_uavs > 1 else 0.0
    return radio.bandwidth_hz / ues_in_cell * np.log2(1.0 + signal / (interference + noise_mw))
