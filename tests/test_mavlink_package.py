"""The layering around MAVLink: ``sitl_stub`` and ``uavlink fly`` share ``uavlink.mavlink`` and
nothing else of each other, and MAVLink 2 is switched on in one place."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = ("uavlink.flight", "uavlink.evaluation")
SOURCE_DIRS = ("uavlink", "sitl_stub", "tests", "benchmarks", "research", "tools")


def _run(code: str) -> str:
    env = dict(os.environ)
    env.pop("MAVLINK20", None)  # a fresh interpreter, as a user's would be
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
        cwd=ROOT,
        check=True,
    )
    return out.stdout.strip()


def test_sitl_stub_imports_no_flight_or_evaluation_module() -> None:
    code = (
        "import importlib, pkgutil, sys, sitl_stub\n"
        "for m in pkgutil.walk_packages(sitl_stub.__path__, 'sitl_stub.'):\n"
        "    importlib.import_module(m.name)\n"
        f"print(','.join(sorted(m for m in sys.modules if m.startswith({FORBIDDEN!r}))))"
    )
    assert _run(code) == ""
    for path in sorted((ROOT / "sitl_stub").rglob("*.py")):  # not even lazily, in a function
        text = path.read_text()
        assert not [name for name in FORBIDDEN if name in text], path


def test_mavlink_package_is_light_and_its_dialect_is_mavlink_2() -> None:
    code = (
        "import sys, uavlink.mavlink, uavlink.mavlink.connection, uavlink.mavlink.px4_modes, "
        "uavlink.mavlink.signing, uavlink.mavlink.rejects\n"
        "print('pymavlink' in sys.modules, any(m.startswith('uavlink.flight') for m in sys.modules))\n"
        "from uavlink.mavlink.dialect import mavlink\n"
        "import os; print(os.environ['MAVLINK20'], mavlink.WIRE_PROTOCOL_VERSION)"
    )
    assert _run(code).splitlines() == ["False False", "1 2.0"]


def test_mavlink20_is_set_in_one_place() -> None:
    here = Path(__file__).resolve()
    setters = [
        path.relative_to(ROOT).as_posix()
        for folder in SOURCE_DIRS
        for path in sorted((ROOT / folder).rglob("*.py"))
        if path != here and "MAVLINK20" in path.read_text()
    ]
    assert setters == ["uavlink/mavlink/dialect.py"]


def test_the_frame_sets_name_mavlinks_frames_and_give_heights_above_home() -> None:
    from uavlink.mavlink import frames
    from uavlink.mavlink.dialect import mavlink

    for name in (
        "GLOBAL",
        "LOCAL_NED",
        "GLOBAL_RELATIVE_ALT",
        "GLOBAL_INT",
        "GLOBAL_RELATIVE_ALT_INT",
        "GLOBAL_TERRAIN_ALT",
        "GLOBAL_TERRAIN_ALT_INT",
    ):
        assert getattr(frames, name) == getattr(mavlink, f"MAV_FRAME_{name}"), name
    assert frames.AMSL_FRAMES.isdisjoint(frames.RELATIVE_ALT_FRAMES)
    assert frames.LOCAL_NED not in frames.GLOBAL_FRAMES
    assert set(frames.TO_INT_FRAME) | set(frames.TO_FLOAT_FRAME) <= frames.GLOBAL_FRAMES
    home_amsl_m = 488.0
    assert frames.height_above_home_m(538.0, mavlink.MAV_FRAME_GLOBAL_INT, home_amsl_m) == 50.0
    assert (
        frames.height_above_home_m(50.0, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, home_amsl_m)
        == 50.0
    )
    assert (
        frames.height_above_home_m(50.0, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT, home_amsl_m) == 50.0
    )


def test_enum_name_reads_the_dialect_and_names_an_unknown_value() -> None:
    from uavlink.mavlink.dialect import enum_name, mavlink

    assert (
        enum_name("MAV_CMD", mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == "MAV_CMD_COMPONENT_ARM_DISARM"
    )
    assert (
        enum_name("MAV_MISSION_RESULT", mavlink.MAV_MISSION_UNSUPPORTED)
        == "MAV_MISSION_UNSUPPORTED"
    )
    assert enum_name("MAV_FRAME", 12345) == "MAV_FRAME 12345"
