"""A candidate fleet teacher: every UAV flies a single-UAV spatial policy on its own cell's UEs.

Where the UEs split (straight_90, straight_180, hotspot) ``kmeans`` puts one UAV at each group's
centroid by GPS, and the fleet policies copy it. On one UAV the spatial policies beat the centroid
(``policies/spatial/straight_180.zip`` +4.9 % over ``kmeans`` at D = 1, 100 episodes of seed 1), so a
teacher that flew such a policy per cell might be a better start than kmeans. This rule is
GPS-free: each UAV sees, in its v6 observation, which UEs it serves (``served_here``), their SINRs
and its cell's AoA spread (``cell_aoa_*``); it hands the single-UAV policy a v1 view of every frame
in memory in which its own cell's SINRs fill all U UE columns (cycled) and the cell's AoA stands for
every UE's. A UAV with an empty cell sees every UE, as a lone UAV would; a UAV whose cell looks far
(its AoAs spread less than 20 deg, its SINRs low) dashes towards it, as ``LeadTeacher`` does.

Each row: the rule, kmeans and the shipped any-size policy at D, paired on the same episodes.

    python research/cell_teacher.py --scenario straight_180 --episodes 100 --seed 1
    python research/cell_teacher.py --scenario straight_180 --leader straight --sizes 2 3 --json
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from entry import run_script
from fleet_bars import episode_args, paired_ratio, ratio_text

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationLayout
from uavlink.learn.lead_teacher import LeadTeacher, single_layout
from uavlink.policies.baselines import hover_sinr_db
from uavlink.rollout import Actor


class CellTeacher:
    """Each UAV flies ``leader`` (a single-UAV policy, layout v1) on its own cell's UEs."""

    name = "cell"
    needs_truth = False

    def __init__(self, cfg: EnvConfig, leader: Actor) -> None:
        self.layout = ObservationLayout.for_config(cfg)
        if self.layout.uav_slots < 1:
            raise ValueError("the cell teacher reads layout v6's served_here: set fleet_slots")
        self.single = single_layout(self.layout)
        self.leader = leader
        self.mapping = ActionMapping.for_config(cfg)
        self.hover_sinr_db = hover_sinr_db(cfg)

    def view(self, obs: np.ndarray) -> np.ndarray:
        """The v1 observation (rows, v1 size) of each UAV's own cell, frame by frame."""
        layout, n_ues = self.layout, self.layout.n_ues
        here = layout.history(obs, "served_here")  # (rows, M, U)
        empty = ~here.any(axis=2)
        cell = np.where(empty[..., None], True, here)
        first = np.argsort(~cell, axis=2, kind="stable")  # the cell's UEs first
        cycled = np.arange(n_ues)[None, None] % cell.sum(axis=2, keepdims=True)
        sinr = np.take_along_axis(
            layout.encoded_history(obs, "sinr_db"),
            np.take_along_axis(first, cycled, axis=2),
            axis=2,
        )
        aoa = np.where(
            empty[..., None],
            layout.encoded_history(obs, "aoa_mean_deg", "aoa_std_deg"),
            layout.encoded_history(obs, "cell_aoa_mean_deg", "cell_aoa_std_deg"),
        )
        frames = np.concatenate([layout.encoded_history(obs, "uav_xy_m"), sinr, aoa], axis=2)
        return frames.reshape(len(obs), -1).astype(np.float32)

    def act(self, obs: np.ndarray, truth: Any = None) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        frame = self.layout.newest_frame(obs)
        here = frame["served_here"]
        empty = ~here.any(axis=1)
        mean_deg = np.where(empty, frame["aoa_mean_deg"], frame["cell_aoa_mean_deg"])
        spread_deg = np.where(empty, frame["aoa_std_deg"], frame["cell_aoa_std_deg"])
        sinr_db = np.where(
            empty,
            frame["sinr_db"].mean(axis=1),
            (frame["sinr_db"] * here).sum(axis=1) / np.maximum(here.sum(axis=1), 1),
        )
        far = (spread_deg < LeadTeacher.close_spread_deg) & (
            sinr_db < self.hover_sinr_db + LeadTeacher.far_sinr_margin_db
        )
        dash = self.mapping.from_polar(mean_deg, np.full(len(obs), self.mapping.r_max_m))
        return np.where(far[:, None], dash, self.leader.act(self.view(obs))).astype(np.float32)


def run(
    scenarios: list[str], leader: str | None, sizes: list[int], episodes: int, seed: int
) -> dict[str, Any]:
    from uavlink.evaluation import evaluate_policy
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.loader import load_policy
    from uavlink.policies.registry import make_baseline

    rows = []
    for scenario in scenarios:
        for d in sizes:
            [(fleet, cfg)] = load_with_env(
                [f"policies/fleet/{scenario}.zip"], EnvOverrides(settings={"n_uavs": d})
            )
            single = cfg.replace(n_uavs=1, fleet_slots=0).validate()
            source = leader or scenario
            rule = CellTeacher(cfg, load_policy(f"policies/spatial/{source}.zip", single))
            cell = evaluate_policy(rule, cfg, episodes, seed)
            kmeans = evaluate_policy(make_baseline("kmeans", cfg), cfg, episodes, seed)
            ppo = evaluate_policy(fleet, cfg, episodes, seed)
            rows.append(
                {
                    "scenario": scenario,
                    "n_uavs": d,
                    "leader": f"policies/spatial/{source}.zip",
                    "cell_mbps": round(cell.mean_rate_mbps, 4),
                    "kmeans_mbps": round(kmeans.mean_rate_mbps, 4),
                    "ppo_mbps": round(ppo.mean_rate_mbps, 4),
                    "cell_vs_kmeans": paired_ratio(cell, kmeans),
                    "ppo_vs_kmeans": paired_ratio(ppo, kmeans),
                    "cell_ues_per_uav": [round(float(x), 3) for x in cell.ues_per_uav],
                    "kmeans_ues_per_uav": [round(float(x), 3) for x in kmeans.ues_per_uav],
                }
            )
    return {"episodes": episodes, "seed": seed, "rows": rows}


def markdown(report: dict[str, Any]) -> str:
    lines = [
        "| scenario | D | leader | cell rule Mbps | kmeans Mbps | PPO Mbps | rule / kmeans | PPO / kmeans |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in report["rows"]:
        lines.append(
            f"| {row['scenario']} | {row['n_uavs']} | {row['leader']} | {row['cell_mbps']:.2f} | "
            f"{row['kmeans_mbps']:.2f} | {row['ppo_mbps']:.2f} | "
            f"{ratio_text(row['cell_vs_kmeans'])} | {ratio_text(row['ppo_vs_kmeans'])} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from uavlink.config import SCENARIOS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--scenario",
        action="append",
        dest="scenarios",
        choices=SCENARIOS,
        help="a scenario whose fleet policy and world are used (repeatable; default straight_180)",
    )
    parser.add_argument(
        "--leader",
        choices=SCENARIOS,
        help="fly policies/spatial/<LEADER>.zip in every cell (default: the scenario's own)",
    )
    parser.add_argument("--sizes", type=int, nargs="+", default=[2], choices=(2, 3, 4))
    args = episode_args(parser, argv, episodes=100, seed=1)
    report = run(
        args.scenarios or ["straight_180"], args.leader, args.sizes, args.episodes, args.seed
    )
    print(json.dumps(report, indent=2) if args.json else markdown(report))
    return 0


if __name__ == "__main__":
    run_script(main)
