"""The results folder: Table I, Table II and the paper's figures, from seeded evaluations.

``uavlink evaluate --scenario all --policy FOLDER --out DIR`` calls ``write_results``. Every number
in the Markdown comes from the evaluations made in that call; the command is written into the file.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from uavlink.evaluation.report_fleet import fleet_sections
from uavlink.evaluation.report_map import TeacherOf, map_sections
from uavlink.evaluation.report_spatial import spatial_sections
from uavlink.evaluation.tables import (
    ReportRun,
    ScenarioRow,
    evaluate_scenarios,
    markdown_table,
    table_one,
    table_two,
    write_csv,
)
from uavlink.mobility import SCENARIOS
from uavlink.policies.loader import policy_for_scenario


def plot_throughput_per_episode(rows: list[ScenarioRow], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for row in rows:
        rates = row.results["ppo"].episode_rate_mbps
        ax.plot(np.arange(1, len(rates) + 1), rates, label=row.scenario, lw=1.2)
    ax.set_xlabel("evaluation episode")
    ax.set_ylabel("average UE throughput (Mbps)")
    ax.set_title("PPO: average throughput per evaluation episode")
    ax.grid(alpha=0.3)
    ax.legend(ncol=3, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_throughput_vs_fairness(rows: list[ScenarioRow], path: Path) -> None:
    """Per scenario, each policy's mean throughput (the table's metric) against its mean R_fair
    (PPO's reward): where the two rank policies differently, the reward does not pay for the metric."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {
        "ppo": ("tab:red", "o"),
        "ppo_mixed": ("tab:orange", "v"),
        "aoa": ("tab:blue", "s"),
        "oracle": ("tab:green", "D"),
        "static": ("tab:gray", "x"),
    }
    fig, axes = plt.subplots(2, 3, figsize=(11, 6.5))
    for ax, row in zip(axes.flat, rows, strict=True):  # the six scenarios
        for key, result in row.results.items():
            color, marker = styles[key]
            ax.errorbar(
                result.mean_fair_rate,
                result.mean_rate_mbps,
                yerr=result.ci95_mbps,
                color=color,
                marker=marker,
                ms=6,
                capsize=2,
                ls="none",
                label=key.replace("_", " "),
            )
        ax.set_title(row.scenario, fontsize=10)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("R_fair (sum of log10 rate), PPO's reward")
    for ax in axes[:, 0]:
        ax.set_ylabel("average UE throughput (Mbps)")
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(
        "Throughput against R_fair, mean over the evaluation episodes (bars: 95 % interval)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_trajectories(row: ScenarioRow, half_width_m: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    traj = row.results["ppo"].trajectory
    assert traj is not None  # table one's columns are evaluated with record_trajectory
    for u in range(traj.ue_xy_m.shape[1]):
        ax.plot(
            traj.ue_xy_m[:, u, 0],
            traj.ue_xy_m[:, u, 1],
            color="tab:gray",
            lw=0.6,
            alpha=0.7,
            label="UEs" if u == 0 else None,
        )
    for key, color in (("ppo", "tab:red"), ("aoa", "tab:blue"), ("oracle", "tab:green")):
        t = row.results[key].trajectory
        assert t is not None  # recorded as for ppo
        ax.plot(
            t.uav_xy_m[:, 0, 0],
            t.uav_xy_m[:, 0, 1],
            color=color,
            lw=1.6,
            label=f"UAV {key} ({row.results[key].episode_rate_mbps[0]:.2f} Mbps)",
        )
    ax.plot(0, 0, "k+", ms=10)
    ax.set_xlim(-half_width_m, half_width_m)
    ax.set_ylim(-half_width_m, half_width_m)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(f"{row.scenario}: episode 0")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_results(
    run: ReportRun,
    policy_folder: Path,
    command: str,
    sweep_sections: Callable[[Path, str], list[str]] = lambda _, __: [],
    spatial_folder: Path | None = None,
    fleet_folder: Path | None = None,
    map_folder: Path | None = None,
    fleet_per_size_folder: Path | None = None,
    teacher_of: TeacherOf | None = None,
) -> Path:
    """Evaluate everything, then write the folder ``run.out`` and the Markdown ``run.markdown``
    (nothing is written if an evaluation fails); returns the Markdown path.
    ``sweep_sections(link_prefix, kind)`` gives the across-seed sections of the sweeps of that kind
    (``"ar1"``, ``"spatial"``, ``"fleet"``, ``"map"``); with ``spatial_folder`` (policies trained on the
    spatial channel) the report gains its spatial part (``uavlink.evaluation.report_spatial``), with
    ``fleet_folder`` too (fleet policies; ``fleet_per_size_folder``: the per-size ones to pair them
    with) its fleet part (``uavlink.evaluation.report_fleet``), and with
    ``map_folder`` too (policies with a memory of place) its map part
    (``uavlink.evaluation.report_map``), whose ``teacher_of`` rebuilds each map policy's warm-start teacher."""
    if map_folder is not None and teacher_of is None:
        raise ValueError("the map part needs teacher_of (uavlink.learn.teachers.policy_teacher)")
    episodes, seed, out, rel = run.episodes, run.seed, run.out, run.rel
    rows = evaluate_scenarios(policy_folder, episodes, seed, run.overrides, run.progress)
    h1, b1 = table_one(rows)
    run.progress("table II")
    h2, b2 = table_two(policy_folder, episodes, seed, run.overrides)
    out.mkdir(parents=True, exist_ok=True)
    spatial = []
    if spatial_folder is not None:
        spatial = spatial_sections(
            run, policy_folder, spatial_folder, rows, sweep_sections(rel, "spatial")
        )
    if map_folder is not None and spatial_folder is not None:
        assert teacher_of is not None  # checked above
        spatial += map_sections(
            run, map_folder, spatial_folder, sweep_sections(rel, "map"), teacher_of
        )
    fleet = []
    if fleet_folder is not None and spatial_folder is not None:
        fleet = fleet_sections(
            run,
            fleet_folder,
            spatial_folder,
            rows[0].cfg.area.half_width_m,
            fleet_per_size_folder,
        ) + sweep_sections(rel, "fleet")
    write_csv(out / "table1.csv", h1, b1)
    write_csv(out / "table2.csv", h2, b2)
    plot_throughput_per_episode(rows, out / "throughput_per_episode.png")
    plot_throughput_vs_fairness(rows, out / "throughput_vs_fairness.png")
    for row in rows:
        plot_trajectories(row, row.cfg.area.half_width_m, out / f"trajectory_{row.scenario}.png")
    raw = {row.scenario: {k: v.to_dict() for k, v in row.results.items()} for row in rows}
    (out / "results.json").write_text(json.dumps(raw, indent=1))
    manifests = {s: policy_for_scenario(policy_folder, s).name for s in SCENARIOS}
    text = [
        "# Results",
        "",
        f"Generated by `{command}` ({episodes} episodes per cell, seed {seed}; all policies see the same",
        "UE trajectories and radio draws). ± is the 95 % interval over episodes; intervals on ratios are",
        "paired bootstraps over episodes. The target column applies the SPEC's rule per scenario: the",
        "paper's gain over static; where even the GPS oracle cannot reach that, min(paper PPO, 95 % of",
        "oracle); never below 90 % of oracle. R_fair (sum of log10 rates, the quantity PPO is",
        "trained to maximise) shows where a higher mean throughput would come at the cost of fairness.",
        "",
        "## Table I — average UE throughput (Mbps)",
        "",
        markdown_table(h1, b1),
        "",
        "Policies: " + ", ".join(f"{s} → `{n}`" for s, n in manifests.items()) + ".",
        "",
        *sweep_sections(rel, "ar1"),
        "## Table II — PPO on `straight` under AoA noise",
        "",
        markdown_table(h2, b2),
        "",
        "## Average throughput per evaluation episode",
        "",
        f"![throughput per episode]({rel / 'throughput_per_episode.png'})",
        "",
        "## Throughput against R_fair",
        "",
        "PPO is trained on R_fair; the tables rank by throughput. Up and right is better on both.",
        "",
        f"![throughput vs R_fair]({rel / 'throughput_vs_fairness.png'})",
        "",
        "## One episode per scenario (UAV trajectories of PPO, aoa and oracle; UEs in grey)",
        "",
        *[f"![{s}]({rel / f'trajectory_{s}.png'})" for s in SCENARIOS],
        "",
        *spatial,
        *fleet,
    ]
    run.markdown.parent.mkdir(parents=True, exist_ok=True)
    run.markdown.write_text("\n".join(text))
    return run.markdown
