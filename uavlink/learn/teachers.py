"""The rules the warm start clones (ours, not the SPEC's): variants of the aoa rule and the privileged
teacher that flies them on the UEs' true AoAs.

``AoaVariant`` is the aoa rule with another speed span and/or a shadow gate that hovers where the
links look favourably shadowed, a draw that moving would throw away (docs/design/learning.md); it stays
GPS-free, so benchmarks evaluate it like any policy. ``TrueAoaTeacher`` flies a rule on the true
AoAs instead of the observation's estimates and says so with ``needs_truth``: under heavy AoA noise
the student then learns what the noisy observation implies about the clean rule's move, not to copy
a rule that flies wherever the noise points. ``make_teacher`` builds what ``TrainConfig`` names
(``warm_start_teacher`` from a config, ``policy_teacher`` from a trained policy's manifest).
The shadowing estimator a gate can read lives in ``uavlink.learn.shadow_estimation``.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from uavlink.config import EnvConfig, TrainConfig, WarmStartConfig
from uavlink.config.train import TEACHER_NAMES
from uavlink.env.actions import ActionMapping
from uavlink.env.core import GroundTruth
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.learn.lead_teacher import area_corners_m, away_target_m, make_lead_teacher
from uavlink.policies.baselines import AoaPolicy
from uavlink.policies.fleet_baselines import FleetAoaPolicy, KMeansPolicy
from uavlink.policies.manifest import PolicyFileError, read_zip_manifest
from uavlink.policies.registry import make_baseline
from uavlink.radio.aoa import circular_mean_std_deg, true_aoa_deg


class ShadowEstimate(Protocol):
    """Anything that estimates the links' mean shadowing (dB) from observations (N, size), such as
    ``uavlink.learn.shadow_estimation.ShadowEstimator``."""

    def predict_db(self, obs: np.ndarray) -> np.ndarray: ...


class AoaVariant(AoaPolicy):
    """The aoa rule with its speed span replaced and an optional shadow gate; GPS-free.

    With ``shadow_gate_db`` set it hovers instead wherever the links look favourably shadowed.
    Without an estimator: where the newest frame's mean SINR beats the mean of the older frames in
    memory by more than the gate (path loss changes little from frame to frame, so such a jump is
    mostly a good shadowing draw). With one: where the estimated mean shadowing is above the gate.
    """

    def __init__(
        self,
        cfg: EnvConfig,
        sinr_span_db: float = AoaPolicy.sinr_span_db,
        shadow_gate_db: float | None = None,
        shadow_estimator: ShadowEstimate | None = None,
    ) -> None:
        super().__init__(cfg)
        if shadow_gate_db is not None and cfg.memory < 2:
            raise UserError("the aoa rule's shadow gate compares frames: it needs memory >= 2")
        if shadow_estimator is not None and shadow_gate_db is None:
            raise UserError("a shadow estimator needs the gate's threshold (shadow_gate_db)")
        self.sinr_span_db = sinr_span_db
        self.shadow_gate_db = shadow_gate_db
        self.shadow_estimator = shadow_estimator

    def act_towards(self, obs: np.ndarray, aoa_mean_deg: np.ndarray) -> np.ndarray:
        action = super().act_towards(obs, aoa_mean_deg)
        if self.shadow_gate_db is None:
            return action
        if self.shadow_estimator is not None:
            lucky = self.shadow_estimator.predict_db(obs) > self.shadow_gate_db
        else:
            mean_sinr_db = self.layout.sinr_db_history(obs).mean(
                axis=2
            )  # (N, memory), newest first
            lucky = mean_sinr_db[:, 0] > mean_sinr_db[:, 1:].mean(axis=1) + self.shadow_gate_db
        return np.where(lucky[:, None], self.hover, action)


class TrueAoaTeacher:
    """``rule`` flown on the UEs' true AoAs (privileged: reads ground truth, never flies for real)."""

    needs_truth = True

    def __init__(self, rule: AoaPolicy) -> None:
        self.rule = rule
        self.name = rule.name
        self.layout = rule.layout

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError(
                "the true-AoA teacher needs ground truth; it cannot fly from MAVLink data"
            )
        aoa_mean_deg, _ = circular_mean_std_deg(
            true_aoa_deg(truth.uav_xy_m[:, None, :], truth.ue_xy_m)
        )
        return self.rule.act_towards(obs, aoa_mean_deg)


