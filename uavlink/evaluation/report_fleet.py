"""The results report's fleet part (SPEC "A fleet"): D = 1, 2, 3 UAVs on the spatial channel.

Every number comes from seeded evaluations on the same episodes (the UEs' motion depends on the
scenario and seed only, so a fleet and a single UAV meet the same UEs and are paired episode by
episode): every baseline for D = 1, 2, 3, the fleet policies (D = 2) and the single-UAV spatial
policies; the fleet policies' ratios against the fleet oracle, the fleet aoa rule and one UAV's
policy, each with a 95 % paired interval and the issue's target; the fleet metrics (Jain's index,
5th-percentile UE rate, UEs per UAV); and a trajectory plot per scenario.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from uavlink.evaluation.core import EvalResult, evaluate_policy, paired_ratio_ci
from uavlink.evaluation.tables import ReportRun, markdown_table, spatial_overrides, write_csv
from uavlink.mobility import SCENARIOS
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.registry import make_baseline

FLEET_BASELINES = ("static", "oracle", "aoa", "kmeans", "genie")
FLEET_SIZES = (1, 2, 3)
POLICY_UAVS = 2  # the shipped fleet policies' D
# Results are keyed "D<d> <baseline>"; the fleet policies' and the single-UAV policies' keys:
FLEET_PPO, SINGLE_PPO = f"D{POLICY_UAVS} ppo", "D1 ppo"
# The bars set for the D = 2 policies: share of the fleet oracle, share of one UAV's policy.
ORACLE_SHARE = {"straight_90": 0.95, "straight_180": 0.95, "hotspot": 0.95}
SINGLE_SHARE = {"no_move": 0.98, "straight": 0.98, "circular": 0.98, "straight_180": 1.6}


def _ratio(a: EvalResult, b: EvalResult) -> tuple[float, float, float]:
    return paired_ratio_ci(a.episode_rate_mbps, b.episode_rate_mbps)


def _fmt(ratio: tuple[float, float, float]) -> str:
    r, lo, hi = ratio
    return f"{r:.3f} [{lo:.3f}, {hi:.3f}]"


def evaluate_fleet(
    fleet_folder: Path,
    single_folder: Path,
    episodes: int,
    seed: int,
    overrides: EnvOverrides,
    progress: Callable[[str], None] = lambda _: None,
) -> dict[str, dict[str, EvalResult]]:
    """Per scenario, results keyed ``"D<d> <baseline>"``, ``FLEET_PPO`` and ``SINGLE_PPO``."""
    on_spatial = spatial_overrides(overrides)
    out = {}
    for scenario in SCENARIOS:
        ((fleet, cfg2),) = load_with_env([fleet_folder], on_spatial.on(scenario))
        ((single, cfg1),) = load_with_env([single_folder], on_spatial.on(scenario))
        results = {}
        for d in FLEET_SIZES:
            cfg = cfg2.replace(n_uavs=d).validate()
            for name in FLEET_BASELINES:
                progress(f"fleet {scenario}: D={d} {name}")
                results[f"D{d} {name}"] = evaluate_policy(
                    make_baseline(name, cfg), cfg, episodes, seed
                )
        progress(f"fleet {scenario}: policies")
        results[FLEET_PPO] = evaluate_policy(fleet, cfg2, episodes, seed, record_trajectory=True)
        results[SINGLE_PPO] = evaluate_policy(single, cfg1, episodes, seed)
        out[scenario] = results
    return out


def throughput_table(rows: dict[str, dict[str, EvalResult]]) -> tuple[list[str], list[list[str]]]:
    columns = [f"D{d} {b}" for d in FLEET_SIZES for b in FLEET_BASELINES]
    # Each policy's column after the baselines with its number of UAVs.
    columns.insert(columns.index(f"D1 {FLEET_BASELINES[-1]}") + 1, SINGLE_PPO)
    columns.insert(columns.index(f"D{POLICY_UAVS} {FLEET_BASELINES[-1]}") + 1, FLEET_PPO)
    header = ["scenario", *[c.replace("ppo", "PPO") for c in columns]]
    return header, [[s, *(f"{r[c].mean_rate_mbps:.2f}" for c in columns)] for s, r in rows.items()]


def ratio_table(rows: dict[str, dict[str, EvalResult]]) -> tuple[list[str], list[list[str]]]:
    """The fleet policies against the fleet oracle, the fleet aoa rule and one UAV's policy."""
    header = [
        "scenario",
        "PPO / oracle",
        "PPO / aoa",
        "PPO / one UAV's PPO",
        "target",
        "met",
        "PPO / genie",
    ]
    body = []
    for scenario, r in rows.items():
        ppo, fleet = r[FLEET_PPO], f"D{POLICY_UAVS}"
        vs_oracle, vs_aoa = _ratio(ppo, r[f"{fleet} oracle"]), _ratio(ppo, r[f"{fleet} aoa"])
        vs_single = _ratio(ppo, r[SINGLE_PPO])
        bars = [("vs aoa", 1.0, vs_aoa)]
        if scenario in ORACLE_SHARE:
            bars.append(("vs oracle", ORACLE_SHARE[scenario], vs_oracle))
        if scenario in SINGLE_SHARE:
            bars.append(("vs one UAV", SINGLE_SHARE[scenario], vs_single))
        target = ", ".join(f"{what} >= {bar:g}" for what, bar, _ in bars)
        met = "yes" if all(ratio[0] >= bar for _, bar, ratio in bars) else "no"
        body.append(
            [
                scenario,
                _fmt(vs_oracle),
                _fmt(vs_aoa),
                _fmt(vs_single),
                target,
                met,
                _fmt(_ratio(ppo, r[f"{fleet} genie"])),
            ]
        )
    return header, body


