"""Per-setting summary of a sweep: mean across seeds with a t interval, gain over static, share of
oracle, wall time; Markdown, CSV and plots in ``runs/<sweep>/``; the median seed's policies and,
beside them, the sweep's record (every job's figures) from which docs/results.md's across-seed table
is rebuilt where ``runs/`` is gone (a fresh clone).

A setting is a scenario x grid point; its seeds are independent training runs evaluated on the same
episodes (same evaluation seed), so the interval is across seeds: mean +- t(0.975, n-1) s / sqrt(n).
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Collection
from pathlib import Path
from typing import Any

from uavlink.errors import UserError
from uavlink.evaluation.tables import markdown_table, write_csv
from uavlink.sweep.jobs import RUN_FIELDS, read_result, result_path
from uavlink.sweep.plots import plot_learning_curves, plot_throughput
from uavlink.sweep.rows import SettingRow
from uavlink.sweep.spec import Job, SweepSpec, describe_point

RECORD_FORMAT = "uavlink-sweep-record-v1"


def record_path(policies_dir: Path, spec: SweepSpec) -> Path:
    """Where ``--policies-out DIR`` keeps the sweep's record: ``DIR/<sweep name>.sweep.json``."""
    return policies_dir / f"{spec.name}.sweep.json"


def _record_entry(result: dict[str, Any]) -> dict[str, Any]:
    """A job's figures as the across-seed table and its plots use them: no policy bytes, no
    per-episode lists, of the run fields only the wall time."""
    entry = {k: v for k, v in result.items() if k not in (*RUN_FIELDS, "policy_zip", "evaluation")}
    entry["evaluation"] = {
        policy: {k: v for k, v in figures.items() if not isinstance(v, list)}
        for policy, figures in result["evaluation"].items()
    }
    entry["timing"] = {"job_s": result["timing"]["job_s"]}
    return entry


def write_record(rows: list[SettingRow], spec: SweepSpec, path: Path) -> None:
    """Write the record of a sweep's finished jobs, atomically."""
    payload = {
        "format": RECORD_FORMAT,
        "sweep": spec.name,
        "jobs": [_record_entry(result) for row in rows for result in row.results],
    }
    tmp = path.with_name(f".{path.name}.partial")
    tmp.write_text(json.dumps(payload, indent=1, sort_keys=True) + "\n")
    tmp.replace(path)


def read_record(path: Path) -> dict[str, dict[str, Any]]:
    """A sweep record's jobs by job key; empty when there is no record."""
    try:
        payload = json.loads(path.read_text())
    except FileNotFoundError:
        return {}
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"{path}: not a readable sweep record ({exc})") from None
    if payload.get("format") != RECORD_FORMAT:
        raise UserError(
            f"{path}: not a sweep record (format {payload.get('format')!r}, expected {RECORD_FORMAT!r})"
        )
    return {job["key"]: job for job in payload["jobs"]}


def collect(
    spec: SweepSpec, sweep_dir: Path, record: dict[str, dict[str, Any]] | None = None
) -> list[SettingRow]:
    """Settings in the sweep file's order, each with the finished results of its jobs: from
    ``sweep_dir``, else from ``record`` (``read_record``; a job's key names its settings, so a
    recipe changed since the record was written finds no figures there)."""
    rows: dict[Any, SettingRow] = {}
    for job in spec.jobs():
        row = rows.setdefault(job.setting, SettingRow(job.scenario, job.point, len(spec.seeds)))
        result = read_result(sweep_dir, job) or (record or {}).get(job.key)
        if result is not None:
            row.results.append(result)
    return list(rows.values())


