"""The results report's fleet part (SPEC "A fleet"): D = 1, 2, 3, 4 UAVs on the spatial channel.

Every number comes from seeded evaluations on the same episodes (the UEs' motion depends on the
scenario and seed only, so fleets of every size and a single UAV meet the same UEs and are paired
episode by episode), each evaluated once per scenario: every baseline at every D, the fleet policy
at each D its layout flies (an any-size policy, layout v6: D = 2 to its slots + 1; a per-size one:
its own D), the per-size policies of the ``per_size_folder`` at theirs and one UAV's spatial policy.
The tables (``report_fleet_tables``): throughput, per D the fleet policy's paired ratios against
kmeans, the genie, the aoa rule and the per-size policy with the issue's bars, per D the fleet
metrics (Jain's index, 5th-percentile UE rate, UEs per UAV); and a trajectory plot per scenario.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from pathlib import Path

from uavlink.config import EnvConfig, fleet_sizes_of
from uavlink.config.env import PLACE_CELLS, REUSE_LISTEN
from uavlink.errors import UserError
from uavlink.evaluation.core import EvalResult, evaluate_policy
from uavlink.evaluation.report_fleet_tables import (
    FLEET_BASELINES,
    FLEET_SIZES,
    JAIN_GAP,
    SINGLE_PPO,
    Rows,
    bars_text,
    by_size,
    fleet_sizes,
    genie_fairness,
    metrics_table,
    per_size,
    ppo,
    ratio_table,
    throughput_table,
)
from uavlink.evaluation.tables import ReportRun, markdown_table, spatial_overrides, write_csv
from uavlink.mobility import SCENARIOS
from uavlink.policies.base import Policy
from uavlink.policies.contract import EnvOverrides, load_with_env
from uavlink.policies.genie import GeniePolicy
from uavlink.policies.registry import make_baseline

PLOT_UAVS = 3  # the fleet size of the trajectory plots (the policy's first size if it flies no 3)


def sizes_flown(policy: Policy, cfg: EnvConfig) -> list[int]:
    """The fleet sizes a policy flies among ``FLEET_SIZES``: an any-size layout's (v6, K slots:
    D = 2 to K + 1), else the policy's own ``n_uavs``."""
    slots = getattr(policy.layout, "uav_slots", 0)
    sizes = fleet_sizes_of(slots) if slots > 0 else [cfg.n_uavs]
    return [d for d in sizes if d > 1 and d in FLEET_SIZES]


def evaluate_fleet(
    fleet_folder: Path,
    single_folder: Path,
    episodes: int,
    seed: int,
    overrides: EnvOverrides,
    progress: Callable[[str], None] = lambda _: None,
    per_size_folder: Path | None = None,
    workers: int = 1,
) -> Rows:
    """Per scenario, results by column (``report_fleet_tables``): ``"D<d> <baseline>"`` for every
    D and baseline, ``"D<d> PPO"`` for each D the fleet policy flies (at ``PLOT_UAVS``, or its
    first D, with episode 0's trajectory), ``"D<d> PPO (per size)"`` for each D a
    ``per_size_folder`` policy flies and ``"D1 PPO"`` for one UAV's. Nothing is evaluated twice.
    With ``workers`` > 1 the evaluations run in that many processes (each rebuilds its scenario's
    jobs and runs one; seeded, so the figures are the same as in one process)."""
    on_spatial = spatial_overrides(overrides)
    folders = (fleet_folder, single_folder, on_spatial, per_size_folder)
    if workers > 1:
        return _evaluate_in_processes(folders, episodes, seed, progress, workers)
    out = {}
    for k, scenario in enumerate(SCENARIOS, 1):
        results: dict[str, EvalResult] = {}
        for key, policy, cfg, source, record in _fleet_jobs(scenario, *folders):
            assert key not in results  # each (D, policy) once: the D = 4 genie costs seconds
            what = key if source is None else f"{key} from {source}/{scenario}"
            progress(f"fleet {scenario} ({k}/{len(SCENARIOS)}): {what}, {episodes} episodes")
            results[key] = evaluate_policy(policy, cfg, episodes, seed, record_trajectory=record)
        out[scenario] = results
    return out


Folders = tuple[Path, Path, EnvOverrides, Path | None]  # fleet, single, overrides, per size


def _evaluate_in_processes(
    folders: Folders,
    episodes: int,
    seed: int,
    progress: Callable[[str], None],
    workers: int,
) -> Rows:
    """``evaluate_fleet``'s evaluations, one task each, in ``workers`` processes."""
    import concurrent.futures
    import multiprocessing

    keys = {s: [job[0] for job in _fleet_jobs(s, *folders)] for s in SCENARIOS}
    assert all(len(set(k)) == len(k) for k in keys.values())  # each (D, policy) once
    out: Rows = {s: {} for s in SCENARIOS}
    # spawn, not fork: the parent may hold torch's thread pools, which a fork does not copy safely
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(
        workers, mp_context=context, initializer=_worker_folders, initargs=(folders,)
    ) as pool:
        jobs = sorted(((s, key) for s in SCENARIOS for key in keys[s]), key=_longest_first)
        futures = {
            pool.submit(_evaluate_one, scenario, key, episodes, seed): (scenario, key)
            for scenario, key in jobs
        }
        for done, future in enumerate(concurrent.futures.as_completed(futures), 1):
            scenario, key = futures[future]
            out[scenario][key] = future.result()
            progress(f"fleet: {done}/{len(futures)} evaluations ({scenario}: {key})")
    return {s: {key: out[s][key] for key in keys[s]} for s in SCENARIOS}  # one process's order


