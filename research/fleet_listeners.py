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
* ``kmeans`` (GPS) in both worlds;
* with ``--policy``, a policy file of the listening fleet (layout v9), paired with the holding
  teacher and with ``sense``.

For the listening fleets, how they fly: the mean distance of the listeners from the serving UAV
(m) and how often a frame's serving UAV differs from the last frame's (switches an episode).

    python research/fleet_listeners.py --sizes 2 3 4 --episodes 100 --seed 1
    python research/fleet_listeners.py --policy runs/fleet_listen/JOB/no_move.zip --sizes 2 3
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


def listening_stats(actor: Any, cfg: Any, episodes: int, seed: int) -> dict[str, float]:
    """How a listening fleet flies on evaluation's episodes: the listeners' mean distance from the
    serving UAV (m) and the serving UAV's switches an episode."""
    from uavlink.rollout import rollout
    from uavlink.seeding import EVAL

    d, gaps, switches, last = cfg.n_uavs, [], 0, None
    for frame in rollout(actor, cfg, EVAL, episodes, seed):
        xy = frame.env.uav_xy_m.reshape(-1, d, 2)
        server = frame.env.readings.serving[:, 0]  # every UE's, in a listening fleet
        if frame.index > 0 and last is not None:
            switches += int((server != last).sum())
        last = server
        listeners = np.arange(d)[None] != server[:, None]  # (N, D)
        gap = np.linalg.norm(xy - xy[np.arange(len(xy)), server][:, None], axis=2)
        gaps.append(gap[listeners].mean())
    return {
        "listener_gap_m": round(float(np.mean(gaps)), 1),
        "switches_per_episode": round(switches / episodes, 2),
    }


def run(sizes: list[int], episodes: int, seed: int, policy: str | None = None) -> dict[str, Any]:
    from uavlink.errors import UserError
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
        actors = {
            "hold": make_lead_teacher(listening, leader),
            "sense": sensing_teacher(listening, leader),
        }
        if policy is not None:
            [(listens, world)] = load_with_env([policy], EnvOverrides(settings={"n_uavs": d}))
            if world.fleet_reuse != "listen":
                raise UserError(f"{policy} does not fly a listening fleet (fleet_reuse=listen)")
            flown = evaluate_policy(listens, world, episodes, seed)
            actors["policy"] = listens
            row |= {
                "policy_mbps": round(flown.mean_rate_mbps, 4),
                "policy_vs_hold": paired_ratio(flown, runs["hold"]),
                "policy_vs_sense": paired_ratio(flown, runs["sense"]),
                "policy_vs_ppo_v8": paired_ratio(flown, runs["ppo_v8"]),
            }
        for name, actor in actors.items():
            row[f"{name}_flies"] = listening_stats(actor, listening, episodes, seed)
        rows.append(row)
    return {"scenario": SCENARIO, "episodes": episodes, "seed": seed, "rows": rows}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=[2, 3, 4], choices=[2, 3, 4])
    parser.add_argument("--policy", help="a listening fleet's policy file (layout v9) to pair")
    args = episode_args(parser, argv, episodes=100, seed=1)
    out = run(args.sizes, args.episodes, args.seed, args.policy)
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
    print(
        "\n| D | flown by | Mbps | vs hold | vs sense | listeners from the server (m) | switches |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in out["rows"]:
        for name in ("hold", "sense", "policy"):
            if f"{name}_flies" not in r:
                continue
            flies = r[f"{name}_flies"]
            versus = (
                f"{ratio_text(r['policy_vs_hold'])} | {ratio_text(r['policy_vs_sense'])}"
                if name == "policy"
                else "- | -"
            )
            print(
                f"| {r['n_uavs']} | {name} | {r[f'{name}_mbps']:.2f} | {versus} "
                f"| {flies['listener_gap_m']:.0f} | {flies['switches_per_episode']:.2f} |"
            )
    return 0


if __name__ == "__main__":
    run_script(main)
