"""Where a command writes, checked before it works (uavlink.cli.options.output_folder / output_file):
a file where a folder goes, a folder where a file goes, or a name that is not what the command
writes is one line and exit status 2 before any training, evaluation or flight, and nothing is
written. Before, `train` trained in full and then failed on `--out`, leaving .partial files."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.cli import assert_user_error, run_uavlink_in_process

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def places(tmp_path: Path) -> Path:
    (tmp_path / "afile").write_text("not a folder")
    (tmp_path / "adir").mkdir()
    (tmp_path / "flight.tlog").write_bytes(b"")
    return tmp_path


CASES = [  # (arguments with {t} for the temporary folder, what the one line says)
    ("train --out {t}/adir --episodes 1", "--out {t}/adir is a folder; give a file name"),
    ("train --out {t}/afile/b.zip --episodes 1", "its folder {t}/afile is a file"),
    ("train --out {t}/b.txt --episodes 1", "--out {t}/b.txt must end in .zip"),
    ("train --out {t}/b.zip --run-dir {t}/afile --episodes 1", "--run-dir {t}/afile is a file"),
    (
        "evaluate --scenario all --policy policies/ --episodes 1 --out {t}/afile",
        "--out {t}/afile is a file",
    ),
    (
        "evaluate --scenario all --policy policies/ --episodes 1 --out {t}/res --markdown {t}/adir",
        "--markdown {t}/adir is a folder",
    ),
    ("fly --policy aoa --out {t}/afile", "--out {t}/afile is a file; give a folder"),
    ("fly --policy aoa --out {t}/afile/sub", "--out {t}/afile/sub lies under {t}/afile, a file"),
    ("plot {t}/adir", "{t}/adir is a folder; give a telemetry log"),
    ("plot {t}/flight.tlog --gif --out {t}/a.png", "--out {t}/a.png must end in .gif"),
    ("plot {t}/flight.tlog --out {t}/a.gif", "--out {t}/a.gif must end in .png"),
    ("export policies/circular.zip --out {t}/afile/x.onnx", "its folder {t}/afile is a file"),
    ("export policies/circular.zip --out {t}/x.zip", "--out {t}/x.zip must end in .onnx"),
    ("sweep sweeps/tiny.toml --out-root {t}/afile --workers 0", "--out-root {t}/afile is a file"),
    (
        "sweep sweeps/tiny.toml --policies-out {t}/afile --workers 0",
        "--policies-out {t}/afile is a file",
    ),
    ("keygen --out {t}/adir", "--out {t}/adir is a folder"),
]


@pytest.mark.parametrize(
    "args,fragment", CASES, ids=[c[0].split()[0] + f"-{i}" for i, c in enumerate(CASES)]
)
def test_a_bad_output_path_is_refused_before_any_work(
    places: Path, monkeypatch, args: str, fragment: str
) -> None:
    monkeypatch.chdir(ROOT)  # the shipped policies and sweeps, by the README's relative paths
    before = sorted(places.rglob("*"))
    runs = sorted((ROOT / "runs").glob("b-seed*")) if (ROOT / "runs").exists() else []
    proc = run_uavlink_in_process(*args.format(t=places).split())
    assert_user_error(proc, fragment.format(t=places))
    assert sorted(places.rglob("*")) == before  # nothing made, nothing half-written
    assert (sorted((ROOT / "runs").glob("b-seed*")) if (ROOT / "runs").exists() else []) == runs


@pytest.fixture
def unwritable(tmp_path: Path) -> Path:
    """A folder that takes no new file: read-only by its mode, or /sys where the mode does not bind
    (root)."""
    import os

    if os.geteuid() == 0:
        return Path("/sys")
    folder = tmp_path / "readonly"
    folder.mkdir(mode=0o555)
    return folder


UNWRITABLE_CASES = [  # before, each trained, evaluated or flew in full, then failed with a traceback
    "train --out {t}/sub/b.zip --episodes 1",
    "evaluate --scenario all --policy policies/ --episodes 1 --out {t}/res",
    "export policies/circular.zip --out {t}/c.onnx",
    "fly --policy aoa --out {t}/flight",
    "sweep sweeps/tiny.toml --out-root {t}/sw --workers 0",
]


@pytest.mark.parametrize("args", UNWRITABLE_CASES, ids=[c.split()[0] for c in UNWRITABLE_CASES])
def test_a_folder_that_takes_no_file_is_refused_before_any_work(
    unwritable: Path, monkeypatch, args: str
) -> None:
    monkeypatch.chdir(ROOT)
    before = sorted(unwritable.iterdir())
    proc = run_uavlink_in_process(*args.format(t=unwritable).split())
    assert_user_error(proc, "cannot write there")
    assert sorted(unwritable.iterdir()) == before


def test_export_takes_a_shipped_name_and_writes_here(tmp_path: Path, monkeypatch) -> None:
    """`uavlink export fleet/hotspot` exports the shipped zip to ./hotspot.onnx (not beside the
    shipped file, which may sit in an installed package); a folder is refused as one."""
    monkeypatch.chdir(tmp_path)
    proc = run_uavlink_in_process("export", "fleet/hotspot", "--n-verify", "4")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "hotspot.onnx").is_file()
    assert "policies/fleet/hotspot.zip -> hotspot.onnx" in proc.stdout
    assert_user_error(run_uavlink_in_process("export", "fleet"), "is a folder; give a policy zip")
