"""The fleet part of the results report: its tables and plot from real (small) evaluations."""

from __future__ import annotations

import pytest

from uavlink.config import EnvConfig
from uavlink.evaluation import evaluate_policy
from uavlink.evaluation.report_fleet import (
    FLEET_BASELINES,
    FLEET_SIZES,
    metrics_table,
    plot_fleet_trajectory,
    ratio_table,
    throughput_table,
)
from uavlink.policies.genie import REFERENCES, GeniePolicy
from uavlink.policies.registry import make_baseline


@pytest.fixture(scope="module")
def rows():
    out = {}
    for scenario in ("no_move", "straight_180"):
        results = {}
        for d in FLEET_SIZES:
            cfg = EnvConfig(scenario=scenario, n_uavs=d, episode_frames=8)
            for name in FLEET_BASELINES:
                # The genie on a 10 m grid: these tests read the tables' shape, not the limit's value.
                policy = (
                    GeniePolicy(cfg, [make_baseline(r, cfg) for r in REFERENCES], grid_m=10.0)
                    if name == "genie"
                    else make_baseline(name, cfg)
                )
                results[f"D{d} {name}"] = evaluate_policy(policy, cfg, 3, 0, record_trajectory=True)
        results["D2 ppo"], results["D1 ppo"] = results["D2 kmeans"], results["D1 aoa"]  # stand-ins
        out[scenario] = results
    return out


def test_tables_hold_every_column_and_judge_the_bars(rows):
    header, body = throughput_table(rows)
    assert header[:7] == [
        "scenario",
        "D1 static",
        "D1 oracle",
        "D1 aoa",
        "D1 kmeans",
        "D1 genie",
        "D1 PPO",
    ]
    assert (
        len(header) == 1 + 3 * len(FLEET_BASELINES) + 2 and len(body) == 2 and "D3 genie" in header
    )
    assert (
        body[1][header.index("D2 PPO")] == f"{rows['straight_180']['D2 kmeans'].mean_rate_mbps:.2f}"
    )
    header, body = ratio_table(rows)
    no_move, s180 = body
    assert "vs one UAV >= 0.98" in no_move[4] and "vs oracle" not in no_move[4]
    assert "vs oracle >= 0.95" in s180[4] and "vs one UAV >= 1.6" in s180[4]
    ratio = float(s180[3].split()[0])  # kmeans D = 2 against the aoa rule with one UAV
    assert s180[5] == (
        "yes"
        if ratio >= 1.6 and float(s180[1].split()[0]) >= 0.95 and float(s180[2].split()[0]) >= 1.0
        else "no"
    )
    assert header[-1] == "PPO / genie" and float(s180[-1].split()[0]) > 0.0
    header, body = metrics_table(rows)
    assert len(body) == 2 * (1 + len(FLEET_BASELINES)) and body[0][1] == "PPO"
    assert all(len(row[6].split(" / ")) == 2 for row in body)  # UEs per UAV, D = 2


@pytest.mark.slow  # 1.8 s: matplotlib
def test_fleet_trajectory_plot_is_written(rows, tmp_path):
    path = tmp_path / "fleet.png"
    plot_fleet_trajectory("straight_180", rows["straight_180"]["D2 kmeans"], 200.0, path)
    assert path.stat().st_size > 10_000
