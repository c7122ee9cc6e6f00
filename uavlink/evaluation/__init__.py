"""Evaluation and the results report (layer: above ``policies``; beside ``learn``, which it never imports).

- ``core``: seeded, batched evaluation of any policy and the paired statistics (ratios with bootstrap
  intervals, episodes won); its names are re-exported here (``from uavlink.evaluation import
  evaluate_policy`` as before the package).
- ``tables``: the report's leaf: per-scenario rows, Table I and II, Markdown and CSV writers.
- ``report``: the results folder (``uavlink evaluate --out``), over its spatial-channel part
  (``report_spatial``) and fleet part (``report_fleet``); the parts import ``tables``, never ``report``
  or each other; the memory-of-place part (``report_map``) draws its pictures with ``place_map``
  (what a map policy remembered, over the true field). Plots import matplotlib inside the function
  that draws.

May import: ``config``, ``errors``, ``mobility``, ``env``, ``seeding``, ``rollout``, ``policies``.
"""

from uavlink.evaluation.core import (
    EvalResult,
    PairedComparison,
    Trajectory,
    compare,
    evaluate_policy,
    paired_ratio_ci,
)

__all__ = [
    "EvalResult",
    "PairedComparison",
    "Trajectory",
    "compare",
    "evaluate_policy",
    "paired_ratio_ci",
]
