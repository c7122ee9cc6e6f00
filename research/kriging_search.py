"""The `kriging` rule against `explore` and today's spatial policy on no_move (spatial channel), with
the model's optimism and the rule's approach varied: the choice behind ``uavlink.env.field_model``'s
constants (made on the validation episodes, seed 1).

The rule flies to the spot its model of the sensed field picks (``uavlink.policies.kriging``):
GPS-free, it searches while a look still pays. Each row is the rule on the same episodes as the
references, as a ratio over today's spatial no_move policy with a paired 95 % bootstrap interval.
The target is 1.2x on no_move; ``--set uav_motion=px4`` flies every UAV as PX4's position loop
does, which says whether a gain is one a multicopter can fly.

    python research/kriging_search.py [--beta 1 1.5 2] [--approach-gain 0.5 1] [--episodes 100] [--seed 1]
        [--set KEY=VALUE] [--json]
"""

from __future__ import annotations

import argparse
import itertools

from entry import run_script
from explore_search import no_move_references, print_summary, versus

from uavlink.env import field_model
from uavlink.evaluation.core import evaluate_policy
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.kriging import KrigingPolicy


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--beta",
        type=float,
        nargs="+",
        default=[field_model.BETA],
        help="the model's optimism, posterior std's weight in a spot's score",
    )
    parser.add_argument(
        "--approach-gain",
        type=float,
        nargs="+",
        default=[0.4],
        help="share of the distance to the pick the rule closes a frame",
    )
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--seed", type=int, default=1, help="evaluation seed (1: validation episodes)"
    )
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="env overrides for every run, e.g. uav_motion=px4",
    )
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    settings = ["radio.shadowing_model=spatial", *args.overrides]
    references = no_move_references(settings, args.episodes, args.seed)
    [(_, cfg)] = load_with_env(
        ["kriging"], EnvOverrides.from_command_line("no_move", None, settings)
    )
    chosen, rows = field_model.BETA, []
    try:
        for beta, gain in itertools.product(args.beta, args.approach_gain):
            field_model.BETA = beta  # read by the model at each pick
            result = evaluate_policy(
                KrigingPolicy(cfg, approach_gain=gain), cfg, args.episodes, args.seed
            )
            rows.append(
                {
                    "beta": beta,
                    "approach_gain": gain,
                    "mean_rate_mbps": round(result.mean_rate_mbps, 4),
                    **versus(result, references),
                }
            )
    finally:
        field_model.BETA = chosen
    if print_summary(args.episodes, args.seed, settings, references, rows, args.json):
        return 0
    print(
        "| beta | approach gain | Mbps | vs explore | vs spatial policy |\n|---:|---:|---:|---|---|"
    )
    for r in rows:
        cells = [
            f"{x[0]:.3f}x [{x[1]:.3f}, {x[2]:.3f}]" for x in (r["vs_explore"], r["vs_spatial"])
        ]
        print(
            f"| {r['beta']:g} | {r['approach_gain']:g} | {r['mean_rate_mbps']:.3f} | {cells[0]} | {cells[1]} |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
