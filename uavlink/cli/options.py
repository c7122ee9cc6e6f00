"""Options more than one command shares: the scenario names, the env overrides (``--scenario``,
``--aoa-noise-deg``, ``--set``) that ``uavlink.policies.contract.EnvOverrides`` reads, seeds, the
checks of output paths made before any work, and the command line a report names."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from uavlink.config import SCENARIO_NAMES, SCENARIOS, check_seed
from uavlink.errors import ConfigError, UserError
from uavlink.policies.contract import BUILT_FOR


def seed(text: str) -> int:
    """argparse type of ``--seed``: an integer in 0..SEED_MAX (``uavlink.config.check_seed``)."""
    try:
        return check_seed(int(text), "a seed")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer seed, got {text!r}") from None


def scenario_list(name: str) -> list[str]:
    """The scenarios ``--scenario NAME`` stands for (``all``: every one but mixed)."""
    if name == "all":
        return list(SCENARIOS)
    if name not in SCENARIO_NAMES:
        raise UserError(
            f"unknown scenario {name!r}; choose from {', '.join(SCENARIO_NAMES)} or all"
        )
    return [name]


def add_env_options(p: argparse.ArgumentParser, for_policy: bool = False) -> None:
    """``--scenario``, ``--aoa-noise-deg`` and ``--set``; ``for_policy``: as evaluate reads them,
    where a policy file's manifest gives the defaults and limits what may change."""
    names = ", ".join(SCENARIO_NAMES)
    if for_policy:  # evaluate: a policy file flies its own scenario unless told otherwise
        p.add_argument(
            "--scenario",
            default=None,
            help=f"one of {names} or all (default: a policy file's own scenario, from its "
            "manifest; circular for a baseline or a folder)",
        )
    else:
        p.add_argument("--scenario", default="circular", help=f"one of {names} (default: circular)")
    p.add_argument(
        "--aoa-noise-deg",
        type=float,
        default=None,
        help="std of the AoA estimate noise (deg)"
        + (" (default: the policy's; 0 for a baseline alone)" if for_policy else ""),
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an env config field, e.g. --set r_max_m=10 --set radio.shadowing=false"
        + (
            f"; under a policy file radio fields may change, {', '.join(BUILT_FOR)} may not "
            "(n_uavs may, within an any-size fleet policy's sizes)"
            if for_policy
            else ""
        ),
    )


def command_line(command: str, otherwise: str) -> str:
    """The command that made a report, for the report to name: this process's arguments when it is
    ``uavlink COMMAND ...``, else ``otherwise`` (the command run from Python, e.g. a test)."""
    return "uavlink " + " ".join(sys.argv[1:]) if sys.argv[1:2] == [command] else otherwise


def output_folder(path: Path, option: str) -> Path:
    """``path`` checked as a folder to write into (made later, by the command, once it has work to
    write): UserError when it or a folder above it is a file, or when the nearest folder that exists
    takes no new file. Checked before any work, so a long run does not end in a traceback at its
    first write."""
    for above in (path, *path.parents):
        if above.exists():
            if not above.is_dir():
                where = "is a file" if above == path else f"lies under {above}, a file"
                raise UserError(f"{option} {path} {where}; give a folder")
            _check_writable(above, path, option)
            break
    return path


def _check_writable(folder: Path, path: Path, option: str) -> None:
    """UserError unless a file can be made (and is at once removed) in ``folder``: what the command
    will write needs it, and permission bits alone do not say (root, read-only mounts, /sys)."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        where = "" if folder == path else f" (its nearest folder, {folder})"
        raise UserError(f"{option} {path}: cannot write there{where}: {exc.strerror}") from None


def output_file(path: Path, option: str, suffixes: tuple[str, ...] = ()) -> Path:
    """``path`` checked as a file to write (its folder made later): UserError when it is a folder,
    a folder above it is a file, or its suffix is not one of ``suffixes`` (when given)."""
    if path.is_dir():
        raise UserError(f"{option} {path} is a folder; give a file name")
    if suffixes and path.suffix.lower() not in suffixes:
        raise UserError(f"{option} {path} must end in {' or '.join(suffixes)}")
    output_folder(path.parent, f"{option} {path}: its folder")
    return path
