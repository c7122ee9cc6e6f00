"""PPO training on the batched VecEnv, as the paper configures it (SPEC "What the paper reports").

``TrainConfig`` (uavlink.config) holds the paper's hyper-parameters and, marked as such, the choices
the paper does not state. Imports torch and stable-baselines3 (inside the functions that need them).
"""

from __future__ import annotations

import json
import logging
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from uavlink.config import (
    CRITIC_ACTOR,
    CRITIC_PRIVILEGED,
    PAPER_HYPERPARAMETERS,
    EnvConfig,
    TrainConfig,
)
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.learn.held_exploration import held_exploration_callback
from uavlink.learn.imitation import CLONE_EPOCHS, critic_warmup_callback, warm_start
from uavlink.learn.monitor import save_checkpoint, training_monitor
from uavlink.learn.policy_transfer import start_from_policy
from uavlink.learn.selection import keep_best_callback
from uavlink.learn.snapshot import (
    check_can_snapshot,
    read_snapshot,
    restore_model,
    snapshot_callback,
)
from uavlink.learn.teachers import warm_start_teacher
from uavlink.policies.manifest import build_manifest, write_zip_manifest
from uavlink.policies.sb3_policy import privileged_critic_policy

__all__ = [
    "check_checkpoint",
    "make_model",
    "time_to_fraction",
    "train",
    "training_env_config",
]


def training_env_config(cfg: EnvConfig, tc: TrainConfig) -> EnvConfig:
    """The env PPO trains in: the policy's env ``cfg`` plus the training's AoA noise randomisation
    (``tc.aoa_noise_max_deg`` into ``RadioConfig.aoa_noise_max_deg``, which the env core reads). The
    manifest keeps ``cfg``: the randomisation is the training's, not the policy's env."""
    return (
        cfg.replace(aoa_noise_max_deg=tc.aoa_noise_max_deg).validate()
        if tc.aoa_noise_max_deg
        else cfg
    )


def make_model(cfg: EnvConfig, tc: TrainConfig, run_dir: Path | None):
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecEnv

    from uavlink.env.vec_env import FleetSizesVecEnv, UavVecEnv  # SB3's VecEnv: torch

    if tc.n_steps % cfg.episode_frames:
        # the batched env's episodes end together: a rollout of whole episodes never bootstraps a
        # cut-off return from a critic that sees no episode clock (docs/design/learning.md, "PPO settings")
        logging.getLogger(__name__).warning(
            "train.n_steps=%d is not a multiple of env.episode_frames=%d: rollouts cut episodes, which "
            "biases PPO's advantages; set --n-steps %d",
            tc.n_steps,
            cfg.episode_frames,
            cfg.episode_frames,
        )
    torch.set_num_threads(tc.torch_threads)
    env: VecEnv = (
        FleetSizesVecEnv.for_sizes(training_env_config(cfg, tc), tc.fleet_sizes, tc.n_envs, tc.seed)
        if tc.fleet_sizes
        else UavVecEnv(training_env_config(cfg, tc), n_envs=tc.n_envs, seed=tc.seed)
    )
    if tc.critic == CRITIC_PRIVILEGED:  # its columns, in training only (learn/privileged.py)
        from uavlink.learn.privileged import privileged_env

        env = privileged_env(env)
    if tc.normalize_reward:
        from stable_baselines3.common.vec_env import VecNormalize

        env = VecNormalize(env, norm_obs=False, norm_reward=True, gamma=tc.gamma)
    policy, policy_kwargs = policy_settings(cfg, tc)
    return PPO(
        policy,
        env,
        **ppo_settings(tc),
        policy_kwargs=policy_kwargs,
        seed=tc.seed,
        device="cpu",
        tensorboard_log=str(run_dir) if run_dir else None,
        verbose=0,
    )


# PPO's settings from TrainConfig (same names on both): a new model's, and what a resumed model takes
# from the command rather than from its checkpoint.
PPO_SETTINGS = (
    "learning_rate",
    "n_steps",
    "batch_size",
    "n_epochs",
    "gamma",
    "gae_lambda",
    "clip_range",
    "ent_coef",
    "vf_coef",
    "max_grad_norm",
)


def ppo_settings(tc: TrainConfig) -> dict[str, Any]:  # PPO's keywords: floats and ints
    return {name: getattr(tc, name) for name in PPO_SETTINGS}