def make_teacher(
    cfg: EnvConfig,
    teacher: str,
    shadow_gate_db: float | None = None,
    sinr_span_db: float | None = None,
    shadow_estimator: ShadowEstimate | None = None,
    leader_policy: str = "",
    spread_m: float | None = None,
) -> Any:
    """The warm start's teacher named ``teacher``: the aoa rule (or its variant, when
    ``shadow_gate_db``, ``sinr_span_db`` or ``shadow_estimator`` is set) on the true AoAs, a
    fleet's ``solo``, ``bearings``, ``spread`` (aiming ``spread_m`` from the other groups, if set)
    or ``lead`` teacher (the latter's leader flies ``leader_policy``, a single-UAV policy file, or
    the single-UAV aoa rule), or another baseline as it is. A combination no teacher takes is
    refused by ``WarmStartConfig``'s own checks, as ``uavlink train`` refuses it."""
    if teacher not in TEACHER_NAMES:
        raise UserError(f"unknown teacher {teacher!r}; choose from {', '.join(TEACHER_NAMES)}")
    ws = WarmStartConfig(
        teacher=teacher,
        shadow_gate_db=shadow_gate_db,
        sinr_span_db=sinr_span_db,
        leader_policy=leader_policy,
        spread_m=spread_m,
    ).validate()
    ws.check_env(cfg)
    if shadow_estimator is not None and shadow_gate_db is None:
        raise UserError("a shadow estimator needs the gate's threshold (shadow_gate_db)")
    if teacher == "lead":
        return make_lead_teacher(cfg, leader_policy)
    if teacher == "solo":
        return SoloTeacher(cfg)
    if teacher == "bearings":
        return BearingsTeacher(cfg)
    if teacher == "spread":
        return SpreadTeacher(cfg) if spread_m is None else SpreadTeacher(cfg, spread_m=spread_m)
    if teacher != "aoa":
        return make_baseline(teacher, cfg)
    if cfg.n_uavs > 1:  # a fleet's aoa rule, with its speed span replaced if asked
        return (
            make_baseline(teacher, cfg)
            if sinr_span_db is None
            else FleetAoaPolicy(cfg, sinr_span_db=sinr_span_db)
        )
    if shadow_gate_db is None and sinr_span_db is None:
        return TrueAoaTeacher(AoaPolicy(cfg))
    span = {} if sinr_span_db is None else {"sinr_span_db": sinr_span_db}
    return TrueAoaTeacher(
        AoaVariant(cfg, shadow_gate_db=shadow_gate_db, shadow_estimator=shadow_estimator, **span)
    )


def warm_start_teacher(cfg: EnvConfig, tc: TrainConfig) -> tuple[Any, Any]:
    """The teacher ``tc.warm_start`` names, built as training builds it (the shadowing estimator its
    gate reads refitted on the same episodes of the training seed), and that estimator (or None)."""
    ws = tc.warm_start
    estimator = None
    if ws.shadow_estimator_episodes is not None:
        from uavlink.learn.shadow_estimation import fit_shadow_estimator

        estimator = fit_shadow_estimator(cfg, ws.shadow_estimator_episodes, tc.seed)
    return make_teacher(
        cfg,
        ws.teacher,
        ws.shadow_gate_db,
        ws.sinr_span_db,
        estimator,
        ws.leader_policy,
        ws.spread_m,
    ), estimator


def policy_teacher(policy: Any, cfg: EnvConfig) -> tuple[Any | None, str]:
    """A trained policy's warm-start teacher rebuilt from its manifest (``training.hyperparameters``)
    to fly ``cfg``, and a label naming the rule and its knobs, e.g. ``aoa (span 3, gate 2)``; None and
    a label saying why for a policy that copied no rule (no warm start). A policy that started from
    another policy's weights (``warm_start.policy``) has that policy's teacher, followed back along
    the chain while the start file is there (its path as the training read it, from the working
    folder): a stage of training is not a new teacher."""
    return _manifest_teacher((getattr(policy, "manifest", None) or {}), cfg, via=())


def _manifest_teacher(
    manifest: dict[str, Any], cfg: EnvConfig, via: tuple[str, ...]
) -> tuple[Any | None, str]:
    training = manifest.get("training") or {}
    tc = TrainConfig.from_dict(training.get("hyperparameters") or {})
    ws = tc.warm_start
    if ws.policy:
        teacher, label = None, ""
        if ws.policy not in via:  # a file cannot have trained from itself; refuse to loop
            with contextlib.suppress(PolicyFileError):  # the start file is gone or foreign
                start = read_zip_manifest(Path(ws.policy))
                teacher, label = _manifest_teacher(start, cfg, (*via, ws.policy))
        if teacher is None:
            return None, f"the weights of {ws.policy}"
        return teacher, f"{label} via {ws.policy}"
    if not ws.teacher:
        return None, "no warm start"
    knobs = [
        f"{k} {v:g}"
        for k, v in (
            ("span", ws.sinr_span_db),
            ("gate", ws.shadow_gate_db),
            ("estimator", ws.shadow_estimator_episodes),
            ("spread_m", ws.spread_m),
        )
        if v is not None
    ]
    return warm_start_teacher(cfg, tc)[0], ws.teacher + (f" ({', '.join(knobs)})" if knobs else "")