def summary_table(
    rows: list[SettingRow], grid_keys: list[str]
) -> tuple[list[str], list[list[str]]]:
    names = [k.split(".", 1)[1] for k in grid_keys]
    header = [
        "scenario",
        *names,
        "seeds",
        "PPO (Mbps)",
        "PPO seed range",
        "static",
        "oracle",
        "aoa",
        "gain over static",
        "PPO / oracle",
        "wall / job",
        "median seed",
    ]
    body = []
    for row in rows:
        if not row.n:
            body.append(
                [
                    row.scenario,
                    *[_cell(row.point[k]) for k in grid_keys],
                    f"0/{row.expected_seeds}",
                    *["—"] * (len(header) - 2 - len(names)),
                ]
            )
            continue
        x = row.numbers()
        hw = "n/a" if math.isnan(x["ppo_ci95_mbps"]) else f"{x['ppo_ci95_mbps']:.2f}"
        gain = f"{x['gain_pct']:+.1f} %"
        share = f"{x['oracle_share_pct']:.1f} %"
        if not math.isnan(x["ppo_ci95_mbps"]):
            gain += f" [{x['gain_lo_pct']:+.1f}, {x['gain_hi_pct']:+.1f}]"
            share += f" [{x['oracle_share_lo_pct']:.1f}, {x['oracle_share_hi_pct']:.1f}]"
        body.append(
            [
                row.scenario,
                *[_cell(row.point[k]) for k in grid_keys],
                f"{row.n}/{row.expected_seeds}",
                f"{x['ppo_mbps']:.2f} ± {hw}",
                f"{x['ppo_min_mbps']:.2f}–{x['ppo_max_mbps']:.2f}",
                f"{x['static_mbps']:.2f}",
                f"{x['oracle_mbps']:.2f}",
                f"{x['aoa_mbps']:.2f}",
                gain,
                share,
                _duration(x["wall_s_mean"]),
                str(x["median_seed"]),
            ]
        )
    return header, body


def write_summary(
    spec: SweepSpec,
    sweep_dir: Path,
    command: str = "",
    record: dict[str, dict[str, Any]] | None = None,
) -> tuple[Path, str]:
    """Write summary.md, summary.csv, throughput.png and learning_curves.png of the jobs in
    ``sweep_dir`` and ``record`` (see ``collect``); returns (md, table)."""
    rows = collect(spec, sweep_dir, record)
    grid_keys = list(spec.grid)
    header, body = summary_table(rows, grid_keys)
    finished = [r for r in rows if r.n]
    numeric = [r.numbers() for r in finished]
    if numeric:
        keys = list(numeric[0])
        write_csv(sweep_dir / "summary.csv", keys, [[_csv(x[k]) for k in keys] for x in numeric])
        plot_throughput(finished, grid_keys, sweep_dir / "throughput.png")
        plot_learning_curves(finished, grid_keys, sweep_dir / "learning_curves.png")
    table = markdown_table(header, body)
    done = sum(r.n for r in rows)
    total = len(spec.jobs())
    text = [
        f"# Sweep `{spec.name}`",
        "",
        *([spec.description, ""] if spec.description else []),
        f"{done} of {total} jobs finished" + (f"; made by `{command}`" if command else "") + ".",
        f"Each job trains PPO for {training_episodes(spec)} episodes and evaluates PPO, "
        f"static, oracle and aoa on the same {spec.eval['episodes']} episodes (evaluation seed "
        f"{spec.eval['seed']}). PPO is the mean over training seeds ± the 95 % Student-t interval "
        "across seeds; gain and oracle share carry the same interval. The median seed is the seed "
        "whose PPO throughput is the median (the lower of the middle two for an even count).",
        "",
        table,
        "",
        *(
            [
                "![throughput per setting](throughput.png)",
                "",
                "![learning curves](learning_curves.png)",
                "",
            ]
            if numeric
            else []
        ),
    ]
    path = sweep_dir / "summary.md"
    path.write_text("\n".join(text))
    clean = [
        {k: None if isinstance(v, float) and math.isnan(v) else v for k, v in x.items()}
        for x in numeric
    ]
    (sweep_dir / "summary.json").write_text(json.dumps(clean, indent=1) + "\n")
    return path, table