def policy_settings(cfg: EnvConfig, tc: TrainConfig) -> tuple[Any, dict[str, Any]]:
    """PPO's policy and ``policy_kwargs``: SB3's ``MlpPolicy`` with ``tc.net_arch`` for the actor and
    the critic, or with ``tc.critic`` privileged the policy whose critic also reads the privileged
    columns (``uavlink.policies.sb3_policy.PrivilegedCriticPolicy``; its actor reads the first
    ``layout.size``: the observation)."""

    arch = list(tc.net_arch)
    kwargs: dict[str, Any] = {"net_arch": {"pi": arch, "vf": arch}}
    if tc.critic != CRITIC_PRIVILEGED:
        return "MlpPolicy", kwargs

    kwargs["actor_obs_size"] = ObservationLayout.for_config(cfg).size
    return privileged_critic_policy(), kwargs


def training_observation_size(cfg: EnvConfig, tc: TrainConfig) -> int:
    """The width of what PPO's policy reads in training: the observation, plus the privileged
    critic's columns with ``tc.critic`` privileged."""

    size = ObservationLayout.for_config(cfg).size
    if tc.critic == CRITIC_PRIVILEGED:
        from uavlink.learn.privileged import privileged_size

        size += privileged_size(cfg)
    return size


def check_checkpoint(resume: Path, cfg: EnvConfig, tc: TrainConfig) -> None:
    """Refuse checkpoint ``resume`` (a file ``model.save`` wrote) in one line when it is not one, or
    when its observation or network is not what ``cfg`` and ``tc`` build."""
    import zipfile

    from stable_baselines3.common.save_util import load_from_zip_file

    if tc.gsde_log_std is not None:  # held exploration's callback sets its noise up at the start
        raise UserError(f"--resume {resume}: a run exploring with --gsde-log-std cannot resume")
    if not resume.is_file():
        raise UserError(f"--resume {resume}: no such checkpoint")
    if not zipfile.is_zipfile(resume):
        raise UserError(
            f"--resume {resume}: not a checkpoint (an SB3 zip such as RUN_DIR/checkpoint.zip)"
        )
    with zipfile.ZipFile(resume) as archive:
        members = archive.namelist()
    if "data" not in members:
        raise UserError(
            f"--resume {resume}: not a checkpoint (an SB3 zip such as RUN_DIR/checkpoint.zip)"
        )
    data, _, _ = load_from_zip_file(resume, device="cpu", load_data=True)
    assert data is not None  # the zip has its "data" entry (checked above)
    if data.get("use_sde"):  # its saved policy would keep gSDE's noise, which nothing flies
        raise UserError(
            f"--resume {resume}: a checkpoint of a run exploring with gSDE cannot resume"
        )
    kwargs = data.get("policy_kwargs") or {}
    critic = CRITIC_PRIVILEGED if "actor_obs_size" in kwargs else CRITIC_ACTOR
    if critic != tc.critic:
        raise UserError(
            f"--resume {resume}: its critic is {critic!r}, not --critic {tc.critic!r}: "
            f"resume with --critic {critic}"
        )
    size = kwargs.get("actor_obs_size", data["observation_space"].shape[0])
    ours = ObservationLayout.for_config(cfg).size
    if size != ours or data["observation_space"].shape[0] != training_observation_size(cfg, tc):
        raise UserError(
            f"--resume {resume}: its observation has {size} values, this env's {ours}: "
            f"resume in the env it was trained in (the same --scenario family and --set)"
        )
    arch = list(kwargs.get("net_arch", {}).get("pi", []))
    if arch != list(tc.net_arch):
        raise UserError(
            f"--resume {resume}: its network is {arch}, not --net-arch {list(tc.net_arch)}"
        )


def _resumed(
    model: Any, resume: Path, cfg: EnvConfig, tc: TrainConfig, run_dir: Path | None
) -> Any:
    """The checkpoint ``resume`` loaded into ``model``'s env with ``tc``'s PPO settings (SB3 keeps the
    checkpoint's own unless told; the manifest records ``tc``'s)."""
    from stable_baselines3 import PPO

    check_checkpoint(resume, cfg, tc)
    return PPO.load(
        resume,
        env=model.get_env(),
        device="cpu",
        custom_objects=ppo_settings(tc),
        tensorboard_log=str(run_dir) if run_dir else None,
    )