def metrics_table(rows: dict[str, dict[str, EvalResult]]) -> tuple[list[str], list[list[str]]]:
    """The fleet metrics of the fleet policies and the baselines with as many UAVs."""
    header = [
        "scenario",
        f"policy (D = {POLICY_UAVS})",
        "Mbps",
        "R_fair",
        "Jain",
        "5th pct UE Mbps",
        "UEs per UAV",
    ]
    body = []
    for scenario, r in rows.items():
        for key in (FLEET_PPO, *(f"D{POLICY_UAVS} {b}" for b in FLEET_BASELINES)):
            x = r[key]
            body.append(
                [
                    scenario,
                    key.split(" ", 1)[1].replace("ppo", "PPO"),
                    f"{x.mean_rate_mbps:.2f}",
                    f"{x.mean_fair_rate:.2f}",
                    f"{x.jain_index:.3f}",
                    f"{x.p5_ue_rate_mbps:.2f}",
                    " / ".join(f"{n:.1f}" for n in x.ues_per_uav),
                ]
            )
    return header, body


def plot_fleet_trajectory(
    scenario: str, result: EvalResult, half_width_m: float, path: Path
) -> None:
    """Episode 0 of a fleet policy: each UAV's path, the UEs coloured by the UAV serving them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = result.trajectory
    assert t is not None  # evaluated with record_trajectory
    colors = matplotlib.color_sequences["tab10"]  # the tab10 colormap's colours, as a list
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    ue = t.ue_xy_m.reshape(-1, 2)
    ax.scatter(
        ue[:, 0], ue[:, 1], s=2, c=[colors[d % 10] for d in t.serving.ravel()], alpha=0.35, lw=0
    )
    for d in range(t.uav_xy_m.shape[1]):
        ax.plot(
            t.uav_xy_m[:, d, 0], t.uav_xy_m[:, d, 1], color=colors[d % 10], lw=2.0, label=f"UAV {d}"
        )
        ax.plot(*t.uav_xy_m[0, d], "o", color=colors[d % 10], ms=5)
    ax.set_xlim(-half_width_m, half_width_m)
    ax.set_ylim(-half_width_m, half_width_m)
    ax.set_aspect("equal")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_title(
        f"{scenario}: fleet of {t.uav_xy_m.shape[1]}, episode 0 ({result.episode_rate_mbps[0]:.2f} Mbps); "
        "UEs coloured by their UAV",
        fontsize=8,
    )
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def fleet_sections(
    run: ReportRun, fleet_folder: Path, single_folder: Path, half_width_m: float
) -> list[str]:
    """Evaluate, write the CSVs and plots into ``run.out`` and return the Markdown of the fleet part."""
    out, rel, seed = run.out, run.rel, run.seed
    rows = evaluate_fleet(
        fleet_folder, single_folder, run.episodes, seed, run.overrides, run.progress
    )
    tables = {
        "fleet_throughput": throughput_table(rows),
        "fleet_ratios": ratio_table(rows),
        "fleet_metrics": metrics_table(rows),
    }
    for name, (header, body) in tables.items():
        write_csv(out / f"{name}.csv", header, body)
    for scenario, r in rows.items():
        plot_fleet_trajectory(
            scenario, r[FLEET_PPO], half_width_m, out / f"fleet_trajectory_{scenario}.png"
        )
    n = len(next(iter(rows.values()))[FLEET_PPO].episode_rate_mbps)
    return [
        "## A fleet of UAVs (spatial channel)",
        "",
        f"Mean UE throughput (Mbps) over {n} episodes (seed {seed}) on the spatial channel, D UAVs sharing the "
        'band with full reuse (SPEC "A fleet"); every column flies the same UE trajectories. '
        f"`D{POLICY_UAVS} PPO` is "
        f"`{fleet_folder}/<scenario>.zip`, `D1 PPO` the single-UAV spatial policy `{single_folder}/<scenario>.zip`; "
        "oracle and kmeans know the UEs' positions (GPS), aoa and PPO do not; genie knows the episode's future "
        "(UE paths, shadowing field) and plans each UAV's path given the others' (docs/design/baselines.md), the limit.",
        "",
        markdown_table(*tables["fleet_throughput"]),
        "",
        "The fleet policies' ratios (paired over episodes, 95 % bootstrap interval) and the bars set for them: "
        ">= the fleet aoa rule everywhere, >= 95 % of the fleet oracle where the UEs split or spread, "
        ">= 98 % of one UAV's policy where they stay together (a second UAV must not hurt) and 1.6x on "
        "straight_180. PPO / genie: how far from the full-knowledge limit the fleet policy flies.",
        "",
        markdown_table(*tables["fleet_ratios"]),
        "",
        f"Fleet metrics, D = {POLICY_UAVS}: Jain's index of the UE rates (mean over frames), the 5th percentile of the "
        "UEs' episode rates, the mean number of UEs each UAV serves.",
        "",
        markdown_table(*tables["fleet_metrics"]),
        "",
        *[f"![{s} fleet]({rel / f'fleet_trajectory_{s}.png'})" for s in SCENARIOS],
        "",
    ]