def _longest_first(job: tuple[str, str]) -> tuple[bool, int]:
    """The order the pool takes a (scenario, key) evaluation in: the genie's first, the largest
    fleet first (minutes each; the rest take seconds), so that the run does not end on one long
    evaluation with the other cores idle."""
    size, name = job[1].split(" ", 1)  # "D<d> <policy>"
    return name != "genie", -int(size[1:])


_FOLDERS: Folders | None = None  # a worker process's folders (_worker_folders)


def _worker_folders(folders: Folders) -> None:
    """A worker process's initializer: the folders every one of its evaluations reads."""
    global _FOLDERS
    _FOLDERS = folders


@functools.cache
def _worker_jobs(scenario: str) -> dict[str, Job]:
    """``scenario``'s jobs in a worker process, by key: its policies are loaded once per process,
    not once for each of its 25 evaluations."""
    assert _FOLDERS is not None
    jobs = {job[0]: job for job in _fleet_jobs(scenario, *_FOLDERS)}
    for _, policy, *_ in jobs.values():
        if isinstance(policy, GeniePolicy):
            # the pool's processes fill the cores: the genie's planning threads would only contend
            # for the GIL (benchmarks/genie_cost.py: two threads cost 1.15-1.25x one thread's CPU)
            policy.workers = 1
    return jobs


def _evaluate_one(scenario: str, key: str, episodes: int, seed: int) -> EvalResult:
    """The evaluation ``key`` of ``scenario``'s jobs, in a worker process."""
    _, policy, cfg, _, record = _worker_jobs(scenario)[key]
    return evaluate_policy(policy, cfg, episodes, seed, record_trajectory=record)


Job = tuple[str, Policy, EnvConfig, Path | None, bool]  # key, policy, env, folder, trajectory?


def _fleet_jobs(
    scenario: str,
    fleet_folder: Path,
    single_folder: Path,
    on_spatial: EnvOverrides,
    per_size_folder: Path | None,
) -> list[Job]:
    """The evaluations of one scenario, D by D: the baselines, then the policies flying that D."""
    # the fleet and per-size policies fly one world (load_with_env refuses two)
    folders = [fleet_folder] + ([per_size_folder] if per_size_folder is not None else [])
    (fleet, fleet_cfg), *sized = load_with_env(folders, on_spatial.on(scenario))
    ((single, single_cfg),) = load_with_env([single_folder], on_spatial.on(scenario))
    flown = sizes_flown(fleet, fleet_cfg)
    if not flown:
        raise UserError(
            f"--fleet {fleet_folder}: its {scenario} policy flies no fleet of "
            f"{FLEET_SIZES[1]} to {FLEET_SIZES[-1]} UAVs (n_uavs={fleet_cfg.n_uavs})"
        )
    plotted = PLOT_UAVS if PLOT_UAVS in flown else flown[0]
    policies = [(ppo(d), fleet, fleet_cfg, fleet_folder, d) for d in flown]
    if per_size_folder is not None:
        policies += [
            (per_size(d), policy, cfg, per_size_folder, d)
            for policy, cfg in sized
            for d in sizes_flown(policy, cfg)
        ]
    policies.append((SINGLE_PPO, single, single_cfg, single_folder, 1))
    # The baselines' world: fleets of any size, one UAV, and no memory of place (what a policy's
    # layout keeps changes what it observes, not the episodes; no baseline here reads it).
    world = fleet_cfg.replace(fleet_slots=0, place_cell_m=0.0, place_model=PLACE_CELLS)
    jobs: list[Job] = []
    for d in FLEET_SIZES:
        cfg = world.replace(n_uavs=d).validate()
        jobs += [(f"D{d} {b}", make_baseline(b, cfg), cfg, None, False) for b in FLEET_BASELINES]
        jobs += [
            (key, policy, own.replace(n_uavs=d).validate(), source, key == ppo(plotted))
            for key, policy, own, source, size in policies
            if size == d
        ]
    return jobs


def _listening(fleet_folder: Path, scenarios: Iterable[str], overrides: EnvOverrides) -> list[str]:
    """The scenarios whose fleet policy, and so its baselines, flies a listening fleet: its env
    loaded as the evaluations load it (the folder's file for the scenario, .zip or .onnx, and the
    overrides)."""
    on_spatial = spatial_overrides(overrides)
    return [
        s
        for s in scenarios
        if load_with_env([fleet_folder], on_spatial.on(s))[0][1].fleet_reuse == REUSE_LISTEN
    ]


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
    run: ReportRun,
    fleet_folder: Path,
    single_folder: Path,
    half_width_m: float,
    per_size_folder: Path | None = None,
) -> list[str]:
    """Evaluate, write the CSVs and plots into ``run.out`` and return the Markdown of the fleet part."""
    rows = evaluate_fleet(
        fleet_folder,
        single_folder,
        run.episodes,
        run.seed,
        run.overrides,
        run.progress,
        per_size_folder,
        run.workers,
    )
    return fleet_markdown(run, rows, fleet_folder, single_folder, half_width_m, per_size_folder)


