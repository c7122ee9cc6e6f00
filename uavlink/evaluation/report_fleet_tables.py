"""The fleet part's tables (``report_fleet`` evaluates, this module lays out): the throughput of every
(D, baseline) and of the policies, per D the fleet policy's paired ratios against kmeans, the genie,
the aoa rule and the per-size policy with the issue's bars judged, per D the fleet metrics, and the
sentences that name where the genie buys throughput with fairness.

Results are keyed by column: ``"D<d> <baseline>"``, ``"D<d> PPO"`` (the fleet policy; ``"D1 PPO"``
is one UAV's spatial policy) and ``"D<d> PPO (per size)"`` (the policy trained for that D alone).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from uavlink.evaluation.core import EvalResult, paired_ratio_ci

FLEET_BASELINES = ("static", "oracle", "aoa", "kmeans", "genie")
FLEET_SIZES = (1, 2, 3, 4)  # every baseline flies each
SINGLE_PPO = "D1 PPO"  # one UAV's spatial policy
# The bars set for the fleet policy (the issue's): PPO >= kmeans at every D, above it where the UEs
# split or spread at these D; PPO / genie >= GENIE_SHARE at these D; PPO >= the per-size policy.
ABOVE_KMEANS = ("straight_90", "straight_180", "hotspot")
ABOVE_KMEANS_SIZES = (2, 3)
GENIE_SHARE, GENIE_SIZES = 0.6, (2, 3)
# Where the genie's Jain's index falls this far below the PPO's, a sentence says so.
JAIN_GAP = 0.1

Rows = dict[str, dict[str, EvalResult]]  # per scenario, results by column
Table = tuple[list[str], list[list[str]]]


def ppo(d: int) -> str:
    return f"D{d} PPO"


def per_size(d: int) -> str:
    return f"D{d} PPO (per size)"


def fleet_sizes(rows: Rows) -> list[int]:
    """The fleet sizes (D > 1) the fleet policy flew in some scenario."""
    return [d for d in FLEET_SIZES if d > 1 and any(ppo(d) in r for r in rows.values())]


@dataclass(frozen=True)
class Bar:
    """PPO / ``against`` must reach ``level``: ``above``, the 95 % interval's lower end is above it;
    otherwise (">=") its upper end is not below it (the data do not say PPO is worse)."""

    against: str
    level: float
    above: bool = False

    def met(self, ratio: tuple[float, float, float]) -> bool:
        _, lo, hi = ratio
        return lo > self.level if self.above else hi >= self.level

    def describe(self) -> str:
        return f"vs {self.against} {'above' if self.above else '>='} {self.level:g}"


def bars(scenario: str, d: int, with_per_size: bool) -> list[Bar]:
    """The bars the fleet policy is held to on ``scenario`` at D = ``d``."""
    out = [Bar("kmeans", 1.0, above=d in ABOVE_KMEANS_SIZES and scenario in ABOVE_KMEANS)]
    if d in GENIE_SIZES:
        out.append(Bar("genie", GENIE_SHARE))
    if with_per_size:
        out.append(Bar("per size", 1.0))
    return out


def bars_text(sizes: Iterable[int]) -> str:
    """The bars in words, for the sizes the fleet policy flew (the report's paragraph)."""
    above = [d for d in ABOVE_KMEANS_SIZES if d in sizes]
    genie = [d for d in GENIE_SIZES if d in sizes]

    def at(ds: list[int]) -> str:
        return " and ".join(str(d) for d in ds)

    text = "PPO >= kmeans at every D"
    if above:
        text += f", above it on {', '.join(ABOVE_KMEANS)} at D = {at(above)}"
    if genie:
        text += f"; PPO / genie >= {GENIE_SHARE:g} at D = {at(genie)}"
    return text + "; PPO >= the per-size policy at its D"


def ratio(a: EvalResult, b: EvalResult) -> tuple[float, float, float]:
    return paired_ratio_ci(a.episode_rate_mbps, b.episode_rate_mbps)


def _fmt(r: tuple[float, float, float]) -> str:
    return f"{r[0]:.3f} [{r[1]:.3f}, {r[2]:.3f}]"


def throughput_table(rows: Rows) -> Table:
    """Per scenario, every (D, baseline) and each policy after the baselines of its D."""
    present = {key for r in rows.values() for key in r}
    columns = []
    for d in FLEET_SIZES:
        columns += [f"D{d} {b}" for b in FLEET_BASELINES]
        columns += [key for key in (ppo(d), per_size(d)) if key in present]
    body = [
        [s, *(f"{r[c].mean_rate_mbps:.2f}" if c in r else "—" for c in columns)]
        for s, r in rows.items()
    ]
    return ["scenario", *columns], body


def ratio_table(rows: Rows, d: int) -> Table:
    """At D = ``d``, per scenario the fleet policy flies it: PPO / kmeans, genie, aoa (and the
    per-size policy), each paired with its 95 % interval, the bars and whether all are met."""
    with_per_size = any(per_size(d) in r for r in rows.values())
    header = ["scenario", "PPO / kmeans", "PPO / genie", "PPO / aoa"]
    header += [f"PPO / {per_size(d)}"] if with_per_size else []
    body = []
    for scenario, r in rows.items():
        if ppo(d) not in r:
            continue
        mine = r[ppo(d)]
        against = {name: ratio(mine, r[f"D{d} {name}"]) for name in ("kmeans", "genie", "aoa")}
        if per_size(d) in r:
            against["per size"] = ratio(mine, r[per_size(d)])
        held = bars(scenario, d, per_size(d) in r)
        failed = [bar.describe() for bar in held if not bar.met(against[bar.against])]
        body.append(
            [
                scenario,
                *(_fmt(against[name]) for name in ("kmeans", "genie", "aoa")),
                *([_fmt(against["per size"]) if "per size" in against else "—"] * with_per_size),
                ", ".join(bar.describe() for bar in held),
                "yes" if not failed else f"no ({', '.join(failed)})",
            ]
        )
    return [*header, "bars", "met"], body


def metrics_table(rows: Rows, d: int) -> Table:
    """At D = ``d``: the fleet metrics of the fleet policy, the per-size one and every baseline."""
    header = [
        "scenario",
        "policy",
        "Mbps",
        "R_fair",
        "Jain",
        "5th pct UE Mbps",
        "UEs per UAV, busiest first",
    ]
    body = []
    for scenario, r in rows.items():
        keys = [ppo(d), per_size(d), *(f"D{d} {b}" for b in FLEET_BASELINES)]
        for key in (k for k in keys if k in r):
            x = r[key]
            body.append(
                [
                    scenario,
                    key.split(" ", 1)[1],
                    f"{x.mean_rate_mbps:.2f}",
                    f"{x.mean_fair_rate:.2f}",
                    f"{x.jain_index:.3f}",
                    f"{x.p5_ue_rate_mbps:.2f}",
                    " / ".join(f"{n:.1f}" for n in x.ues_per_uav),
                ]
            )
    return header, body


def genie_fairness(rows: Rows, d: int) -> list[str]:
    """One sentence per scenario where, at D = ``d``, the genie's Jain's index falls more than
    ``JAIN_GAP`` below the fleet policy's: the genie buys its throughput with fairness there."""
    return [
        f"The genie buys throughput with fairness on {scenario} at D = {d}: genie Jain "
        f"{r[f'D{d} genie'].jain_index:.2f} vs PPO {r[ppo(d)].jain_index:.2f}."
        for scenario, r in rows.items()
        if ppo(d) in r and r[f"D{d} genie"].jain_index < r[ppo(d)].jain_index - JAIN_GAP
    ]


def by_size(tables: dict[int, Table]) -> Table:
    """Per-D tables as one with a leading D column (the CSVs hold every D in one file): the union of
    their columns, "—" where a D's table lacks one (the per-size ratio beside D = 2 only)."""
    columns = list(dict.fromkeys(c for header, _ in tables.values() for c in header))
    body = [
        [str(d), *(dict(zip(header, row, strict=True)).get(c, "—") for c in columns)]
        for d, (header, rows) in tables.items()
        for row in rows
    ]
    return ["D", *columns], body
