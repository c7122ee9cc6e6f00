"""How far from the team the limit lies: the genie kept within a radius of the team.

For each seeded episode of a scenario on the spatial channel, the genie's dynamic programme
(``uavlink.policies.genie``, one UAV, the 4 m grid) is solved again with every grid spot farther
than R metres from the team's centroid forbidden at each frame, for several R (from the first frame
a path can keep to it: circular's team starts out of reach). A GPS-free policy
that stays within R of the team can do no better than that plan, whatever it remembers. Beside
them, the paths ``explore``, the scenario's map policy and its spatial policy fly in the same
episodes, scored the same way. Every figure is the planner's own: the mean UE throughput of a path
on the mean channel (path loss and the episode's shadowing field, no fast fading), so all columns
are comparable with each other; ``uavlink evaluate`` scores flown episodes with fast fading and
gives the genie a few per cent less (research/log/genie.md).

    python research/genie_reach.py                           # no_move, 20 episodes, a table
    python research/genie_reach.py --scenarios no_move circular --episodes 50 --json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from entry import run_script

ROOT = Path(__file__).resolve().parents[1]
RADII_M = (25.0, 50.0, 100.0, 150.0)
POLICIES = ("explore", "map", "spatial")


def flown_paths(policy, cfg, episodes: int, seed: int) -> np.ndarray:
    """The UAV's path (E, T + 1, 2) in each of ``episodes`` seeded evaluation episodes."""
    from uavlink.rollout import chunks
    from uavlink.seeding import EVAL

    paths = []
    for chunk in chunks(cfg, EVAL, episodes, seed):
        env = chunk.env
        steps = [env.uav_xy_m.copy()]
        for _ in chunk.frames(policy):
            steps.append(env.uav_xy_m.copy())
        paths.append(np.stack(steps, axis=1))
    return np.concatenate(paths)


def within_radius_path(reward: np.ndarray, near: np.ndarray, grid, first: np.ndarray) -> np.ndarray:
    """The best grid path that keeps to the ``near`` (T, n, n) cells from the earliest frame it can
    (the team may start out of reach: circular's is 150 m from the UAV), free before that."""
    from uavlink.policies.genie.grid import best_grid_path

    for k in range(len(reward)):
        cells, _ = best_grid_path(
            np.where(near | (np.arange(len(reward)) < k)[:, None, None], reward, -np.inf),
            grid,
            first,
        )
        if cells is not None:
            return cells
    raise AssertionError("unreachable: with no frame constrained the genie's own path is allowed")


def episode_values(
    planner, grid, ue_m: np.ndarray, flown: dict[str, np.ndarray]
) -> dict[str, float]:
    """One episode's figures: the genie's plan, its mean distance from the team's centroid, the plan
    within each radius of it, and each flown path (T + 1, 2), all scored by the planner (float64)."""
    from uavlink.policies.genie.grid import best_grid_path, one_uav_rate_mbps

    start = planner.start_m  # (1, 2)

    def score(cells: np.ndarray | None) -> float:
        if cells is None:  # no path keeps within the radius (the start outside it)
            return float("nan")
        return planner.rate_mbps(np.concatenate([start, grid.points_m(cells)])[:, None])

    reward = one_uav_rate_mbps(
        planner.rx_grid, planner.cfg.radio
    )  # (T, n, n) Mbps (entry t: frame t + 1)
    first = grid.cells_within(start[0], grid.r_max_m)
    centroid = ue_m.mean(axis=1)  # (T, 2), frame t + 1
    gap_m = np.hypot(
        grid.x_m[None, :, None] - centroid[:, 0, None, None],
        grid.x_m[None, None, :] - centroid[:, 1, None, None],
    )
    cells, _ = best_grid_path(reward, grid, first)
    values = {
        "genie": score(cells),
        "distance_m": float(np.hypot(*(grid.points_m(cells) - centroid).T).mean()),
    }
    for r in RADII_M:
        values[f"within {r:g} m"] = score(within_radius_path(reward, gap_m <= r, grid, first))
    for name, path in flown.items():
        values[name] = planner.rate_mbps(path[:, None])
    return values


def episode_planners(cfg, grid, episodes: int, seed: int, progress: bool):
    """(episode index, the genie's planner of that episode) for ``episodes`` seeded evaluation
    episodes, in order: the UEs' whole paths and the episode's field, as the genie sees them."""
    from uavlink.policies.genie.policy import EpisodePlanner, env_field, future_ues
    from uavlink.rollout import chunks
    from uavlink.seeding import EVAL

    episode = 0
    for chunk in chunks(cfg, EVAL, episodes, seed):
        truth = chunk.env.ground_truth()
        ue, _ = future_ues(truth.mobility, cfg.episode_frames, cfg.frame_s, cfg.area.half_width_m)
        for env in range(chunk.env.n_envs):
            if progress:
                print(
                    f"{cfg.scenario}: episode {episode + 1}/{episodes}", file=sys.stderr, flush=True
                )
            yield (
                episode,
                EpisodePlanner(
                    cfg,
                    grid,
                    ue[:, env],
                    env_field(truth.shadow_field, env, 1),
                    truth.uav_xy_m[env : env + 1],
                ),
            )
            episode += 1