def fleet_markdown(
    run: ReportRun,
    rows: Rows,
    fleet_folder: Path,
    single_folder: Path,
    half_width_m: float,
    per_size_folder: Path | None = None,
) -> list[str]:
    """Write the CSVs and plots of ``rows`` (``evaluate_fleet``'s) into ``run.out`` and return the
    Markdown of the fleet part."""
    out, rel = run.out, run.rel
    sizes = fleet_sizes(rows)
    throughput = throughput_table(rows)
    ratios = {d: ratio_table(rows, d) for d in sizes}
    metrics = {d: metrics_table(rows, d) for d in sizes}
    write_csv(out / "fleet_throughput.csv", *throughput)
    write_csv(out / "fleet_ratios.csv", *by_size(ratios))
    write_csv(out / "fleet_metrics.csv", *by_size(metrics))
    plotted = {}
    for scenario, r in rows.items():
        key = next(k for k in map(ppo, sizes) if k in r and r[k].trajectory is not None)
        plotted[scenario] = key
        path = out / f"fleet_trajectory_{scenario}.png"
        plot_fleet_trajectory(scenario, r[key], half_width_m, path)
    first = next(iter(rows.values()))
    n = len(first[f"D{FLEET_SIZES[0]} {FLEET_BASELINES[0]}"].episode_rate_mbps)
    per_size_sizes = sorted({d for r in rows.values() for d in FLEET_SIZES if per_size(d) in r})
    kind = (
        f"one policy for every fleet size, flown at D = {', '.join(map(str, sizes))}"
        if len(sizes) > 1
        else f"a policy for a fleet of {sizes[0]}"
    )
    per_size_text = (
        " "
        + ", ".join(f"`{per_size(d)}`" for d in per_size_sizes)
        + f" is `{per_size_folder}/<scenario>.zip`, the policy trained for that fleet size alone."
        if per_size_sizes
        else " No per-size policies (`--fleet-per-size`): the per-size bar is not judged."
    )
    listening = _listening(fleet_folder, rows, run.overrides)
    listening_text = (
        f" {', '.join(listening)} {'flies' if len(listening) == 1 else 'fly'} a listening fleet, "
        "its fleet policy and its baselines alike: one UAV serves every UE, the others take none "
        "and only listen."
        if listening
        else ""
    )
    text = [
        "## A fleet of UAVs (spatial channel)",
        "",
        f"Mean UE throughput (Mbps) over {n} episodes (seed {run.seed}) on the spatial channel, D UAVs "
        f'sharing the band with full reuse (SPEC "A fleet"); every column flies the same UE '
        f"trajectories.{listening_text} "
        f"`D<d> PPO` (d > 1) is `{fleet_folder}/<scenario>.zip`, {kind};{per_size_text} "
        f"`{SINGLE_PPO}` is the single-UAV spatial policy `{single_folder}/<scenario>.zip`. "
        "oracle and kmeans know the UEs' positions (GPS), aoa and PPO do not; genie knows the episode's "
        "future (UE paths, shadowing field) and plans each UAV's path given the others' "
        "(docs/design/baselines.md), the limit.",
        "",
        markdown_table(*throughput),
        "",
        "Per D, the fleet policy's ratios (paired over episodes, 95 % bootstrap interval) and the bars "
        f"set for it: {bars_text(sizes)}. `>=` holds where the interval's upper end is not below the "
        "bar (the episodes do not show PPO below it), `above` where its lower end is above it; `met` "
        "says whether every bar of the row holds and names those that do not. The fleet metrics "
        "below each: Jain's index of the UE rates (mean over frames), the 5th percentile of the UEs' "
        "episode rates, the mean number of UEs the busiest UAV of each frame serves, then the next "
        "busiest (the roles move between UAVs from episode to episode, so a UAV's index would "
        "average them away).",
        "",
    ]
    for d in sizes:
        fairness = genie_fairness(rows, d) or [
            f"At D = {d} the genie's Jain's index is nowhere more than {JAIN_GAP:g} below the PPO's."
        ]
        text += [
            f"**D = {d}**: the fleet policy's ratios.",
            "",
            markdown_table(*ratios[d]),
            "",
            f"Fleet metrics, D = {d}.",
            "",
            markdown_table(*metrics[d]),
            "",
            *(f"- {line}" for line in fairness),
            "",
        ]
    shown = sorted(set(plotted.values()))
    return [
        *text,
        f"The fleet policy's episode 0 per scenario ({', '.join(f'`{key}`' for key in shown)}):",
        "",
        *[f"![{s} fleet]({rel / f'fleet_trajectory_{s}.png'})" for s in rows],
        "",
    ]
