"""How far a fleet policy's episode moves when its inputs are rounded to float32, as MAVLink carries them.

A lockstep flight feeds the policy the vehicles' positions (LOCAL_POSITION_NED) and the radio
payload's SINRs and AoAs (DEBUG_FLOAT_ARRAY), all float32; the env builds the same observation from
float64. This evaluates the policy both ways on the same seeded episodes (PX4's motion, as a
lockstep flight's replay), so a flight's departure from its evaluation can be read against what the
rounding alone does.

    python research/fleet_input_sensitivity.py --policy policies/fleet/hotspot.zip --seed 1 [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from unittest import mock

import numpy as np


def run(policy_path: str, scenario: str | None, episodes: int, seed: int) -> dict:
    from uavlink.env.core import BatchedUavEnv
    from uavlink.env.observation import fleet_view_quantities
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    overrides = EnvOverrides(scenario=scenario, settings={"uav_motion": "px4"})
    [(policy, cfg)] = load_with_env([policy_path], overrides)
    plain = evaluate_policy(policy, cfg, episodes, seed)

    def as_mavlink(env: BatchedUavEnv) -> dict[str, np.ndarray]:
        r = env.readings
        assert r is not None
        xy = env.uav_xy_m.astype(np.float32).astype(float)
        aoa = r.heard_aoa_deg.astype(np.float32).astype(float)
        fleet = fleet_view_quantities(
            env.layout, xy.reshape(env.n_envs, env.n_uavs, 2), r.serving, aoa
        )
        sinr = r.heard_sinr_db.astype(np.float32).astype(float)
        return {
            "uav_xy_m": xy,
            "sinr_db": sinr.reshape(env.n_rows, -1),
            "aoa_deg": aoa.reshape(env.n_rows, -1),
            **fleet,
        }

    with mock.patch.object(BatchedUavEnv, "_sensed", as_mavlink):
        rounded = evaluate_policy(policy, cfg, episodes, seed)
    return {
        "policy": policy_path,
        "scenario": cfg.scenario,
        "n_uavs": cfg.n_uavs,
        "episodes": episodes,
        "seed": seed,
        "float64_mbps": round(plain.mean_rate_mbps, 6),
        "float32_inputs_mbps": round(rounded.mean_rate_mbps, 6),
        "per_episode_abs_change_pct": round(
            float(np.mean(np.abs(rounded.episode_rate_mbps / plain.episode_rate_mbps - 1))) * 100,
            3,
        ),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", default="policies/fleet/hotspot.zip")
    parser.add_argument("--scenario", default=None, help="default: the policy's own")
    parser.add_argument("--episodes", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)
    report = run(args.policy, args.scenario, args.episodes, args.seed)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(
            f"{report['policy']} on {report['scenario']} (D = {report['n_uavs']}, px4 motion), "
            f"{report['episodes']} episodes of seed {report['seed']}: {report['float64_mbps']:.3f} "
            f"Mbps from float64 inputs, {report['float32_inputs_mbps']:.3f} from float32 ones "
            f"(mean |change| per episode {report['per_episode_abs_change_pct']:.2f} %)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