def time_to_fraction(
    curve: list[tuple[int, float]], fraction: float = 0.95, window: int = 10
) -> int | None:
    """First step at which the moving average of episode throughput reaches ``fraction`` of its final value."""
    if len(curve) < window:
        return None
    steps = np.array([s for s, _ in curve])
    smooth = np.convolve([r for _, r in curve], np.ones(window) / window, mode="valid")
    reached = np.flatnonzero(smooth >= fraction * smooth[-1])
    return int(steps[window - 1 + reached[0]]) if len(reached) else None


@contextmanager
def _without_distribution_checks() -> Iterator[None]:
    """Skip torch.distributions' argument checks while SB3 builds a Gaussian for every rollout step
    and minibatch (about 5 % of a 256-row forward pass); a check only, so nothing computed changes."""
    from torch.distributions import Distribution

    before = Distribution._validate_args
    Distribution.set_default_validate_args(False)
    try:
        yield
    finally:
        Distribution.set_default_validate_args(before)


def _warm_start(sb3_policy: Any, cfg: EnvConfig, tc: TrainConfig) -> dict[str, Any]:
    """Clone the teacher TrainConfig names into the actor (uavlink/learn/imitation.py), or start from
    the policy it names (uavlink/learn/policy_transfer.py); the report."""

    ws = tc.warm_start
    if ws.policy:
        return start_from_policy(sb3_policy, cfg, ws.policy, ws.log_std)
    epochs = CLONE_EPOCHS if ws.epochs is None else ws.epochs
    # Every fleet size trained on gets its share of the teacher's episodes, flown by the teacher
    # made for that size.
    sized = [cfg.replace(n_uavs=size).validate() for size in tc.fleet_sizes] or [cfg]
    teachers = [(sized_cfg, *warm_start_teacher(sized_cfg, tc)) for sized_cfg in sized]
    estimator = teachers[0][2]
    report = warm_start(
        sb3_policy,
        [(sized_cfg, teacher) for sized_cfg, teacher, _ in teachers],
        ws.episodes // len(sized),
        tc.seed,
        epochs=epochs,
        log_std=ws.log_std,
        dagger_rounds=ws.dagger_rounds,
    ).to_dict()
    if estimator is not None:
        report["shadow_estimator_r2"] = round(estimator.r2, 4)
    return report


def _announced_warm_start(
    model: Any, cfg: EnvConfig, tc: TrainConfig, progress: bool
) -> dict[str, Any]:
    """``_warm_start`` with a line before and after it on stderr (unless ``progress`` is off): a
    copy with DAgger rounds runs for minutes before PPO's first step."""
    ws, start = tc.warm_start, time.perf_counter()
    if progress:
        rounds = f", {ws.dagger_rounds} DAgger rounds" if ws.dagger_rounds else ""
        source = (
            f"from {ws.policy}"
            if ws.policy
            else f"copying {ws.teacher} ({ws.episodes} episodes{rounds})"
        )
        print(f"warm start: {source}", file=sys.stderr, flush=True)
    cloned = _warm_start(model.policy, training_env_config(cfg, tc), tc)
    if progress:
        minutes = (time.perf_counter() - start) / 60
        print(f"warm start: done in {minutes:.1f} min", file=sys.stderr, flush=True)
    return cloned


