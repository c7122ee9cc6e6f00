"""What a memory of place is worth when the team moves: the best spot remembered, scored now.

A memory of place tells a GPS-free policy where it sensed best. Going back pays only while that
spot is still good. On the spatial channel the shadowing decorrelates over 50 m at the UE end too
(SPEC "A spatially consistent channel"), so a spot's value fades as the team moves: at 8 m/s by
exp(-8 t / 50) after t frames.

For each seeded episode, the path today's spatial policy flies (``policies/spatial/<scenario>.zip``)
is scored frame by frame on the mean channel (path loss and the episode's shadowing field, no fast
fading; the genie's scoring, ``uavlink.policies.genie``). At each frame t the memory's pick is the
spot of the best value sensed over the last A frames. Two numbers follow:
- what the memory claims: the pick's value when it was sensed, against the value here now;
- what the pick is worth now: the value the UAV would have at the pick this frame, with the team
  where it is now.
Travel is free here, which favours the memory: a UAV needs frames to get back. A ratio "now" above
1 is the most a return could gain; at or below 1 no memory of this kind can gain by returning.

    python research/memory_worth.py                              # every scenario, 50 episodes
    python research/memory_worth.py --scenarios no_move straight_180 --episodes 20 --json
    python research/memory_worth.py --plot docs/img/memory_worth.png   # the figure in docs/design/learning.md
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from entry import run_script
from genie_reach import episode_planners, flown_paths, scenario_args

ROOT = Path(__file__).resolve().parents[1]
WINDOWS_FRAMES = (4, 16, 128)  # today's observation (M = 4), a longer memory, the whole episode


def remembered_picks(values: np.ndarray, window: int) -> np.ndarray:
    """Frame index (T,) of the best of ``values`` (T,) over the last ``window`` frames, each frame."""
    picks = np.empty(len(values), dtype=int)
    for t in range(len(values)):
        lo = max(0, t - window + 1)
        picks[t] = lo + int(np.argmax(values[lo : t + 1]))
    return picks


def frame_rates_mbps(planner, path_m: np.ndarray) -> np.ndarray:
    """Mean UE rate (T,) at each frame of ``path_m`` (T + 1, 2), on the mean channel, Mbps."""
    from uavlink.radio.cells import mean_channel_rate_bps

    return (
        mean_channel_rate_bps(planner.rx_dbm(path_m[:, None]), planner.cfg.radio).mean(axis=-1)
        * 1e-6
    )


def episode_sums(planner, path_m: np.ndarray) -> dict[int, tuple[float, float, float, float]]:
    """Per window: (value here, the pick's value when sensed, the pick's value now, the pick's age in
    frames), each summed over the episode's frames."""
    here = frame_rates_mbps(planner, path_m)  # entry t: frame t + 1, the UAV at path_m[t + 1]
    sums = {}
    for window in WINDOWS_FRAMES:
        picks = remembered_picks(here, window)
        at_pick = path_m.copy()
        at_pick[1:] = path_m[1:][picks]  # the UAV put back on its pick, every frame
        now = frame_rates_mbps(planner, at_pick)
        age = np.arange(len(here)) - picks
        sums[window] = (
            float(here.sum()),
            float(here[picks].sum()),
            float(now.sum()),
            float(age.sum()),
        )
    return sums