def run(scenarios: list[str], episodes: int, seed: int, progress: bool) -> dict:
    from uavlink.evaluation import paired_ratio_ci
    from uavlink.evaluation.tables import spatial_overrides
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.genie.grid import Grid
    from uavlink.policies.loader import policy_for_scenario

    rows = []
    for scenario in scenarios:
        specs = {
            "explore": "explore",
            "map": policy_for_scenario(ROOT / "policies" / "map", scenario),
            "spatial": policy_for_scenario(ROOT / "policies" / "spatial", scenario),
        }
        loaded = dict(
            zip(
                specs,
                load_with_env(list(specs.values()), spatial_overrides(EnvOverrides(scenario))),
                strict=True,
            )
        )
        cfg = loaded["explore"][1]
        paths = {
            name: flown_paths(policy, c, episodes, seed) for name, (policy, c) in loaded.items()
        }
        grid = Grid.over_area(cfg.area.half_width_m, 4.0, cfg.r_max_m)
        values = {
            name: []
            for name in ("genie", "distance_m", *(f"within {r:g} m" for r in RADII_M), *POLICIES)
        }
        for episode, planner in episode_planners(cfg, grid, episodes, seed, progress):
            flown = {name: path[episode] for name, path in paths.items()}
            for name, value in episode_values(planner, grid, planner.ue_xy_m[1:], flown).items():
                values[name].append(value)
        genie = np.array(values["genie"])
        row = {
            "scenario": scenario,
            "genie_mbps": round(float(genie.mean()), 4),
            "genie_mean_distance_from_team_m": round(float(np.mean(values["distance_m"])), 1),
            "shares": {},
        }
        for name, v in values.items():
            if name in ("genie", "distance_m"):
                continue
            v = np.array(v)
            ok = np.isfinite(
                v
            )  # a radius no reachable path keeps to (the start outside it) is left out
            share, lo, hi = (
                paired_ratio_ci(v[ok], genie[ok]) if ok.sum() > 1 else (float("nan"),) * 3
            )
            row["shares"][name] = {
                "mbps": round(float(v[ok].mean()), 4) if ok.any() else None,
                "of_genie": round(share, 4),
                "ci95": [round(lo, 4), round(hi, 4)],
                "episodes": int(ok.sum()),
            }
        rows.append(row)
    return {
        "benchmark": "genie_reach",
        "episodes": episodes,
        "seed": seed,
        "radii_m": list(RADII_M),
        "statistic": "planned mean UE throughput on the mean channel; share of the genie's with a 95 % "
        "paired bootstrap interval",
        "rows": rows,
    }


def markdown(result: dict) -> str:
    names = list(result["rows"][0]["shares"])
    lines = [
        "| scenario | genie (Mbps) | genie's distance from the team (m) | "
        + " | ".join(f"{n} / genie" for n in names)
        + " |",
        "|---|---:|---:|" + "---:|" * len(names),
    ]
    for row in result["rows"]:
        cells = []
        for n in names:
            s = row["shares"][n]
            cells.append(
                f"{100 * s['of_genie']:.1f} % [{100 * s['ci95'][0]:.1f}, {100 * s['ci95'][1]:.1f}]"
                + ("" if s["episodes"] == result["episodes"] else f" ({s['episodes']} eps)")
            )
        lines.append(
            f"| {row['scenario']} | {row['genie_mbps']:.2f} | {row['genie_mean_distance_from_team_m']:.0f} | "
            + " | ".join(cells)
            + " |"
        )
    return "\n".join(lines)


def scenario_args(
    doc: str,
    argv: list[str] | None,
    scenarios: list[str],
    episodes: int,
    plot_help: str | None = None,
) -> argparse.Namespace:
    """The options of a benchmark over seeded episodes of some scenarios (this one's and
    memory_worth's), checked: --scenarios, --episodes, --seed, --json, and --plot PNG with a
    ``plot_help``."""
    from uavlink.mobility import SCENARIOS

    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0].replace("\n", " "))
    parser.add_argument(
        "--scenarios", nargs="+", default=scenarios, help=f"(default: {' '.join(scenarios)})"
    )
    parser.add_argument(
        "--episodes",
        type=int,
        default=episodes,
        help=f"seeded episodes per scenario (default {episodes})",
    )
    parser.add_argument("--seed", type=int, default=0, help="evaluation seed (default 0)")
    parser.add_argument(
        "--json", action="store_true", help="print one JSON object instead of a table"
    )
    if plot_help:
        parser.add_argument("--plot", type=Path, default=None, metavar="PNG", help=plot_help)
    args = parser.parse_args(argv)
    unknown = [s for s in args.scenarios if s not in SCENARIOS]
    if unknown or args.episodes < 1:
        parser.error(f"unknown scenario {unknown[0]!r}" if unknown else "--episodes must be >= 1")
    return args


def main(argv: list[str] | None = None) -> int:
    args = scenario_args(__doc__, argv, ["no_move"], 20)
    result = run(args.scenarios, args.episodes, args.seed, progress=sys.stderr.isatty())
    print(json.dumps(result, indent=1) if args.json else markdown(result))
    return 0


if __name__ == "__main__":
    run_script(main)