class SoloTeacher:
    """A fleet's warm-start teacher for UEs that stay together (GPS, privileged; training only):
    the UAV nearest the UEs' centroid flies to it; every other UAV heads for the corner of the
    area farthest from the centroid and, while its cell still holds a UE (shadowing can favour a
    far UAV), moves on along the wall to the next far corner, holding once its cell is empty. With
    one group a second active cell only takes UEs and interferes with all the others (SPEC "A
    fleet": the greedy oracle loses 3-15 % there); an empty cell is silent."""

    name = "solo"
    needs_truth = True

    def __init__(self, cfg: EnvConfig) -> None:
        self.cfg = cfg
        self.mapping = ActionMapping.for_config(cfg)
        self.layout = ObservationLayout.for_config(cfg)
        self.corners = area_corners_m(cfg)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError("the solo teacher needs ground truth")
        n_uavs = self.cfg.n_uavs
        uav = truth.uav_xy_m.reshape(-1, n_uavs, 2)
        centroid = truth.ue_xy_m.mean(axis=1)[:, None, :]  # (N, 1, 2)
        dist = np.linalg.norm(uav - centroid, axis=2)
        leader = dist.argmin(axis=1)[:, None] == np.arange(n_uavs)  # (N, D)
        serving = np.asarray(self.layout.own_cell(self.layout.newest_frame(obs)).any(axis=1))
        centroids = np.repeat(centroid[:, 0], n_uavs, axis=0)  # agent rows
        away = away_target_m(self.corners, truth.uav_xy_m, centroids, serving)
        target = np.where(leader.reshape(-1, 1), centroids, away)
        return self.mapping.towards(target - truth.uav_xy_m, 1.0)


class BearingsTeacher:
    """A fleet's GPS-free teacher (any-size layout, v6): each UAV flies towards the centroid of the
    UEs it serves, located by the bearings every UAV hears of them (the layout's ``ue_fix_offset_m``);
    a UAV that serves none holds. With every UE attached to its strongest UAV, that is one step of
    Lloyd's k-means per frame from where the fleet is, so the fleet settles on a k-means split of
    the UEs without reading their GPS; an empty cell stays silent."""

    name = "bearings"
    needs_truth = False

    def __init__(self, cfg: EnvConfig) -> None:
        self.layout = ObservationLayout.for_config(cfg)
        self.mapping = ActionMapping.for_config(cfg)

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        frame = self.layout.newest_frame(obs)
        mine = self.layout.own_cell(frame)  # (rows, U)
        count = np.maximum(mine.sum(axis=1), 1)[:, None]
        centroid = (frame["ue_fix_offset_m"] * mine[..., None]).sum(axis=1) / count
        return self.mapping.towards(centroid, 1.0)


class SpreadTeacher(KMeansPolicy):
    """A fleet's warm-start teacher where the UEs split (GPS, privileged; training only): kmeans's
    split, each UAV aiming ``lead_frames`` frames ahead of its group's centroid along the group's
    mean velocity and ``spread_m`` further from the other groups (away from their centroids'
    mean). Full reuse makes every other cell interference, so a UAV a little outside its group
    trades some of its own UEs' path gain for less interference at theirs and its neighbours'; and
    a UAV that flies to where the centroid was lags moving UEs by a frame. Both constants were
    chosen on validation episodes (research/log/fleet.md, "A spread kmeans teacher"): against
    kmeans +1.7 / +4.9 / +7.9 % on straight_180 and +3.1 / +3.6 / +2.3 % on hotspot at D = 2 / 3 / 4.
    """

    name = "spread"

    def __init__(self, cfg: EnvConfig, spread_m: float = 20.0, lead_frames: float = 1.0) -> None:
        super().__init__(cfg)
        self.spread_m = spread_m
        self.lead_frames = lead_frames

    def act(self, obs: np.ndarray, truth: GroundTruth | None = None) -> np.ndarray:
        if truth is None:
            raise ValueError("the spread teacher needs ground truth")
        centroid_m, velocity_mps = self.groups(truth)
        target_m = centroid_m + self.lead_frames * self.cfg.frame_s * velocity_mps
        away = target_m - self.others_m(target_m)
        away /= np.maximum(np.linalg.norm(away, axis=2, keepdims=True), 1e-9)
        target_m = target_m + self.spread_m * away
        return self.mapping.towards(target_m.reshape(-1, 2) - truth.uav_xy_m, 1.0)

    def others_m(self, target_m: np.ndarray) -> np.ndarray:
        """The point (N, D, 2) each UAV's target moves away from: the other targets' mean."""
        return (target_m.sum(axis=1, keepdims=True) - target_m) / (self.cfg.n_uavs - 1)
