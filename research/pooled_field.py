"""What is a listening UAV worth to the one that serves? A model of the field fed from two places.

Where the team stays together the best fleet is one UAV serving and the others out of its way, and
what the serving UAV lacks is the field where it has not flown (research/log/fleet.md, "A silent UAV
as the team's field sensor?"). A second UAV that takes no UE and sends no data (a barred cell, TS
38.304 ``cellBarred``) still hears every UE's uplink reference signal where it flies (TS 38.305
UL-AoA measures the same signal), so it could sense the field for the first. Since it is silent, the
serving UAV's world is a single UAV's; this script flies the single-UAV policy that reads a model
of the field (``policies/map/<scenario>.zip``, layout v5) or the ``kriging`` rule in that world and
adds, each frame before its decision, the value the listener senses where it is (mean over UEs of
log2(1 + SNR), with the fast fading over the UE's RBs drawn from a stream of its own) to the
serving UAV's model (``FieldModel.observe``); a fleet of D has D - 1 listeners. They start where
the serving UAV does and fly at r_max:

* ``spiral``: Archimedean spirals out from the start, rings one decorrelation distance apart, the
  listeners' turned evenly;
* ``ucb``: each to the spot whose optimistic value, less what the flight there costs, is highest
  among those more than a decorrelation distance from the serving UAV (where it senses itself)
  and from the other listeners' targets.

A yardstick for a listen-only role, not a fleet policy: the listener's rules read the model, GPS-free,
but the pooling is the script's. Paired against the same policy without a listener on the same
episodes.

    python research/pooled_field.py --scenario no_move --sizes 2 3 --episodes 100 --seed 1
"""

from __future__ import annotations

import argparse
import itertools
import json
from typing import Any

import numpy as np
from entry import run_script
from fleet_bars import episode_args, ratio_text

LISTENERS = ("none", "spiral", "ucb")
TRAVEL_COST_BITS = 0.1  # ucb: what a frame of flight to a spot costs, in optimistic value


def spiral_m(frames: int, r_max_m: float, pitch_m: float, turn_rad: float = 0.0) -> np.ndarray:
    """(frames + 1, 2) an Archimedean spiral r = pitch theta / 2 pi from the origin, turned by
    ``turn_rad``, walked at ``r_max_m`` a frame (the arc length solved step by step), then held at
    its end past the model's disc of candidate spots."""
    from uavlink.env.field_model import RADIUS_M

    b = pitch_m / (2.0 * np.pi)
    theta, out = 0.0, [np.zeros(2)]
    for _ in range(frames):
        if b * theta < RADIUS_M:
            theta += r_max_m / max(np.hypot(b * theta, b), 1e-9)
        angle = theta + turn_rad
        out.append(b * theta * np.array([np.cos(angle), np.sin(angle)]))
    return np.array(out)


