"""Train one sweep job with a privileged critic that also reads the shadowing field.

The shipped privileged critic (uavlink/learn/privileged.py) reads the UEs' true positions and
velocities, not the field, which decides 40-50 % of a fleet's throughput; GAE turns the errors of
a critic blind to it into biased advantages, and Monte-Carlo advantages mostly stopped PPO moving
hotspot's good copy down (research/log/fleet.md, "What moves hotspot's good copy down"). Here the
critic also reads, per agent row and per UE, the link's shadowing from this UAV and from eight
points around it (20 and 40 m towards the four axes), and each UE's best current link in the
fleet, all over the shadowing std: where the field is better near this UAV, which the actor
cannot see. Training only; the actor, the saved policy's only flying part, reads the observation
alone, so the policy evaluates, exports and flies as any other.

    python research/field_critic.py research/sweeps/fleet_spread.toml --scenario hotspot \\
        --seed 1 --out runs/trials/hotspot_field_critic_seed1.zip
"""

from __future__ import annotations

import sys
from typing import Any
from unittest import mock

import numpy as np
from entry import run_script

PROBE_RADII_M = (20.0, 40.0)
PROBE_BEARINGS_DEG = (0.0, 90.0, 180.0, 270.0)


def probe_offsets_m() -> np.ndarray:
    """(P, 2): this UAV's own position first, then the probes around it."""
    rad = np.radians(PROBE_BEARINGS_DEG)
    ring = [(r * np.cos(a), r * np.sin(a)) for r in PROBE_RADII_M for a in rad]
    return np.array([(0.0, 0.0), *ring])


def field_width(n_ues: int) -> int:
    """Columns the field adds: every probe's shadowing per UE, and each UE's best fleet link."""
    return (len(probe_offsets_m()) + 1) * n_ues


def field_columns(truth: Any, cfg: Any) -> np.ndarray:
    """(N D, field_width) float32 of every agent row (row i is UAV i % D of env i // D)."""
    d, offsets = cfg.n_uavs, probe_offsets_m()
    uav = truth.uav_xy_m.reshape(-1, d, 2)
    n, p = len(uav), len(offsets)
    points = (uav[:, :, None, :] + offsets).reshape(n, d * p, 2)
    shadow = truth.shadow_field.shadow_db(points, truth.ue_xy_m) / cfg.radio.shadowing_std_db
    shadow = shadow.reshape(n, -1, d, p)  # (N, U, D, P)
    own = shadow.transpose(0, 2, 3, 1).reshape(n * d, -1)  # each row's probes, UEs innermost
    best = np.repeat(shadow[..., 0].max(axis=2), d, axis=0)  # (N D, U)
    return np.concatenate([own, best], axis=1).astype(np.float32)


def field_critic_env_class() -> type:
    """``PrivilegedVecEnv`` with the field's columns after its own."""
    from uavlink.learn.privileged import PrivilegedVecEnv

    class FieldCriticVecEnv(PrivilegedVecEnv):
        def bounds(self) -> tuple[np.ndarray, np.ndarray]:
            low, high = super().bounds()
            width = field_width(self.cfg.n_ues)
            return (
                np.concatenate([low, np.full(width, -5.0, np.float32)]),
                np.concatenate([high, np.full(width, 5.0, np.float32)]),
            )

        def columns(self, truth: Any) -> np.ndarray:
            return np.concatenate([super().columns(truth), field_columns(truth, self.cfg)], axis=1)

    return FieldCriticVecEnv


def main(argv: list[str] | None = None) -> int:
    from frozen_std_train import curve_sixths, sweep_job

    episodes = ("--episodes", {"type": int, "help": "PPO episodes (default: the job's)"})
    args, job = sweep_job(__doc__.split("\n\n")[0], argv, episodes)

    from uavlink.config.train import CRITIC_PRIVILEGED
    from uavlink.learn.training import train

    tc = job.train if args.episodes is None else job.train.replace(episodes=args.episodes)
    if tc.critic != CRITIC_PRIVILEGED or job.env.radio.shadowing_model != "spatial":
        print(f"{job.name}: needs a privileged critic on the spatial channel", file=sys.stderr)
        return 2
    # privileged_env builds its wrapper by this module-level name when train() makes the model
    with mock.patch("uavlink.learn.privileged.PrivilegedVecEnv", field_critic_env_class()):
        training = train(job.env, tc, args.out, progress=False)
    sixths = curve_sixths(training)
    print(f"{job.name} with the field critic -> {args.out}; learning curve in sixths {sixths}")
    return 0


if __name__ == "__main__":
    run_script(main)