def train(
    cfg: EnvConfig,
    tc: TrainConfig,
    out: Path,
    run_dir: Path | None = None,
    resume: Path | None = None,
    progress: bool = True,
    callbacks: Sequence[Any] = (),
    snapshot: Path | None = None,
    snapshot_every_s: float = 60.0,
) -> dict[str, Any]:
    """Train, save ``out`` (SB3 zip with manifest) and return the manifest's training section.
    ``tc`` is validated against ``cfg`` here, so a bad setting fails before any work. ``callbacks``:
    extra SB3 callbacks that only observe (benchmarks/train_throughput.py times the loop with one).
    ``snapshot``: a file the run writes between rollouts (every ``snapshot_every_s`` of wall time)
    and, when it is there at the start, continues from, to the weights the uninterrupted run gives
    (uavlink/learn/snapshot.py); removed once ``out`` is written."""

    tc.validate(cfg)
    snapped = None
    if snapshot is not None:
        check_can_snapshot(tc, resume)
        snapped = read_snapshot(snapshot, cfg, tc)
    model = make_model(cfg, tc, run_dir)
    if snapped is not None:
        # it sets the global random states: nothing from here to `learn` draws from them
        model = restore_model(snapped, tensorboard_log=model.tensorboard_log)
    if resume is not None:
        model = _resumed(model, resume, cfg, tc, run_dir)
    # the wall time counts the warm start too, and a snapshot's time before it was taken
    start = time.perf_counter() - (snapped["elapsed_s"] if snapped else 0.0)
    cloned = snapped["warm_start"] if snapped else None
    if (tc.warm_start.teacher or tc.warm_start.policy) and resume is None and snapped is None:
        cloned = _announced_warm_start(model, cfg, tc, progress)
    if run_dir is None:
        # Without a run folder SB3 would make an empty one under the temp dir for every run.
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    if run_dir is not None:  # made once the inputs have loaded: a bad one leaves no empty folder
        run_dir.mkdir(parents=True, exist_ok=True)
    total_timesteps = tc.total_timesteps(cfg)
    monitor = training_monitor(
        tc.trained_timesteps(cfg), run_dir, tc.checkpoint_every_steps, progress
    )
    callbacks = [monitor, *callbacks]
    if tc.gsde_log_std is not None:  # before the critic warm-up, which freezes the std it finds
        callbacks.append(held_exploration_callback(tc.gsde_log_std))
    warmup = None
    if cloned is not None:
        warmup = critic_warmup_callback(tc.warm_start.critic_rollouts)
        callbacks.append(warmup)
    keep_best = None
    if tc.validation_episodes:
        keep_best = keep_best_callback(cfg, tc.validation_episodes, tc.seed)
        callbacks.append(keep_best)  # last: the weights it leaves are the ones saved
    if snapshot is not None:

        def carried() -> dict[str, Any]:
            return {
                "elapsed_s": time.perf_counter() - start,
                "warm_start": cloned,
                "curve": list(monitor.curve),
                "next_checkpoint": monitor.next_checkpoint,
                "warmup_rollouts": warmup.rollouts_done if warmup is not None else 0,
            }

        callbacks.append(snapshot_callback(snapshot, cfg, tc, carried, snapshot_every_s))
        if snapped is not None:
            monitor.curve[:] = snapped["curve"]
            monitor.next_checkpoint = snapped["next_checkpoint"]
            if warmup is not None:
                warmup.rollouts_done = snapped["warmup_rollouts"]
    try:
        with _without_distribution_checks():
            model.learn(
                total_timesteps=total_timesteps - model.num_timesteps,
                callback=callbacks,
                reset_num_timesteps=resume is None and snapped is None,
                tb_log_name="ppo",
            )
    except KeyboardInterrupt:
        kept = []
        if snapshot is not None and snapshot.is_file():
            kept.append(
                f"the snapshot {snapshot} continues this run exactly: the same command again"
            )
        if run_dir is not None and tc.gsde_log_std is None:  # gSDE's runs cannot resume
            checkpoint = save_checkpoint(model, run_dir)
            kept.append(
                f"checkpoint at {model.num_timesteps:,} steps in {checkpoint}; "
                f"--resume {checkpoint} continues"
            )
        if not kept:
            raise
        raise KeyboardInterrupt("; ".join(kept)) from None
    wall_s = time.perf_counter() - start
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".partial.zip")
    model.save(tmp)
    t95 = time_to_fraction(monitor.curve)
    training = {
        "algo": "PPO (stable-baselines3)",
        "hyperparameters": tc.to_dict(),
        "paper_hyperparameters": list(PAPER_HYPERPARAMETERS),
        "total_timesteps": int(model.num_timesteps),
        "wall_time_s": round(wall_s, 1),
        "steps_to_95pct_final": t95,
        "resumed_from": str(resume) if resume else None,
        "warm_start": cloned,
        "validation": keep_best.report() if keep_best is not None else None,
        "learning_curve": monitor.curve[:: max(1, len(monitor.curve) // 200)],
    }
    write_zip_manifest(tmp, build_manifest(cfg, training))
    tmp.replace(out)
    tmp.with_suffix(".json").replace(out.with_suffix(".json"))
    if run_dir is not None:
        (run_dir / "training.json").write_text(json.dumps(training, indent=2))
    if snapshot is not None:
        snapshot.unlink(missing_ok=True)
    return training