def heard_value_bits(env: Any, xy_m: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(N,) what a silent UAV at ``xy_m`` (N, 2) senses of the UEs' uplink: mean log2(1 + SNR)."""
    from uavlink.env.place_memory import sensed_value_bits
    from uavlink.radio.fading import mean_rician_power_gain
    from uavlink.radio.pathloss import distance_3d_m, mean_rx_power_dbm

    channel, ue = env.channel, env.mobility.position_m
    at = xy_m[:, None, :]
    rx_dbm = mean_rx_power_dbm(distance_3d_m(at, ue, channel.altitude_m), channel.radio)
    rx_dbm = rx_dbm[..., 0] + channel.field.shadow_db(at, ue)[..., 0]  # (N, U)
    snr = 10.0 ** ((rx_dbm - channel.noise_dbm) / 10.0)
    radio = channel.radio
    if radio.fast_fading:
        snr *= mean_rician_power_gain(rng, snr.shape, channel.rbs_per_ue, radio.rician_k_db)
    return sensed_value_bits(10.0 * np.log10(snr))


def ucb_targets_m(model: Any, listeners_m: np.ndarray, server_m: np.ndarray) -> np.ndarray:
    """(N, L, 2) the ``ucb`` listeners' targets (see the module docstring), chosen in turn, each
    away from the serving UAV and from the targets chosen before it."""
    from uavlink.env.field_model import BETA, DECORRELATION_M

    spots = model.spots_m
    optimistic = model.mean + BETA * np.sqrt(np.maximum(model.var, 0.0))
    taken = [server_m]
    for listener in range(listeners_m.shape[1]):
        to_spot = np.linalg.norm(spots[None] - listeners_m[:, listener, None], axis=2)
        score = optimistic - TRAVEL_COST_BITS * to_spot / model.r_max_m
        for xy in taken:
            score[np.linalg.norm(spots[None] - xy[:, None], axis=2) < DECORRELATION_M] = -np.inf
        taken.append(spots[score.argmax(axis=1)])
    return np.stack(taken[1:], axis=1)


class ListenedModel:
    """A serving UAV's model of the field that, before each of its updates, moves the listeners
    one frame (``rule``) and adds what each hears where it then is (the pooling hook)."""

    def __init__(self, env: Any, rule: str, n_listeners: int, rng: np.random.Generator) -> None:
        from uavlink.env.field_model import DECORRELATION_M, FieldModel

        cfg = env.cfg
        self.env, self.rule, self.rng, self.r_max_m = env, rule, rng, cfg.r_max_m
        self.model = FieldModel(
            env.n_envs,
            cfg.episode_frames,
            cfg.r_max_m,
            cfg.area.half_width_m,
            sensors=1 + n_listeners,
        )
        turns = 2.0 * np.pi * np.arange(n_listeners) / max(n_listeners, 1)
        self.paths = np.stack(
            [spiral_m(cfg.episode_frames, cfg.r_max_m, DECORRELATION_M, t) for t in turns], axis=1
        ).reshape(cfg.episode_frames + 1, n_listeners, 2)
        self.xy_m = np.zeros((env.n_envs, n_listeners, 2))
        self.frame = 0

    def reset(self) -> None:
        self.model.reset()
        self.xy_m[:] = 0.0
        self.frame = 0

    def update(self, uav_xy_m: np.ndarray, value_bits: np.ndarray) -> dict[str, np.ndarray]:
        if self.frame > 0:  # the listeners move with the frame, then sense
            if self.rule == "spiral":
                target = np.broadcast_to(self.paths[self.frame], self.xy_m.shape)
            else:
                target = ucb_targets_m(self.model, self.xy_m, np.asarray(uav_xy_m, dtype=float))
            step = target - self.xy_m
            dist = np.linalg.norm(step, axis=2, keepdims=True)
            self.xy_m = self.xy_m + step * np.minimum(1.0, self.r_max_m / np.maximum(dist, 1e-9))
        for xy in self.xy_m.transpose(1, 0, 2):
            self.model.observe(xy, heard_value_bits(self.env, xy, self.rng))
        self.frame += 1
        return self.model.update(uav_xy_m, value_bits)


def fly(policy: Any, cfg: Any, listener: str, n_listeners: int, episodes: int, seed: int) -> Any:
    """``policy``'s per-episode mean rates (E,), Mbps, with ``n_listeners`` UAVs flying the
    ``listener`` rule pooled into its model (none: the policy alone, as evaluation flies it)."""
    from uavlink.env.core import BatchedUavEnv
    from uavlink.rollout import Chunk
    from uavlink.seeding import EVAL

    rates = []
    for index, start in enumerate(range(0, episodes, EVAL.chunk_envs)):
        n = min(EVAL.chunk_envs, episodes - start)
        env = BatchedUavEnv(cfg, n_envs=n, seed=EVAL.seed(seed, index))
        if n_listeners:  # a research hook: the pooling is this script's
            rng = np.random.default_rng([seed, index, 9])
            env._builder.field = ListenedModel(env, listener, n_listeners, rng)  # noqa: SLF001
        chunk = Chunk(index, env)
        per_frame = [f.result.mean_rate_mbps for f in chunk.frames(policy)]
        rates.append(np.mean(per_frame, axis=0))
    return np.concatenate(rates)


def run(
    scenario: str, leaders: list[str], sizes: list[int], episodes: int, seed: int
) -> dict[str, Any]:
    from uavlink.config.env import PLACE_KRIGING
    from uavlink.errors import UserError
    from uavlink.evaluation import paired_ratio_ci
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.kriging import KrigingPolicy

    [(mapped, cfg)] = load_with_env([f"policies/map/{scenario}.zip"], EnvOverrides())
    if cfg.place_model != PLACE_KRIGING:
        raise UserError(f"policies/map/{scenario}.zip reads no model of the field (layout v5)")
    rows = []
    for leader in leaders:
        policy = mapped if leader == "map" else KrigingPolicy(cfg)
        alone = fly(policy, cfg, "none", 0, episodes, seed)
        for listener, d in itertools.product(LISTENERS[1:], sizes):
            pooled = fly(policy, cfg, listener, d - 1, episodes, seed)
            ratio = [round(x, 4) for x in paired_ratio_ci(pooled, alone)]
            rows.append(
                {
                    "leader": leader,
                    "listener": listener,
                    "n_uavs": d,
                    "alone_mbps": round(float(alone.mean()), 4),
                    "pooled_mbps": round(float(pooled.mean()), 4),
                    "pooled_vs_alone": ratio,
                }
            )
    return {"scenario": scenario, "episodes": episodes, "seed": seed, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", default="no_move", choices=SCENARIOS)
    parser.add_argument(
        "--leaders", nargs="+", default=["map", "kriging"], choices=["map", "kriging"]
    )
    parser.add_argument(
        "--sizes", nargs="+", type=int, default=[2, 3], choices=[2, 3, 4], help="fleet sizes D"
    )
    args = episode_args(parser, argv, episodes=100, seed=1)
    out = run(args.scenario, args.leaders, args.sizes, args.episodes, args.seed)
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{out['scenario']}, {out['episodes']} episodes of seed {out['seed']}")
    print("| serving UAV | listeners | D | alone (Mbps) | pooled (Mbps) | pooled / alone |")
    print("|---|---|---|---|---|---|")
    for r in out["rows"]:
        print(
            f"| {r['leader']} | {r['listener']} | {r['n_uavs']} | {r['alone_mbps']:.2f} "
            f"| {r['pooled_mbps']:.2f} "
            f"| {ratio_text(r['pooled_vs_alone'])} |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
