"""Train one sweep job with PPO's advantages taken against copies of the policy flying the same episodes.

Is PPO held at a good copy by its gradient's noise (research/log/fleet.md, "What moves hotspot's
good copy down")? Most of one episode's return against another's is the episode's own (the UEs'
paths, the field), not what the policy's exploration did in it. Here each fleet size's ``n_envs``
episodes are ``--copies`` copies of ``n_envs / copies`` worlds: every copy is a core of its own
seeded alike, so it draws the same UE paths and shadowing field. The UEs' stream does not depend
on where the UAVs fly; the radio's does (fast fading is drawn per scheduled resource block, and a
cell's share of them follows whom it serves), so each copy's radio stream is set to the first
copy's at every episode's start: the field and the draws at reset are shared, fast fading and AoA
noise within an episode are not (the script stops if the copies' UEs or fields part). Each agent
row's advantage is its Monte-Carlo advantage (return-to-go less the critic's value) less the mean
of the same row's in the other copies, a leave-one-out baseline (Kool et al. 2019, "Buy 4
REINFORCE samples, get a baseline for free!"): the episode's own luck cancels, what this copy's
exploration changed remains. No other copy's term depends on this copy's actions, so the estimate
stays unbiased. The critic still learns GAE's returns. Training only: the actor and the saved
policy are the product's, and evaluate, export and fly as any other.

    python research/paired_ppo.py sweeps/fleet.toml --scenario straight_180 --seed 1 \\
        --out runs/trials/straight_180_paired_seed1.zip [--copies 4] [--measure POLICY]
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
from entry import run_script


def paired_env(cfg: Any, tc: Any, copies: int) -> Any:
    """The fleet sizes' VecEnv of ``make_model``, each size's batch as ``copies`` cores seeded alike
    (parts in the order size 0 copy 0, size 0 copy 1, ...), each behind the privileged critic's
    wrapper."""
    from uavlink.env.vec_env import FleetSizesVecEnv, UavVecEnv
    from uavlink.learn.privileged import PrivilegedVecEnv
    from uavlink.learn.training import training_env_config
    from uavlink.seeding import FLEET_SIZES

    train_cfg = training_env_config(cfg, tc)
    parts = [
        PrivilegedVecEnv(
            UavVecEnv(
                train_cfg.replace(n_uavs=size).validate(),
                tc.n_envs // copies,
                FLEET_SIZES.seed(tc.seed, k),  # a fresh SeedSequence each: spawning moves one on
            )
        )
        for k, size in enumerate(tc.fleet_sizes)
        for _ in range(copies)
    ]
    for start in range(0, len(parts), copies):
        share_radio_at_reset([part.venv.core for part in parts[start : start + copies]])
    return FleetSizesVecEnv(parts)


def share_radio_at_reset(cores: list) -> None:
    """Every episode of ``cores[1:]`` starts from the radio stream ``cores[0]``'s started from (the
    cores reset in list order: FleetSizesVecEnv resets and steps its parts in order)."""
    lead, held = cores[0], {}
    lead_reset = lead.reset

    def reset_lead(seed: Any = None) -> np.ndarray:
        held["state"] = lead.radio_rng.bit_generator.state
        return lead_reset(seed)

    lead.reset = reset_lead
    for core in cores[1:]:

        def reset_copy(seed: Any = None, core: Any = core, plain: Any = core.reset) -> np.ndarray:
            if seed is None and "state" in held:  # a seeded reset reseeds every copy alike
                core.radio_rng.bit_generator.state = held["state"]
            return plain(seed)

        core.reset = reset_copy


def returns_to_go(rewards: np.ndarray, episode_starts: np.ndarray, gamma: float) -> np.ndarray:
    """(T, R) discounted returns to the episode's end within the rollout (whole episodes)."""
    out = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[1], dtype=rewards.dtype)
    for t in reversed(range(len(rewards))):
        if t + 1 < len(rewards):
            running = running * (1.0 - episode_starts[t + 1])
        running = rewards[t] + gamma * running
        out[t] = running
    return out


def leave_one_out(advantages: np.ndarray, edges: np.ndarray, copies: int) -> np.ndarray:
    """Each row's advantage less the mean of the same row's in the other copies of its size; the
    parts between ``edges`` run size by size, ``copies`` of each, alike in rows."""
    out = advantages.copy()
    for start in range(0, len(edges) - 1, copies):
        a, b = int(edges[start]), int(edges[start + copies])
        block = advantages[:, a:b].reshape(len(advantages), copies, -1)
        others = (block.sum(axis=1, keepdims=True) - block) / (copies - 1)
        out[:, a:b] = (block - others).reshape(len(advantages), -1)
    return out