def training_episodes(spec: SweepSpec) -> str:
    """The jobs' training episodes: one figure, or the range where recipes differ."""
    counts = sorted({job.train.episodes for job in spec.jobs()})
    return f"{counts[0]:,}" if len(counts) == 1 else f"{counts[0]:,} to {counts[-1]:,}"


def finished_rows(
    spec: SweepSpec, sweep_dir: Path, record: dict[str, dict[str, Any]] | None = None
) -> list[SettingRow]:
    """The sweep's rows (see ``collect``); a UserError naming the unfinished scenarios if any job is missing."""
    rows = collect(spec, sweep_dir, record)
    missing = [r.scenario for r in rows if r.n < r.expected_seeds]
    if missing:
        raise UserError(
            f"sweep {spec.name!r} in {sweep_dir} is not finished ({', '.join(missing)}): "
            f"run `uavlink sweep` on it first"
        )
    return rows


def results_section(
    spec: SweepSpec,
    sweep_dir: Path,
    assets: Path,
    link_prefix: Path,
    shipped_to: Path = Path("policies"),
    level: str = "##",
) -> str:
    """Markdown for docs/results.md: the across-seed table of a finished sweep and its figures,
    drawn into ``assets`` as ``sweep_<sweep name>_<figure>`` (linked as ``link_prefix/<file>``, so
    several sweeps share one folder). Its median seeds are shipped to ``shipped_to``; the figures
    come from ``sweep_dir``, else from the record shipped beside them."""
    rows = finished_rows(spec, sweep_dir, read_record(record_path(shipped_to, spec)))
    header, body = summary_table(rows, list(spec.grid))
    assets.mkdir(parents=True, exist_ok=True)
    prefix = f"sweep_{spec.name}_"
    plot_throughput(rows, list(spec.grid), assets / f"{prefix}throughput.png")
    plot_learning_curves(rows, list(spec.grid), assets / f"{prefix}learning_curves.png")
    figures = [
        line
        for name in ("throughput", "learning_curves")
        for line in (f"![{name}]({link_prefix / f'{prefix}{name}.png'})", "")
    ]
    return "\n".join(
        [
            f"{level} Table I across training seeds (sweep `{spec.name}`)",
            "",
            f"`uavlink sweep` of `{spec.name}` ({len(spec.seeds)} seeds per scenario, {training_episodes(spec)} "
            f"training episodes each, evaluation on {spec.eval['episodes']} episodes, seed {spec.eval['seed']}). "
            "PPO is the mean over training seeds ± the 95 % Student-t interval across seeds. "
            + shipped_sentence(rows, spec, shipped_to),
            "",
            markdown_table(header, body),
            "",
            *figures,
        ]
    )


def shipped_sentence(rows: list[SettingRow], spec: SweepSpec, shipped_to: Path) -> str:
    """Which shipped policies are this run's median seeds. A shipped policy's manifest keeps the
    per-seed figures of the run it was chosen from; where they are not this run's (the code moved
    the figures since, and the policies were not re-shipped), the sentence says so."""
    from uavlink.policies.manifest import PolicyFileError, read_zip_manifest

    considered, earlier = 0, []
    for row in rows:
        try:
            selection = read_zip_manifest(shipped_to / f"{row.scenario}.zip").get("selection", {})
        except PolicyFileError:
            continue  # nothing shipped for this scenario
        considered += 1
        shipped = selection.get("seeds_mbps", {}) if selection.get("sweep") == spec.name else {}
        here = {str(r["seed"]): r["evaluation"]["ppo"]["mean_rate_mbps"] for r in row.results}
        if shipped.keys() != here.keys() or any(abs(shipped[k] - here[k]) > 1e-6 for k in here):
            earlier.append(row.scenario)
    where = f"The policies in `{shipped_to}/` (the single-policy table above) are"
    if not earlier:
        return f"{where} each scenario's median seed."
    which = "" if len(earlier) == considered else f" for {', '.join(earlier)}"
    return (
        f"{where} not this run's median seeds{which}: they were chosen from an earlier run of the "
        "sweep whose per-seed throughputs differ from this run's (each manifest's `selection` keeps "
        f"them){'; elsewhere they are' if which else ''}."
    )


