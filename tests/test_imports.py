"""`import uavlink` stays light: the simulator, env, baselines and CLI need no heavy dependency."""

from __future__ import annotations

import subprocess
import sys

HEAVY = (
    "torch",
    "stable_baselines3",
    "pymavlink",
    "onnxruntime",
    "matplotlib",
    "dask",
    "distributed",
)


def test_core_imports_no_heavy_modules() -> None:
    code = (
        "import sys, uavlink, uavlink.cli, uavlink.env, uavlink.radio, uavlink.mobility, "
        "uavlink.policies, uavlink.evaluation, uavlink.evaluation.report, uavlink.policies.loader, "
        "uavlink.policies.registry, uavlink.learn\n"
        f"print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert out.stdout.strip() == ""


def test_evaluate_baseline_runs_without_heavy_modules() -> None:
    code = (
        "import sys\n"
        "from uavlink.cli import main\n"
        "rc = main(['evaluate', '--policy', 'aoa', '--episodes', '2', '--json'])\n"
        f"print('HEAVY=' + ','.join(m for m in {HEAVY!r} if m in sys.modules))\n"
        "sys.exit(rc)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("HEAVY=")