def pair(model: Any, cfg: Any, tc: Any, copies: int, spread: list) -> Any:
    """``model`` on the paired env, its advantages the leave-one-out ones; each rollout appends to
    ``spread`` the std of its Monte-Carlo advantages and of the paired ones."""
    if not tc.fleet_sizes or tc.n_envs % copies:
        raise SystemExit("paired_ppo: a job of several fleet sizes, n_envs a multiple of --copies")
    sizes = paired_env(cfg, tc, copies)
    env = sizes
    if tc.normalize_reward:  # as make_model wraps it
        from stable_baselines3.common.vec_env import VecNormalize

        env = VecNormalize(sizes, norm_obs=False, norm_reward=True, gamma=tc.gamma)
    assert env.num_envs == model.n_envs  # the same agent rows as the job's own env
    model.set_env(env)
    buffer, gamma = model.rollout_buffer, tc.gamma
    gae = buffer.compute_returns_and_advantage

    def compute_returns_and_advantage(last_values: Any, dones: np.ndarray) -> None:
        gae(last_values, dones)  # the critic's targets, as the product trains it
        mc = returns_to_go(buffer.rewards, buffer.episode_starts, gamma) - buffer.values
        buffer.advantages[:] = leave_one_out(mc, sizes._edges, copies)
        spread.append((float(mc.std()), float(buffer.advantages.std())))
        check_copies_agree(sizes, copies)

    buffer.compute_returns_and_advantage = compute_returns_and_advantage
    return model


def paired_model_maker(copies: int, spread: list):
    """``make_model`` with the paired env and the leave-one-out advantages (:func:`pair`)."""
    from uavlink.learn import training

    plain_make_model = training.make_model

    def make_model(cfg: Any, tc: Any, run_dir: Any) -> Any:
        return pair(plain_make_model(cfg, tc, run_dir), cfg, tc, copies, spread)

    return make_model


def measure(policy: Any, job: Any, copies: int, rollouts: int = 3) -> list:
    """``rollouts`` rollouts (and updates) of ``policy`` on the job's paired env: the advantages'
    spread in each (the pairing must hold past the first episode, not only in it)."""
    from stable_baselines3 import PPO

    spread: list = []
    model = pair(PPO.load(policy, device="cpu"), job.env, job.train, copies, spread)
    model.learn(total_timesteps=rollouts * model.n_envs * model.n_steps)
    return spread


def check_copies_agree(env: Any, copies: int) -> None:
    """The copies of a size fly the same UEs in the same field (else the pairing is lost: stop)."""
    grid_m = np.linspace(-150.0, 150.0, 4)
    probes_m = np.stack(np.meshgrid(grid_m, grid_m), axis=-1).reshape(1, -1, 2)  # (1, 16, 2)
    for start in range(0, len(env.parts), copies):
        seen = []
        for part in env.parts[start : start + copies]:
            truth = part.venv.core.ground_truth()
            ues = truth.ue_xy_m
            field_db = truth.shadow_field.shadow_db(np.repeat(probes_m, len(ues), axis=0), ues)
            seen.append(np.concatenate([ues.ravel(), field_db.ravel()]))
        if any(not np.array_equal(seen[0], other) for other in seen[1:]):
            raise SystemExit("paired_ppo: the copies' UEs or fields parted")


def main(argv: list[str] | None = None) -> int:
    from frozen_std_train import curve_sixths, sweep_job

    copies = ("--copies", {"type": int, "default": 4, "help": "copies of each world (default 4)"})
    probe = (
        "--measure",
        {"metavar": "POLICY", "help": "fly POLICY three rollouts, print the spread"},
    )
    args, job = sweep_job(__doc__.split("\n\n")[0], argv, copies, probe, out_unless="measure")
    if args.measure:
        if not Path(args.measure).is_file():
            from uavlink.errors import UserError

            raise UserError(f"--measure {args.measure}: no such file")
        for k, (mc, paired) in enumerate(measure(args.measure, job, args.copies)):
            print(
                f"{args.measure}, rollout {k}: advantage std {mc:.4f} Monte-Carlo, {paired:.4f} paired"
            )
        return 0

    from uavlink.learn.training import train

    spread: list = []
    with mock.patch("uavlink.learn.training.make_model", paired_model_maker(args.copies, spread)):
        training = train(job.env, job.train, args.out, progress=False)
    sixths = curve_sixths(training)
    ratio = np.mean([p / m for m, p in spread])
    print(
        f"{job.name}, {args.copies} copies of each world -> {args.out}; curve in sixths {sixths}; "
        f"paired / Monte-Carlo advantage std {ratio:.3f} (mean over rollouts)"
    )
    return 0


if __name__ == "__main__":
    run_script(main)