def run(scenarios: list[str], episodes: int, seed: int, progress: bool) -> dict:
    from uavlink.evaluation import paired_ratio_ci
    from uavlink.evaluation.tables import spatial_overrides
    from uavlink.policies.contract import EnvOverrides, load_with_env
    from uavlink.policies.genie.grid import Grid
    from uavlink.policies.loader import policy_for_scenario

    rows = []
    for scenario in scenarios:
        spec = policy_for_scenario(ROOT / "policies" / "spatial", scenario)
        [(policy, cfg)] = load_with_env([spec], spatial_overrides(EnvOverrides(scenario)))
        paths = flown_paths(policy, cfg, episodes, seed)
        # the planner is used for its scoring only: a coarse grid keeps its set-up cheap
        grid = Grid.over_area(cfg.area.half_width_m, 50.0, cfg.r_max_m)
        sums = {w: [] for w in WINDOWS_FRAMES}
        for episode, planner in episode_planners(cfg, grid, episodes, seed, progress):
            for window, s in episode_sums(planner, paths[episode]).items():
                sums[window].append(s)
        row = {"scenario": scenario, "policy": str(Path(spec).relative_to(ROOT)), "windows": {}}
        frames = episodes * cfg.episode_frames
        for window in WINDOWS_FRAMES:
            here, claimed, now, age = np.array(sums[window]).T
            ratios = {}
            for name, v in (("claimed", claimed), ("now", now)):
                r, lo, hi = paired_ratio_ci(v, here)
                ratios[name] = {"ratio": round(r, 4), "ci95": [round(lo, 4), round(hi, 4)]}
            row["windows"][str(window)] = {
                **ratios,
                "here_mbps": round(float(here.sum() / frames), 4),
                "mean_age_frames": round(float(age.sum() / frames), 1),
            }
        rows.append(row)
    return {
        "benchmark": "memory_worth",
        "episodes": episodes,
        "seed": seed,
        "windows_frames": list(WINDOWS_FRAMES),
        "statistic": "the memory's pick (best value sensed over the last A frames) against the value here: "
        "as sensed then (claimed) and as it would be now (now); mean-channel rates of the "
        "spatial policy's path, ratio of episode sums with a 95 % paired bootstrap interval",
        "rows": rows,
    }


def markdown(result: dict) -> str:
    head = " | ".join(
        f"last {w}: claimed | last {w}: now | last {w}: age" for w in result["windows_frames"]
    )
    lines = [
        f"| scenario | here (Mbps) | {head} |",
        "|---|---:|" + "---:|---:|---:|" * len(result["windows_frames"]),
    ]
    for row in result["rows"]:
        cells = []
        for w in result["windows_frames"]:
            s = row["windows"][str(w)]
            for name in ("claimed", "now"):
                r, (lo, hi) = s[name]["ratio"], s[name]["ci95"]
                cells.append(f"{r:.3f} [{lo:.3f}, {hi:.3f}]")
            cells.append(f"{s['mean_age_frames']:.1f}")
        here = row["windows"][str(result["windows_frames"][0])]["here_mbps"]
        lines.append(f"| {row['scenario']} | {here:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def plot(result: dict, path: Path) -> None:
    """Per scenario, what the memory's pick claims and what it is worth now, against the memory's
    length: the two lines part where the team moves."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    windows = result["windows_frames"]
    fig = Figure(figsize=(7.0, 4.2), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for i, row in enumerate(result["rows"]):
        colour = f"C{i}"
        for name, style in (("claimed", ":"), ("now", "-")):
            ax.plot(
                windows,
                [row["windows"][str(w)][name]["ratio"] for w in windows],
                style,
                color=colour,
                marker="o",
                label=row["scenario"] if name == "now" else None,
            )
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_xscale("log", base=2)
    ax.set_xticks(windows, [str(w) for w in windows])
    ax.set_xlabel("memory length (frames): the pick is the best spot sensed over the last ones")
    ax.set_ylabel("pick / here (mean-channel throughput)")
    ax.set_title(
        f"The remembered best spot: claimed (dotted) and worth now (solid), "
        f"{result['episodes']} episodes",
        fontsize=9,
    )
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(path)


def main(argv: list[str] | None = None) -> int:
    from uavlink.mobility import SCENARIOS

    args = scenario_args(
        __doc__,
        argv,
        list(SCENARIOS),
        50,
        plot_help="also draw the ratios against the memory's length into this PNG",
    )
    result = run(args.scenarios, args.episodes, args.seed, progress=sys.stderr.isatty())
    print(json.dumps(result, indent=1) if args.json else markdown(result))
    if args.plot is not None:
        plot(result, args.plot)
    return 0


if __name__ == "__main__":
    run_script(main)
