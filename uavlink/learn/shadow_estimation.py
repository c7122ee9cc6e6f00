"""A GPS-free estimate of the links' shadowing from the observation (ours), for the aoa teacher's gate
(``uavlink.learn.teachers.AoaVariant``).

Under the SPEC's shadowing (Gudmundson: it decorrelates with displacement and has no memory of
place) a favourable draw is worth keeping by hovering, and moving re-draws it (docs/design/radio.md). The
base station cannot read shadowing, but its SINR history carries much of it: path loss changes little
from frame to frame, the shadowing changes with the UAV's and the UEs' displacement. ``ShadowEstimator``
is a ridge regression from features of the observation window (``shadow_features``) to the mean
shadowing of the UE links in dB. It is fitted on simulated episodes, where the channel's true
shadowing is known (privileged labels, in simulation only), and then reads observations alone, so a
policy that uses it stays GPS-free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uavlink.config import EnvConfig
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.policies.baselines import AoaPolicy
from uavlink.rollout import chunks
from uavlink.seeding import SHADOW, SHADOW_HELD_OUT, SHADOW_HELD_OUT_HOVERS, SHADOW_HOVERS

# The data's rule hovers at random in this share of frames, so both are seen.
HOVER_PROBABILITY = 0.3
RIDGE = 1.0  # L2 penalty on the weights (features are O(1) to O(10))


def shadow_features(layout: ObservationLayout, obs: np.ndarray) -> np.ndarray:
    """Features (N, F) of observations (N, size): per-UE SINRs (dB) of every frame in memory, the
    newest frame's SINRs minus each older frame's, their means over UEs, the UAV's displacement (m)
    between frames, the AoA features, and a constant."""
    n = obs.shape[0]
    sinr_db = layout.sinr_db_history(obs)  # (N, memory, U), newest first
    uav_xy_m = layout.uav_xy_m_history(obs)
    displacement_m = np.linalg.norm(uav_xy_m[:, :-1] - uav_xy_m[:, 1:], axis=2)
    jump_db = sinr_db[:, :1] - sinr_db[:, 1:]
    return np.concatenate(
        [
            sinr_db.reshape(n, -1),
            jump_db.reshape(n, -1),
            sinr_db.mean(axis=2),
            jump_db.mean(axis=2),
            displacement_m,
            layout.aoa_feature_history(obs).reshape(n, -1),
            np.ones((n, 1)),
        ],
        axis=1,
    )


@dataclass(frozen=True)
class ShadowEstimator:
    """Linear estimate of the links' mean shadowing (dB) from an observation window."""

    layout: ObservationLayout
    weights: np.ndarray
    r2: float  # coefficient of determination on held-out episodes

    def predict_db(self, obs: np.ndarray) -> np.ndarray:
        """Estimated mean shadowing (N,) in dB of the links, for observations (N, size)."""
        return shadow_features(self.layout, obs) @ self.weights


class RandomHovers:
    """The aoa rule, hovering instead in a random ``HOVER_PROBABILITY`` share of frames (``draws``)."""

    needs_truth = False

    def __init__(self, rule: AoaPolicy, draws: np.random.Generator) -> None:
        self.rule, self.draws, self.name, self.layout = rule, draws, rule.name, rule.layout

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        hover = self.draws.random(int(obs.shape[0])) < HOVER_PROBABILITY  # int: an array, (N,)
        return np.where(hover[:, None], self.rule.hover, self.rule.act(obs))


def shadow_dataset(
    cfg: EnvConfig, episodes: int, seed: int, held_out: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """(features, mean shadowing dB) of every frame with a full memory, from ``episodes`` seeded
    episodes flown by the aoa rule with random hovers; ``held_out`` draws another set of episodes."""
    rule, layout = AoaPolicy(cfg), ObservationLayout.for_config(cfg)
    stream, hovers = (
        (SHADOW_HELD_OUT, SHADOW_HELD_OUT_HOVERS) if held_out else (SHADOW, SHADOW_HOVERS)
    )
    features, targets = [], []
    for chunk in chunks(cfg, stream, episodes, seed):
        for frame in chunk.frames(RandomHovers(rule, hovers.generator(seed, chunk.index))):
            if frame.index + 1 >= cfg.memory:
                features.append(shadow_features(layout, frame.result.observation))
                targets.append(frame.env.channel.shadow_db.mean(axis=(1, 2)))
    return np.concatenate(features), np.concatenate(targets)


def fit_shadow_estimator(cfg: EnvConfig, episodes: int, seed: int) -> ShadowEstimator:
    """Ridge-fit the estimator on ``episodes`` episodes; its R² is measured on a quarter as many
    other episodes."""
    if cfg.memory < 2:
        raise ValueError("the shadow estimator compares frames: it needs memory >= 2")
    if not cfg.radio.shadowing:
        raise ValueError("radio.shadowing is off: there is no shadowing to estimate")
    x, y = shadow_dataset(cfg, episodes, seed)
    weights = np.linalg.solve(x.T @ x + RIDGE * np.eye(x.shape[1]), x.T @ y)
    x_held, y_held = shadow_dataset(cfg, max(1, episodes // 4), seed, held_out=True)
    r2 = 1.0 - float(np.mean((x_held @ weights - y_held) ** 2) / np.var(y_held))
    return ShadowEstimator(ObservationLayout.for_config(cfg), weights, r2)
