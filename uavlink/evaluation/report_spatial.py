"""The results report's spatial-channel part: what of each learned gain survives shadowing with a
memory of place (``radio.shadowing_model = "spatial"``, SPEC "A spatially consistent channel").

Three evaluations on the spatial channel, all on the same seeded episodes as the AR(1) Table I:
the policies trained on it (a second Table I and Table II), and the AR(1) policies flown on it
(how much of each gain transfers). The transfer table sets, per scenario, PPO's gain over the aoa
rule and its share of the GPS oracle side by side for the three cases, so a reader sees which part
of a gain was the channel and which was learning.
"""

from __future__ import annotations

from pathlib import Path

from uavlink.evaluation.core import paired_ratio_ci
from uavlink.evaluation.tables import (
    ReportRun,
    ScenarioRow,
    evaluate_scenarios,
    gain_cell,
    markdown_table,
    spatial_overrides,
    table_one,
    table_two,
    write_csv,
)


def _vs(row: ScenarioRow, other: str) -> str:
    return gain_cell(
        *paired_ratio_ci(row.results["ppo"].episode_rate_mbps, row.results[other].episode_rate_mbps)
    )


def transfer_table(
    ar1: list[ScenarioRow], transferred: list[ScenarioRow], spatial: list[ScenarioRow]
) -> tuple[list[str], list[list[str]]]:
    """Per scenario, PPO vs aoa and PPO vs oracle (paired, 95 %): AR(1) policies on AR(1), the same
    policies on the spatial channel, and policies trained on the spatial channel."""
    header = [
        "scenario",
        "AR(1): PPO vs aoa",
        "AR(1): PPO vs oracle",
        "AR(1) policy on spatial: vs aoa",
        "AR(1) policy on spatial: vs oracle",
        "spatial policy: vs aoa",
        "spatial policy: vs oracle",
    ]
    body = [
        [
            a.scenario,
            _vs(a, "aoa"),
            _vs(a, "oracle"),
            _vs(t, "aoa"),
            _vs(t, "oracle"),
            _vs(s, "aoa"),
            _vs(s, "oracle"),
        ]
        for a, t, s in zip(ar1, transferred, spatial, strict=True)
    ]
    return header, body


def spatial_sections(
    run: ReportRun,
    ar1_folder: Path,
    spatial_folder: Path,
    ar1_rows: list[ScenarioRow],
    sweep_sections: list[str],
) -> list[str]:
    """Evaluate, write the CSVs into ``run.out`` and return the Markdown of the spatial part."""
    on_spatial = spatial_overrides(run.overrides)
    spatial = evaluate_scenarios(
        spatial_folder,
        run.episodes,
        run.seed,
        on_spatial,
        lambda m: run.progress(f"spatial {m}"),
        extra=("genie",),
    )
    transferred = evaluate_scenarios(
        ar1_folder,
        run.episodes,
        run.seed,
        on_spatial,
        lambda m: run.progress(f"AR(1) policies on spatial {m}"),
    )
    run.progress("spatial table II")
    h1, b1 = table_one(spatial)
    h2, b2 = table_two(spatial_folder, run.episodes, run.seed, on_spatial)
    h3, b3 = transfer_table(ar1_rows, transferred, spatial)
    out = run.out
    write_csv(out / "table1_spatial.csv", h1, b1)
    write_csv(out / "table2_spatial.csv", h2, b2)
    write_csv(out / "transfer_spatial.csv", h3, b3)
    return [
        "## On the spatial channel",
        "",
        'The same tables with shadowing as a function of place (`radio.shadowing_model = "spatial"`,',
        "docs/design/radio.md): a UAV that returns to a spot reads the shadowing it read there before, so no",
        "policy can re-roll a building's shadow by moving. Same episodes, seeds and columns as above.",
        "",
        f"### Table I on the spatial channel (policies trained on it: `{spatial_folder}`)",
        "",
        markdown_table(h1, b1),
        "",
        '`genie` is the full-knowledge yardstick (SPEC "The limit, and a memory of place"): it knows the',
        "episode's UE paths and shadowing field and flies the best path under the motion limits (dynamic",
        "programming over a 4 m grid, docs/design/baselines.md); PPO / genie is how far from that limit each policy flies.",
        "",
        *sweep_sections,
        "### What survives: PPO's gain over the aoa rule and its share of the oracle, per channel",
        "",
        "Paired ratios over the same episodes, 95 % bootstrap intervals. AR(1): the shipped policies on",
        "the paper's channel (Table I above); AR(1) policy on spatial: the same policies flown on the",
        "spatial channel; spatial policy: the policies trained there. The baselines fly each case's channel.",
        "",
        markdown_table(h3, b3),
        "",
        "### Table II on the spatial channel (the spatial `straight` policy under AoA noise)",
        "",
        markdown_table(h2, b2),
        "",
    ]
