"""A listening fleet on no_move: one UAV serves, the others listen and feed one model of the field.

With ``fleet_reuse = "listen"`` a fleet has one cell (the UAV strongest for the most UEs serves them
all; the others are barred and send nothing, but hear every UE's uplink), and with ``place_model =
"pooled"`` (layout v9) every UAV's readings go into one model of the field per fleet, from which
each UAV picks where it is. `research/pooled_field.py` measured what listeners add to one serving
UAV outside the fleet env (+4-9 %); here the same inside it, on the same episodes:

* the shipped fleet policy (layout v8, full reuse) and its teacher, the lead teacher with no_move's
  map policy leading (the others keep their cells empty in the far corners);
* the lead teacher in the listening fleet, the others holding where they start (``hold``);
* the same with the others flying to the spot their fleet's model picks from where they are
  (``sense``: the ``kriging`` rule, GPS-free; a research rule);
* ``kmeans`` (GPS) in both worlds.

    python research/fleet_listeners.py --sizes 2 3 4 --episodes 100 --seed 1
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from entry import run_script
from fleet_bars import episode_args, paired_ratio, ratio_text

SCENARIO = "no_move"


def sensing_teacher(cfg: Any, leader: str) -> Any:
    """The lead teacher whose other UAVs fly to their fleet model's pick (``sense``)."""
    from uavlink.learn.lead_teacher import make_lead_teacher

    teacher = make_lead_teacher(cfg, leader)

    def away(obs: np.ndarray, leader_xy_m: np.ndarray) -> np.ndarray:
        pick = teacher.layout.newest_frame(obs)["place_pick_offset_m"]
        return teacher.mapping.towards(pick, 1.0).astype(np.float32)

    teacher.away = away  # a research rule: the product's teacher holds them
    return teacher


def run(sizes: list[int], episodes: int, seed: int) -> dict[str, Any]:
    from uavlink.evaluation import evaluate_policy
    from uavlink.learn.lead_teacher import make_lead_teacher
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.registry import make_baseline

    leader = f"policies/map/{SCENARIO}.zip"
    rows = []
    for d in sizes:
        [(fleet, own)] = load_with_env(
            [f"policies/fleet/{SCENARIO}.zip"], EnvOverrides(settings={"n_uavs": d})
        )
        listening = own.replace(fleet_reuse="listen", place_model="pooled").validate()
        runs = {
            "ppo_v8": evaluate_policy(fleet, own, episodes, seed),
            "lead_v8": evaluate_policy(make_lead_teacher(own, leader), own, episodes, seed),
            "hold": evaluate_policy(
                make_lead_teacher(listening, leader), listening, episodes, seed
            ),
            "sense": evaluate_policy(sensing_teacher(listening, leader), listening, episodes, seed),
            "kmeans_full": evaluate_policy(make_baseline("kmeans", own), own, episodes, seed),
            "kmeans_listen": evaluate_policy(
                make_baseline("kmeans", listening), listening, episodes, seed
            ),
        }
        row: dict[str, Any] = {"n_uavs": d}
        row |= {f"{k}_mbps": round(v.mean_rate_mbps, 4) for k, v in runs.items()}
        row |= {
            "hold_vs_lead_v8": paired_ratio(runs["hold"], runs["lead_v8"]),
            "sense_vs_hold": paired_ratio(runs["sense"], runs["hold"]),
            "sense_vs_ppo_v8": paired_ratio(runs["sense"], runs["ppo_v8"]),
        }
        rows.append(row)
    return {"scenario": SCENARIO, "episodes": episodes, "seed": seed, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=[2, 3, 4], choices=[2, 3, 4])
    args = episode_args(parser, argv, episodes=100, seed=1)
    out = run(args.sizes, args.episodes, args.seed)
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{out['scenario']}, {out['episodes']} episodes of seed {out['seed']} (Mbps)")
    print(
        "| D | PPO (v8) | lead (v8) | hold | sense | kmeans full / listen "
        "| hold / lead v8 | sense / hold | sense / PPO v8 |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in out["rows"]:
        print(
            f"| {r['n_uavs']} | {r['ppo_v8_mbps']:.2f} | {r['lead_v8_mbps']:.2f} "
            f"| {r['hold_mbps']:.2f} | {r['sense_mbps']:.2f} "
            f"| {r['kmeans_full_mbps']:.2f} / {r['kmeans_listen_mbps']:.2f} "
            f"| {ratio_text(r['hold_vs_lead_v8'])} | {ratio_text(r['sense_vs_hold'])} "
            f"| {ratio_text(r['sense_vs_ppo_v8'])} |"
        )
    return 0


if __name__ == "__main__":
    run_script(main)
