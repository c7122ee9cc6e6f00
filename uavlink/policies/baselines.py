"""Rule-based policies every evaluation reports (SPEC "Baselines every evaluation reports")."""

from __future__ import annotations

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.policies.base import RulePolicy
from uavlink.radio.noise import mean_snr_db
from uavlink.radio.rates import fair_rate, rate_bps


def hover_sinr_db(cfg: EnvConfig) -> float:
    """The aoa rule's hover level: the SINR of a UE straight below its UAV on the mean channel (the
    link budget overhead, no shadowing or fading), dB."""
    return float(mean_snr_db(cfg.area.uav_altitude_m, cfg.radio))


class StaticPolicy(RulePolicy):
    """Hover where the episode starts (the area centre; a fleet's UAVs on their start circle)."""

    name = "static"
    layout = None
    needs_truth = False

    def __init__(self, cfg: EnvConfig) -> None:
        self.hover = ActionMapping.for_config(cfg).from_polar(0.0, 0.0)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        return np.tile(self.hover, (obs.shape[0], 1))


class AoaPolicy(RulePolicy):
    """GPS-free rule (SPEC "Baselines every evaluation reports"): fly towards the circular-mean
    AoA, slower as the SINRs level off at the hover level.

    Speed = r_max * clip((hover SINR - mean SINR) / ``sinr_span_db``, 0, 1), where the hover SINR is
    the link budget straight overhead (no shadowing or fading). Because a shadowed frame also lowers
    the SINRs, the rule keeps moving while its UEs are shadowed and stops when they are not, which
    under the SPEC's shadowing model (no memory of place) buys throughput even when the UEs stay put
    (docs/design/radio.md). The warm start's variants of it: ``uavlink.learn.teachers``.
    """

    name = "aoa"
    needs_truth = False
    sinr_span_db = 10.0  # full speed this far below the hover SINR

    def __init__(self, cfg: EnvConfig) -> None:
        self.layout = ObservationLayout.for_config(cfg)
        self.mapping = ActionMapping.for_config(cfg)
        self.hover_sinr_db = hover_sinr_db(cfg)
        self.hover = self.mapping.from_polar(0.0, 0.0)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        return self.act_towards(obs, self.layout.newest_frame(obs)["aoa_mean_deg"])

    def act_towards(self, obs: np.ndarray, aoa_mean_deg: np.ndarray) -> np.ndarray:
        """The rule's actions (N, 2) with the circular-mean AoA (N,) in deg given, rather than read
        from the observations (N, size): the seam a privileged teacher uses (``uavlink.learn.teachers``)."""
        gap = (
            self.hover_sinr_db - self.layout.newest_frame(obs)["sinr_db"].mean(axis=1)
        ) / self.sinr_span_db
        distance = self.mapping.r_max_m * np.clip(gap, 0.0, 1.0)
        return self.mapping.from_polar(aoa_mean_deg, distance)


class OraclePolicy(RulePolicy):
    """Knows the UEs' true positions and velocities (GPS) and each frame takes the reachable move
    that maximises the expected R_fair at the UEs' next positions (mean channel: no shadowing or
    fading). Moves searched: ``n_angles`` directions x ``n_radii`` distances up to r_max, plus hover.
    A GPS greedy reference, not a bound: greedy over one frame and blind to shadowing, it flies below
    the GPS-free ``aoa`` rule in some scenarios (docs/design/baselines.md)."""

    name = "oracle"
    layout = None
    needs_truth = True

    def __init__(self, cfg: EnvConfig, n_angles: int = 32, n_radii: int = 6) -> None:
        self.cfg = cfg
        self.mapping = ActionMapping.for_config(cfg)
        angles = np.linspace(-180.0, 180.0, n_angles, endpoint=False)
        radii = np.linspace(cfg.r_max_m / n_radii, cfg.r_max_m, n_radii)
        grid_a, grid_r = np.meshgrid(angles, radii)
        self.cand_angle = np.concatenate([[0.0], grid_a.ravel()])
        self.cand_dist = np.concatenate([[0.0], grid_r.ravel()])
        rad = np.radians(self.cand_angle)
        self.cand_move = self.cand_dist[:, None] * np.stack([np.cos(rad), np.sin(rad)], axis=1)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError(
                "the oracle baseline needs ground truth; it cannot fly from MAVLink data"
            )
        half = self.cfg.area.half_width_m
        ue_next = np.clip(truth.ue_xy_m + truth.ue_velocity_mps * self.cfg.frame_s, -half, half)
        uav_cand = np.clip(
            truth.uav_xy_m[:, None, :] + self.cand_move[None], -half, half
        )  # (N, C, 2)
        delta = ue_next[:, None, :, :] - uav_cand[:, :, None, :]  # (N, C, U, 2)
        dist = np.sqrt((delta**2).sum(-1) + self.cfg.area.uav_altitude_m**2)
        snr = 10.0 ** (mean_snr_db(dist, self.cfg.radio) / 10.0)
        score = fair_rate(rate_bps(snr, self.cfg.radio.bandwidth_hz, self.cfg.n_ues))  # (N, C)
        best = np.argmax(score, axis=1)
        # Re-derive the actual move after the geofence clip so the action lands where scored.
        return self.mapping.towards(uav_cand[np.arange(len(best)), best] - truth.uav_xy_m, 1.0)
