"""How far a fleet policy's episode moves when what MAVLink carries is rounded to float32.

A lockstep flight feeds the policy the vehicles' positions (LOCAL_POSITION_NED) and the radio
payload's SINRs and AoAs (DEBUG_FLOAT_ARRAY), and sends the vehicles setpoints
(SET_POSITION_TARGET_LOCAL_NED), all float32. With PX4's motion the env rounds where the flight does
(``BatchedUavEnv._as_carried``), so that a lockstep flight equals its evaluation to the bit. This
evaluates the policy on the same seeded episodes that way and with every value kept in float64:
how much the last bits alone move a policy's episodes.

    python research/fleet_input_sensitivity.py --policy policies/fleet/hotspot.zip --seed 1 [--json]
"""

from __future__ import annotations

import argparse
import json
from unittest import mock

import numpy as np
from entry import run_script


def run(policy_path: str, scenario: str | None, episodes: int, seed: int) -> dict:
    from uavlink.env.core import BatchedUavEnv
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env

    overrides = EnvOverrides(scenario=scenario, settings={"uav_motion": "px4"})
    [(policy, cfg)] = load_with_env([policy_path], overrides)
    rounded = evaluate_policy(policy, cfg, episodes, seed)  # the env's own: MAVLink's float32
    with mock.patch.object(BatchedUavEnv, "_as_carried", lambda self, values: values):
        plain = evaluate_policy(policy, cfg, episodes, seed)
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
    run_script(main)
