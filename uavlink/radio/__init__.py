"""Radio model: TR 25.814 urban-macro channel, SINR, round-robin rates and AoA. Pure numpy.

May import: ``config``, ``errors``.
"""

from uavlink.radio.aoa import circular_mean_std_deg, measured_aoa_deg, true_aoa_deg, wrap_deg
from uavlink.radio.channel import RadioChannel, RadioReadings
from uavlink.radio.fading import (
    mean_rician_power_gain,
    rician_gain_table,
    rician_power_gain,
    tabulated_rician_power_gain,
)
from uavlink.radio.noise import mean_snr_db, noise_power_dbm
from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm, path_loss_db
from uavlink.radio.rates import fair_rate, rate_bps, round_robin_rbs

__all__ = [
    "RadioChannel",
    "RadioReadings",
    "circular_mean_std_deg",
    "distance_3d_m",
    "fair_rate",
    "mean_rician_power_gain",
    "mean_rx_power_dbm",
    "mean_snr_db",
    "measured_aoa_deg",
    "noise_power_dbm",
    "path_loss_db",
    "rate_bps",
    "rician_gain_table",
    "rician_power_gain",
    "round_robin_rbs",
    "tabulated_rician_power_gain",
    "true_aoa_deg",
    "wrap_deg",
]
