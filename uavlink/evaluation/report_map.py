"""The results report's memory-of-place part: the map policies (trained with a memory of
place, ``sweeps/map.toml``) against today's spatial policies and the GPS-free ``explore`` rule.

Per scenario that has a map policy, and mixed (each episode's scenario drawn): the map policy, the
spatial policy of the scenario, explore, aoa, static and the genie (the full-knowledge yardstick),
all on the spatial channel on the same seeded episodes, with paired ratios: the map policy over the
spatial policy, over explore and over the teacher its warm start copied (the rule with its knobs,
rebuilt from the policy's manifest by the caller's ``teacher_of``:
``uavlink.learn.teachers.policy_teacher``, which this layer may not import), explore over the spatial
policy, and each of the two policies as a share of the genie.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from uavlink.config import SCENARIO_NAMES, EnvConfig
from uavlink.evaluation import EvalResult, evaluate_policy, paired_ratio_ci
from uavlink.evaluation.map_sensitivity import SENSITIVITY_SCENARIOS, sensitivity, sensitivity_table
from uavlink.evaluation.place_map import draw_place_map, fly_place_map
from uavlink.evaluation.tables import (
    ReportRun,
    gain_cell,
    markdown_table,
    share_cell,
    spatial_overrides,
    write_csv,
)
from uavlink.policies.base import Policy
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.loader import policy_for_scenario
from uavlink.policies.manifest import PolicyFileError

COLUMNS = ("map", "spatial", "explore", "aoa", "static", "genie")


def _ratio(results: dict[str, EvalResult], a: str, b: str) -> str:
    return gain_cell(*paired_ratio_ci(results[a].episode_rate_mbps, results[b].episode_rate_mbps))


def _share(results: dict[str, EvalResult], a: str) -> str:
    return share_cell(
        *paired_ratio_ci(results[a].episode_rate_mbps, results["genie"].episode_rate_mbps)
    )


# (policy, its env) -> the teacher its warm start copied, flying that env (None where it copied no
# rule), and a label naming it
TeacherOf = Callable[[Policy, EnvConfig], tuple[Policy | None, str]]


def map_table(
    map_folder: Path,
    spatial_folder: Path,
    episodes: int,
    seed: int,
    overrides: EnvOverrides,
    teacher_of: TeacherOf,
    progress: Callable[[str], None] = lambda _: None,
    with_genie: bool = True,
) -> tuple[list[str], list[list[str]]]:
    """The table's header and rows; ``with_genie=False`` leaves out the genie's columns (its plans
    cost about a CPU-second per episode, where the rest costs milliseconds)."""
    columns = COLUMNS if with_genie else COLUMNS[:-1]
    header = [
        "scenario",
        "map PPO",
        "spatial PPO",
        "explore",
        "aoa",
        "static",
        *(["genie"] if with_genie else []),
        "map vs spatial PPO",
        "map vs explore",
        "map vs its teacher",
        "explore vs spatial PPO",
        *(["map / genie", "spatial / genie"] if with_genie else []),
    ]
    body = []
    on_spatial = spatial_overrides(overrides)
    for scenario in SCENARIO_NAMES:  # mixed: one policy for all, each episode's scenario drawn
        try:
            map_file = policy_for_scenario(map_folder, scenario)
        except PolicyFileError:
            continue  # not trained yet: the table shows the scenarios that are
        specs = [map_file, policy_for_scenario(spatial_folder, scenario), *columns[2:]]
        loaded = load_with_env(specs, on_spatial.on(scenario))
        results = {}
        for column, (policy, cfg) in zip(columns, loaded, strict=True):
            progress(f"map {scenario}: {column}")
            results[column] = evaluate_policy(policy, cfg, episodes, seed)
        teacher, label = teacher_of(*loaded[0])
        if teacher is not None:  # flies the map policy's env, as it did in the warm start
            progress(f"map {scenario}: {label}")
            results["teacher"] = evaluate_policy(teacher, loaded[0][1], episodes, seed)
            label = f"{label}: {_ratio(results, 'map', 'teacher')}"
        body.append(
            [
                scenario,
                *(f"{results[c].mean_rate_mbps:.2f} ± {results[c].ci95_mbps:.2f}" for c in columns),
                _ratio(results, "map", "spatial"),
                _ratio(results, "map", "explore"),
                label,
                _ratio(results, "explore", "spatial"),
                *([_share(results, "map"), _share(results, "spatial")] if with_genie else []),
            ]
        )
    return header, body


def map_sections(
    run: ReportRun,
    map_folder: Path,
    spatial_folder: Path,
    sweep_sections: list[str],
    teacher_of: TeacherOf,
) -> list[str]:
    """Evaluate, write ``map.csv`` and the pictures into ``run.out`` and return the Markdown of the
    part, which links the pictures as the Markdown sees ``run.out``."""
    out, rel, seed, overrides, progress = run.out, run.rel, run.seed, run.overrides, run.progress
    header, body = map_table(
        map_folder, spatial_folder, run.episodes, seed, overrides, teacher_of, progress
    )
    write_csv(out / "map.csv", header, body)
    pictures = []
    for scenario in (row[0] for row in body):
        progress(f"map {scenario}: picture")
        [(policy, cfg)] = load_with_env(
            [policy_for_scenario(map_folder, scenario)], spatial_overrides(overrides).on(scenario)
        )
        draw_place_map(fly_place_map(policy, cfg, seed), out / f"place_map_{scenario}.png")
        pictures += [
            f"![the map {scenario}'s policy built]({rel / f'place_map_{scenario}.png'})",
            "",
        ]
    trained = [s for s in SENSITIVITY_SCENARIOS if s in {row[0] for row in body}]
    by_channel = (
        sensitivity(map_folder, spatial_folder, run.episodes, seed, trained, progress, overrides)
        if trained
        else None
    )
    return [
        f"### A memory of place: map policies (`{map_folder}`) and the explore rule",
        "",
        "Policies whose observation holds a memory of place (layout v3: the best spot the UAV sensed,",
        "relative to it, its value against now and its age; on no_move layout v5, with the spot a model",
        "of the sensed field picks; docs/design/baselines.md), trained on the spatial",
        "channel (`sweeps/map.toml`), against the spatial policies above and the GPS-free `explore`",
        "rule (search a cross, return to the best spot sensed, follow the team when it leaves), and as a",
        "share of the `genie` (the full-knowledge yardstick). Same episodes; paired ratios with 95 %",
        "bootstrap intervals; `mixed`: each episode's scenario drawn, the mixed policies of both kinds.",
        '"Its teacher" is the rule the policy\'s warm start copied, with its knobs (speed span, shadow',
        "gate, shadowing estimator), rebuilt from the policy's manifest as training built it.",
        "Scenarios without a map policy yet are left out.",
        "",
        markdown_table(header, body),
        "",
        f"What each map policy remembered in episode 0 of seed {seed} (`uavlink.evaluation.place_map`):",
        "left, the mean UE throughput a UAV would get from each spot at the episode's last frame (path",
        "loss and the shadowing field, no fast fading); right, the value the policy sensed in each cell it",
        "visited, on the same scale, and the cell its memory ranks best.",
        "",
        *pictures,
        *(
            []
            if by_channel is None
            else [
                "#### How much a map is worth on which channel",
                "",
                "Each policy over static on the same episodes, with the shadowing's sigma and its UAV-end",
                "decorrelation set by radio overrides (the map and spatial policies were trained at 8 dB and",
                "50 m; `uavlink.evaluation.map_sensitivity`, also `python research/map_sensitivity.py`).",
                "A short decorrelation puts a better spot near any other; a long one leaves little to find.",
                "",
                sensitivity_table(by_channel),
                "",
            ]
        ),
        *sweep_sections,
    ]
