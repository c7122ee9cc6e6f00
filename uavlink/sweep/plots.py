"""A sweep's figures: PPO per setting across seeds beside the baselines, and the learning curves."""

from __future__ import annotations

import math
from pathlib import Path

from uavlink.sweep.rows import SettingRow
from uavlink.sweep.spec import describe_point


def _label(row: SettingRow, grid_keys: list[str]) -> str:
    return row.scenario if not grid_keys else f"{row.scenario}\n{describe_point(row.point)}"


def plot_throughput(rows: list[SettingRow], grid_keys: list[str], path: Path) -> None:
    """PPO mean per setting with the across-seed interval, each seed, and the baselines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(rows) + 2), 4.5))
    for i, row in enumerate(rows):
        mean, hw = row.ppo_interval()
        ax.errorbar(
            i,
            mean,
            yerr=0 if math.isnan(hw) else hw,
            fmt="o",
            color="tab:red",
            capsize=5,
            label="PPO (mean ± 95 % across seeds)" if i == 0 else None,
        )
        ax.scatter(
            [i + 0.12] * row.n,
            row.column("ppo"),
            s=10,
            color="tab:red",
            alpha=0.4,
            label="PPO seeds" if i == 0 else None,
        )
        for name, color, marker in (
            ("static", "tab:gray", "_"),
            ("aoa", "tab:blue", "x"),
            ("oracle", "tab:green", "^"),
        ):
            ax.scatter(
                [i - 0.15],
                [row.baseline(name)],
                color=color,
                marker=marker,
                s=60,
                label=name if i == 0 else None,
            )
    ax.set_xticks(
        range(len(rows)),
        [_label(r, grid_keys) for r in rows],
        fontsize=8,
        rotation=0 if len(rows) <= 6 else 30,
    )
    ax.set_ylabel("average UE throughput (Mbps)")
    ax.set_title("Throughput per setting")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_learning_curves(
    rows: list[SettingRow], grid_keys: list[str], path: Path, max_panels: int = 12
) -> None:
    """Training-episode throughput against env steps, one panel per setting, one line per seed; where
    a job kept its best weights on validation episodes (``train.validation_episodes``), that
    deterministic curve dashed in the seed's colour and the kept point starred."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = rows[:max_panels]
    cols = min(3, len(shown))
    lines = math.ceil(len(shown) / cols)
    fig, axes = plt.subplots(
        lines, cols, figsize=(4.2 * cols, 3.0 * lines), squeeze=False, sharey=True
    )
    for ax, row in zip(axes.flat, shown, strict=False):
        for result in row.results:
            curve = result["training"]["learning_curve"]
            color = None
            if curve:
                (line,) = ax.plot(
                    [s for s, _ in curve],
                    [r for _, r in curve],
                    lw=0.9,
                    label=f"seed {result['seed']}",
                )
                color = line.get_color()
            validation = result["training"].get("validation")  # records before it have none
            if validation:
                ax.plot(
                    *zip(*validation["curve"], strict=True),
                    ls="--",
                    lw=0.8,
                    color=color,
                    label=f"seed {result['seed']}, validation",
                )
                ax.plot(
                    validation["kept_steps"], validation["kept_mbps"], marker="*", ms=8, color=color
                )
        ax.set_title(_label(row, grid_keys).replace("\n", ", "), fontsize=8)
        ax.set_xlabel("env steps", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    axes[0][0].set_ylabel("training episode throughput (Mbps)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
