"""User mistakes and missing optional packages end in one line and exit 2, with nothing written:
real child processes of the CLI, the missing package made absent as Python sees an uninstalled one."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from support.cli import ROOT, assert_user_error, run_uavlink_in_process


def _without(modules: tuple[str, ...], *args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """``uavlink ARGS`` in a child where importing any of ``modules`` fails as if it were not installed."""
    code = (
        "import sys\n"
        f"for name in {modules!r}: sys.modules[name] = None\n"
        "from uavlink.cli import main\n"
        f"sys.exit(main({list(args)!r}))\n"
    )
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=cwd
    )


@pytest.mark.parametrize(
    ("modules", "args", "extra"),
    [
        (
            ("torch", "stable_baselines3"),
            ("evaluate", "--policy", "lone/circular.zip", "--episodes", "1"),  # no ONNX twin
            "train",
        ),
        (
            ("torch", "stable_baselines3", "onnxruntime"),
            (
                "evaluate",
                "--policy",
                "policies/circular.zip",
                "--episodes",
                "1",
            ),  # a twin, no runtime
            "train",
        ),
        (("stable_baselines3",), ("train", "--out", "never.zip", "--episodes", "1"), "train"),
        (("onnx",), ("export", "policies/circular.zip", "--out", "never.onnx"), "export"),
    ],
)
def test_a_missing_optional_package_names_its_extra(modules, args, extra, tmp_path):
    lone = tmp_path / "lone"
    lone.mkdir()
    shutil.copy(ROOT / "policies" / "circular.zip", lone)
    proc = _without(
        modules,
        *(str(ROOT / a) if a.startswith("policies/") else a for a in args),
        *(["--scenario", "circular"] if "lone/circular.zip" in args else []),
        cwd=tmp_path,
    )
    assert_user_error(proc, f"this needs {modules[0]}", f"pip install 'uavlink[{extra}]'")
    assert [p.name for p in tmp_path.iterdir()] == ["lone"]  # nothing written


def test_a_shipped_zip_flies_as_its_onnx_twin_without_torch(tmp_path):
    """The [fly] install has no torch: a shipped zip is evaluated through its ONNX twin and gives
    the figures the zip gives in stable-baselines3 (here a copy of it with no twin beside it) to
    the last digit."""
    args = ("--episodes", "2", "--seed", "3", "--scenario", "circular", "--json")
    proc = _without(
        ("torch", "stable_baselines3"), "evaluate", "--policy", "circular.zip", *args, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    lone = tmp_path / "lone"
    lone.mkdir()
    shutil.copy(ROOT / "policies" / "circular.zip", lone)
    with_torch = run_uavlink_in_process("evaluate", "--policy", str(lone / "circular.zip"), *args)
    assert with_torch.returncode == 0, with_torch.stderr
    twin, zipped = json.loads(proc.stdout), json.loads(with_torch.stdout)
    assert twin["mean_rate_mbps"] == zipped["mean_rate_mbps"]
    assert twin["mean_fair_rate"] == zipped["mean_fair_rate"]


def test_a_twin_exported_from_other_bytes_is_refused_without_torch(tmp_path):
    """A zip beside an ONNX twin of another policy (a retrained zip, its old twin left beside it):
    without stable-baselines3 the zip cannot run, and the twin is not flown in its place."""
    shutil.copy(ROOT / "policies" / "circular.zip", tmp_path / "circular.zip")
    shutil.copy(ROOT / "policies" / "straight.onnx", tmp_path / "circular.onnx")
    proc = _without(
        ("torch", "stable_baselines3"),
        "evaluate",
        "--policy",
        str(tmp_path / "circular.zip"),
        "--episodes",
        "1",
    )
    assert_user_error(proc, "was exported from another version", "uavlink export")


def test_the_results_folder_needs_matplotlib_before_it_writes_a_table(tmp_path):
    out = tmp_path / "results"
    proc = _without(
        ("matplotlib",),
        "evaluate",
        "--policy",
        str(ROOT / "policies"),
        "--scenario",
        "all",
        "--episodes",
        "2",
        "--out",
        str(out),
    )
    assert_user_error(proc, "this needs matplotlib", "uavlink[plot]")
    assert not out.exists()


@pytest.mark.parametrize(
    "args",
    [
        ("evaluate", "--policy", "static", "--seed", "-1"),
        ("export", "policies/circular.zip", "--out", "never.onnx", "--seed", "-1"),
    ],
)
def test_a_negative_seed_is_refused_in_one_line(args):
    assert_user_error(
        run_uavlink_in_process(*args), "a seed must be an integer in 0..2147483647, got -1"
    )


def test_an_argparse_error_is_one_line_too():
    assert_user_error(
        run_uavlink_in_process("evaluate", "--episodes", "abc"),
        "argument --episodes: invalid int value: 'abc'",
        "see uavlink evaluate --help",
    )


def test_an_unknown_option_is_the_commands_error():
    """Before, the top-level parser said it: `uavlink: error: unrecognized arguments: --bogus (see
    uavlink --help)`, pointing away from the command's own help."""
    assert_user_error(
        run_uavlink_in_process("fly", "--bogus"),
        "uavlink fly: error: unrecognized arguments: --bogus",
        "see uavlink fly --help",
    )


def test_report_options_without_out_are_refused():
    assert_user_error(
        run_uavlink_in_process(
            "evaluate", "--policy", "static", "--markdown", "x.md", "--map", "m"
        ),
        "--markdown, --map go with --out FOLDER",
    )


def test_resume_from_a_file_that_is_no_checkpoint_leaves_no_run_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    garbage = tmp_path / "garbage.zip"
    garbage.write_text("not a zip")
    assert_user_error(
        run_uavlink_in_process(
            "train", "--out", "e.zip", "--episodes", "2", "--resume", str(garbage)
        ),
        "not a checkpoint",
    )
    assert_user_error(
        run_uavlink_in_process(
            "train",
            "--out",
            "e.zip",
            "--episodes",
            "2",
            "--start-from",
            str(tmp_path / "missing.zip"),
        ),
        "missing.zip",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.zip"]


def test_a_malformed_scheduler_address_fails_at_once_and_writes_nothing(tmp_path):
    pytest.importorskip("distributed")
    out_root = tmp_path / "runs"
    assert_user_error(
        run_uavlink_in_process(
            "sweep",
            str(ROOT / "sweeps" / "tiny.toml"),
            "--scheduler",
            "bogus",
            "--out-root",
            str(out_root),
        ),
        "'bogus' is not a Dask address",
    )
    assert not out_root.exists()


@pytest.mark.slow
@pytest.mark.waits  # 20 s of Dask's connect timeout, no CPU
def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path):
    pytest.importorskip("distributed")
    import socket

    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out_root = tmp_path / "runs"
    assert_user_error(
        run_uavlink_in_process(
            "sweep",
            str(ROOT / "sweeps" / "tiny.toml"),
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
            "--out-root",
            str(out_root),
        ),
        "cannot reach the Dask scheduler",
    )
    assert not out_root.exists()


def test_each_optional_module_names_an_extra_that_installs_it():
    import tomllib

    from uavlink.errors import EXTRA_OF_MODULE

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]

    def installs(extra: str) -> str:  # an extra's requirements, with those of the extras it names
        return " ".join(installs(r[8:-1]) if r.startswith("uavlink[") else r for r in extras[extra])

    for module, extra in EXTRA_OF_MODULE.items():
        package = {"stable_baselines3": "stable-baselines3", "dask": "distributed"}.get(
            module, module
        )  # dask: by distributed
        assert re.search(rf"(^|\s){re.escape(package)}\b", installs(extra)), (module, extra)