def export_median_policies(
    spec: SweepSpec, sweep_dir: Path, dest: Path
) -> list[tuple[str, Path, int]]:
    """Copy each scenario's median-seed policy to ``dest/<scenario>.zip`` (manifest records the
    choice) and write the sweep's record beside them; returns the policies copied.

    Needs one setting per scenario (no grid with several points) and every seed finished, in
    ``sweep_dir`` or in the record already in ``dest``. A scenario whose median job is only in that
    record keeps the policy shipped from it.
    """
    from uavlink.policies.manifest import read_zip_manifest, write_zip_manifest

    if len(spec.points()) > 1:
        raise UserError(
            "--policies-out needs one setting per scenario: this sweep has a grid "
            f"of {len(spec.points())} points"
        )
    rows = collect(spec, sweep_dir, read_record(record_path(dest, spec)))
    missing = [r.scenario for r in rows if r.n < r.expected_seeds]
    if missing:
        raise UserError(
            f"--policies-out: not every seed finished for {', '.join(missing)}; rerun the sweep"
        )
    dest.mkdir(parents=True, exist_ok=True)
    written = []
    for row in rows:
        chosen = row.median_result()
        out = dest / f"{row.scenario}.zip"
        if not (sweep_dir / chosen["name"] / "policy.zip").is_file():
            shipped_key = (
                read_zip_manifest(out).get("selection", {}).get("key") if out.is_file() else None
            )
            if shipped_key != chosen["key"]:
                raise UserError(
                    f"--policies-out: {row.scenario}'s median job {chosen['name']} is in the record "
                    f"but {out} is not its policy; rerun that job (delete {record_path(dest, spec)})"
                )
            continue
        tmp = dest / f".{row.scenario}.zip.partial"
        shutil.copyfile(sweep_dir / chosen["name"] / "policy.zip", tmp)
        manifest = read_zip_manifest(tmp)
        manifest["evaluation"] = {
            row.scenario: {
                k: v for k, v in chosen["evaluation"]["ppo"].items() if k != "episode_rate_mbps"
            }
        }
        manifest["selection"] = {
            "rule": "median seed of the sweep by PPO evaluation throughput",
            "sweep": spec.name,
            "job": chosen["name"],
            "key": chosen["key"],
            "seed": chosen["seed"],
            "seeds_mbps": {
                str(r["seed"]): r["evaluation"]["ppo"]["mean_rate_mbps"] for r in row.results
            },
        }
        write_zip_manifest(tmp, manifest)
        tmp.replace(out)
        tmp.with_suffix(".json").replace(out.with_suffix(".json"))
        written.append((row.scenario, out, chosen["seed"]))
    write_record(rows, spec, record_path(dest, spec))
    return written


def jobs_table(jobs: list[Job], sweep_dir: Path, recorded: Collection[str] = ()) -> str:
    """One line per job with its status (``recorded``: keys of a shipped record's jobs), for --dry-run."""

    def status(job: Job) -> str:
        if result_path(sweep_dir, job).is_file():
            return "done"
        return "done (record)" if job.key in recorded else "to run"

    header = ["job", "scenario", "seed", "point", "status"]
    body = [[j.name, j.scenario, str(j.seed), describe_point(j.point), status(j)] for j in jobs]
    return markdown_table(header, body)


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.1f} s"
    return f"{seconds / 60:.1f} min" if seconds < 3600 else f"{seconds / 3600:.2f} h"


def _cell(value: Any) -> str:
    return describe_point({"x.v": value}).split("=", 1)[1]


def _csv(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else round(value, 6)
    return value
