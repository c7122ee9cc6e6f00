"""PPO training on the batched VecEnv, as the paper configures it (SPEC "What the paper reports").

Reads as the experiment's spec: ``TrainConfig`` holds the paper's hyper-parameters and, marked as
such, the choices the paper does not state. Imports torch and stable-baselines3.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from uavlink.config import EnvConfig

# What the paper states; everything else in TrainConfig is our choice.
PAPER_HYPERPARAMETERS = ("learning_rate", "net_arch", "gamma", "gae_lambda", "max_grad_norm",
                         "clip_range", "episodes")


@dataclass
class TrainConfig:
    # The paper's (SPEC): 12,000 episodes x 128 frames, lr 3e-4, 3 x 128 actor and critic,
    # gamma 0.99, GAE lambda 0.95, max grad norm 1.0, clip 0.2. Memory M = 4 lives in EnvConfig.
    episodes: int = 12_000
    learning_rate: float = 3e-4
    net_arch: tuple[int, ...] = (128, 128, 128)
    gamma: float = 0.99
    gae_lambda: float = 0.95
    max_grad_norm: float = 1.0
    clip_range: float = 0.2
    # Not stated by the paper (ours): rollout = one 128-frame episode in each of n_envs envs.
    n_envs: int = 32
    n_steps: int = 128
    batch_size: int = 512
    n_epochs: int = 10
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    # Scale rewards by a running estimate of the return's std (SB3 VecNormalize, rewards only):
    # undiscounted returns reach ~100, and without it the critic's gradient dominates the shared
    # max-grad-norm clip. Observations are already O(1) by construction and are not normalised,
    # so the saved policy needs no statistics at inference.
    normalize_reward: bool = True
    # Domain randomisation (ours): when > 0, every training episode draws its AoA noise std
    # uniformly from [aoa_noise_deg, aoa_noise_max_deg], so one policy holds up under noisy AoA
    # estimates. Training only: the manifest's env config, and so every evaluation, keep the
    # env's own fixed noise.
    aoa_noise_max_deg: float = 0.0
    # Behaviour-cloning warm start (ours; uavlink/imitation.py): when set to a baseline's name,
    # the actor is first fitted to that rule's actions over warm_start_episodes of its own flying
    # and its exploration std set to exp(warm_start_log_std); PPO then fits only the critic for
    # warm_start_critic_rollouts rollouts (the actor frozen) and trains as usual after that.
    warm_start_teacher: str = ""
    warm_start_episodes: int = 256
    warm_start_epochs: int | None = None  # passes over the cloning data; None: imitation.CLONE_EPOCHS (20)
    warm_start_log_std: float = -1.0
    warm_start_critic_rollouts: int = 10  # PPO updates with the actor frozen, fitting the critic
    # The aoa teacher with its shadow gate (AoaPolicy): it hovers when the newest frame's mean SINR
    # beats the older frames' by more than this many dB. None: the SPEC's rule as it is.
    warm_start_shadow_gate_db: float | None = None
    # The aoa teacher's speed span (AoaPolicy.sinr_span_db): full speed this many dB below the hover
    # SINR. None: the baseline's.
    warm_start_sinr_span_db: float | None = None
    # Gate the aoa teacher on a shadowing estimate (uavlink/shadow_estimation.py) fitted on this many
    # episodes, instead of on the SINR jump: it hovers while the estimated mean shadowing of the links
    # is above warm_start_shadow_gate_db. None: the SINR jump.
    warm_start_shadow_estimator_episodes: int | None = None
    seed: int = 0
    torch_threads: int = 1
    checkpoint_every_steps: int = 100_000
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def total_timesteps(self) -> int:
        return self.episodes * 128

    def hyperparameters(self) -> dict[str, Any]:
        data = dataclasses.asdict(self)
        data["net_arch"] = list(self.net_arch)
        return data


def training_env_config(cfg: EnvConfig, tc: TrainConfig) -> EnvConfig:
    """The env PPO trains in: ``cfg`` plus the training-only AoA noise randomisation."""
    return cfg.replace(aoa_noise_max_deg=tc.aoa_noise_max_deg).validate() if tc.aoa_noise_max_deg else cfg


def make_model(cfg: EnvConfig, tc: TrainConfig, run_dir: Path | None):
    import torch
    from stable_baselines3 import PPO

    from uavlink.env.vec_env import UavVecEnv

    torch.set_num_threads(tc.torch_threads)
    env = UavVecEnv(training_env_config(cfg, tc), n_envs=tc.n_envs, seed=tc.seed)
    if tc.normalize_reward:
        from stable_baselines3.common.vec_env import VecNormalize

        env = VecNormalize(env, norm_obs=False, norm_reward=True, gamma=tc.gamma)
    arch = list(tc.net_arch)
    return PPO(
        "MlpPolicy", env, learning_rate=tc.learning_rate, n_steps=tc.n_steps, batch_size=tc.batch_size,
        n_epochs=tc.n_epochs, gamma=tc.gamma, gae_lambda=tc.gae_lambda, clip_range=tc.clip_range,
        ent_coef=tc.ent_coef, vf_coef=tc.vf_coef, max_grad_norm=tc.max_grad_norm,
        policy_kwargs={"net_arch": {"pi": arch, "vf": arch}}, seed=tc.seed, device="cpu",
        tensorboard_log=str(run_dir) if run_dir else None, verbose=0,
    )


def _callback(total: int, run_dir: Path | None, checkpoint_every: int, progress: bool):
    from stable_baselines3.common.callbacks import BaseCallback

    class TrainingMonitor(BaseCallback):
        """Progress bar with the mean episode throughput, learning curve, periodic checkpoint."""

        def __init__(self) -> None:
            super().__init__()
            self.curve: list[tuple[int, float]] = []
            self._bar = None
            self._next_checkpoint = checkpoint_every

        def _on_training_start(self) -> None:
            if progress:
                from tqdm.auto import tqdm

                # disable=None: no bar when stderr is not a terminal (logs, pipes, CI)
                self._bar = tqdm(total=total, initial=self.num_timesteps, unit="step", dynamic_ncols=True,
                                 disable=None)

        def _on_step(self) -> bool:
            rates = [i["episode"]["mean_rate_mbps"] for i in self.locals["infos"] if "episode" in i]
            if rates:
                mean = float(np.mean(rates))
                self.curve.append((int(self.num_timesteps), round(mean, 4)))
                self.logger.record("rollout/mean_rate_mbps", mean)
                if self._bar is not None:
                    self._bar.set_postfix_str(f"{mean:.2f} Mbps")
            if self._bar is not None:
                self._bar.n = min(self.num_timesteps, total)
                self._bar.refresh() if self.num_timesteps % 4096 < self.training_env.num_envs else None
            if run_dir is not None and self.num_timesteps >= self._next_checkpoint:
                self.model.save(run_dir / "checkpoint.zip")
                self._next_checkpoint += checkpoint_every
            return True

        def _on_training_end(self) -> None:
            if self._bar is not None:
                self._bar.n = min(self.num_timesteps, total)
                self._bar.close()

    return TrainingMonitor()


def time_to_fraction(curve: list[tuple[int, float]], fraction: float = 0.95, window: int = 10) -> int | None:
    """First step at which the moving average of episode throughput reaches ``fraction`` of its final value."""
    if len(curve) < window:
        return None
    steps = np.array([s for s, _ in curve])
    smooth = np.convolve([r for _, r in curve], np.ones(window) / window, mode="valid")
    reached = np.flatnonzero(smooth >= fraction * smooth[-1])
    return int(steps[window - 1 + reached[0]]) if len(reached) else None


def _warm_start(sb3_policy: Any, cfg: EnvConfig, tc: TrainConfig) -> dict[str, Any]:
    """Clone the teacher TrainConfig names into the actor (uavlink/imitation.py); the report."""
    from uavlink.imitation import CLONE_EPOCHS, make_teacher, warm_start

    estimator = None
    if tc.warm_start_shadow_estimator_episodes is not None:
        from uavlink.shadow_estimation import fit_shadow_estimator

        estimator = fit_shadow_estimator(cfg, tc.warm_start_shadow_estimator_episodes, tc.seed)
    teacher = make_teacher(cfg, tc.warm_start_teacher, tc.warm_start_shadow_gate_db, tc.warm_start_sinr_span_db,
                           estimator)
    epochs = CLONE_EPOCHS if tc.warm_start_epochs is None else tc.warm_start_epochs
    report = warm_start(sb3_policy, cfg, teacher, tc.warm_start_episodes, tc.seed, epochs=epochs,
                        log_std=tc.warm_start_log_std).to_dict()
    if estimator is not None:
        report["shadow_estimator_r2"] = round(estimator.r2, 4)
    return report


def train(cfg: EnvConfig, tc: TrainConfig, out: Path, run_dir: Path | None = None,
          resume: Path | None = None, progress: bool = True) -> dict[str, Any]:
    """Train, save ``out`` (SB3 zip with manifest) and return the manifest's training section."""
    from stable_baselines3 import PPO

    from uavlink.policies.manifest import build_manifest, write_zip_manifest

    if run_dir is not None:
        run_dir.mkdir(parents=True, exist_ok=True)
    model = make_model(cfg, tc, run_dir)
    if resume is not None:
        model = PPO.load(resume, env=model.get_env(), device="cpu", tensorboard_log=str(run_dir) if run_dir else None)
    start = time.perf_counter()  # the wall time counts the warm start too
    cloned = None
    if tc.warm_start_teacher and resume is None:
        cloned = _warm_start(model.policy, training_env_config(cfg, tc), tc)
    if run_dir is None:
        # Without a run folder SB3 would make an empty one under the temp dir for every run.
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))
    monitor = _callback(tc.total_timesteps, run_dir, tc.checkpoint_every_steps, progress)
    callbacks = [monitor]
    if cloned is not None:
        from uavlink.imitation import critic_warmup_callback

        callbacks.append(critic_warmup_callback(tc.warm_start_critic_rollouts))
    model.learn(total_timesteps=tc.total_timesteps - model.num_timesteps, callback=callbacks,
                reset_num_timesteps=resume is None, tb_log_name="ppo")
    wall_s = time.perf_counter() - start
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".partial.zip")
    model.save(tmp)
    t95 = time_to_fraction(monitor.curve)
    training = {
        "algo": "PPO (stable-baselines3)",
        "hyperparameters": tc.hyperparameters(),
        "paper_hyperparameters": list(PAPER_HYPERPARAMETERS),
        "total_timesteps": int(model.num_timesteps),
        "wall_time_s": round(wall_s, 1),
        "steps_to_95pct_final": t95,
        "resumed_from": str(resume) if resume else None,
        "warm_start": cloned,
        "learning_curve": monitor.curve[:: max(1, len(monitor.curve) // 200)],
    }
    write_zip_manifest(tmp, build_manifest(cfg, training))
    tmp.replace(out)
    tmp.with_suffix(".json").replace(out.with_suffix(".json"))
    if run_dir is not None:
        (run_dir / "training.json").write_text(json.dumps(training, indent=2))
    return training
