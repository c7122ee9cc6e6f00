"""Resolve what ``--policy`` names: an existing file or folder, a baseline, or a shipped policy by
name; and load it (an SB3 zip, an ONNX file, or a folder's policy for a scenario).

The shipped policies are the repository's ``policies/`` folder; a wheel carries them as
``uavlink/shipped`` (``setup.py``'s build step copies them there), so an installed package flies them
from any folder. Each zip has an ONNX twin beside it, which acts alike to the last bit (``uavlink
export`` checks it; ``tests/test_shipped_policies.py`` keeps it so). A zip whose twin was exported
from these very bytes (the twin's manifest records the zip's sha256) runs as its twin: the same
decisions without torch, so the ``[fly]`` install of a companion computer flies it, and every install
starts a flight or an evaluation seconds sooner (torch's import is 3-4 s of CPU) and evaluates
faster (docs/design/flight.md, "A zip runs as its ONNX twin"). A twin left from other bytes is
never flown: the zip runs in stable-baselines3, or, without it, is refused in one line.
"""

from __future__ import annotations

import difflib
import importlib.util
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from uavlink.config import MIXED, EnvConfig
from uavlink.policies.base import Policy
from uavlink.policies.manifest import PolicyFileError
from uavlink.policies.registry import BASELINES, make_baseline

if TYPE_CHECKING:
    from uavlink.policies.onnx_policy import OnnxPolicy

POLICY_SUFFIXES = (".zip", ".onnx")
_PACKAGE = Path(__file__).resolve().parents[1]  # the installed or checked-out ``uavlink``


def shipped_root() -> Path | None:
    """The folder of shipped policies: the installed package's ``uavlink/shipped``, else the source
    checkout's ``policies/`` beside the package; None when neither exists."""
    return next(
        (p for p in (_PACKAGE / "shipped", _PACKAGE.parent / "policies") if p.is_dir()), None
    )


def shipped_policies() -> dict[str, Path]:
    """Every shipped policy by name (``circular``, ``spatial/circular``, ``fleet/straight_180``): its
    zip, or its ONNX file where no zip is shipped; sorted by name."""
    root = shipped_root()
    if root is None:
        return {}
    found: dict[str, Path] = {}
    for suffix in reversed(POLICY_SUFFIXES):  # a zip wins over its twin
        for path in root.rglob(f"*{suffix}"):
            found[path.relative_to(root).with_suffix("").as_posix()] = path
    return dict(sorted(found.items()))


def locate(spec: str | Path) -> str | Path:
    """What ``--policy`` names, in order: an existing file or folder (as given), a baseline, a
    shipped policy or folder by name (``circular``, ``circular.zip``, ``spatial/circular``,
    ``map/no_move``, ``fleet/straight_180``, ``policies/circular.zip``). A path that does not exist
    (absolute, ``./``, ``~``) is a PolicyFileError that says so; anything else one naming the
    closest shipped policies. Quiet: a command says which shipped file a
    name became (``shipped_note``) once its other checks have passed, so bad input stays one line."""
    text = str(spec)
    if text in BASELINES or Path(text).exists():
        return spec
    if Path(text).is_absolute() or text.startswith((".", "~")):  # a path, not a name to look up
        raise PolicyFileError(f"{text}: no such file")
    name = text.removeprefix("policies/").rstrip("/")
    stem = next((name[: -len(s)] for s in POLICY_SUFFIXES if name.endswith(s)), name)
    root = shipped_root()
    shipped = shipped_policies()
    if root is not None:
        if name in ("", "policies"):
            found = root
        elif name != stem and (root / name).is_file():
            found = root / name
        elif stem in shipped:
            found = shipped[stem]
        elif stem and (root / stem).is_dir():
            found = root / stem
        else:
            found = None
        if found is not None:
            return found
    close = difflib.get_close_matches(stem, [*shipped, *BASELINES], n=3, cutoff=0.6)
    hint = f"; closest: {', '.join(close)}" if close else ""
    raise PolicyFileError(
        f"{text}: no such file, baseline ({', '.join(BASELINES)}) or shipped policy{hint} "
        "(`uavlink policies` lists them)"
    )


def shipped_note(specs: Sequence[str | Path], found: Sequence[str | Path]) -> str:
    """The lines (stderr) that say which shipped file each name became, ``uavlink: --policy NAME: the
    shipped FILE``; empty where every spec named a file or baseline as given."""
    return "\n".join(
        f"uavlink: --policy {spec}: the shipped {path}"
        for spec, path in zip(specs, found, strict=True)
        if str(spec) != str(path)
    )


def zip_twin(zip_path: Path) -> tuple[OnnxPolicy, bool] | None:
    """The ONNX twin beside ``zip_path``, loaded, and whether it was exported from these bytes (its
    manifest's ``source_policy_sha256``, which ``uavlink export`` writes); None where there is no
    twin, or no onnxruntime to read it."""
    twin = zip_path.with_suffix(".onnx")
    if not twin.is_file() or importlib.util.find_spec("onnxruntime") is None:
        return None
    from uavlink.policies.manifest import file_sha256
    from uavlink.policies.onnx_policy import OnnxPolicy

    policy = OnnxPolicy(twin)
    return policy, policy.manifest.get("source_policy_sha256") == file_sha256(zip_path)


def load_policy(spec: str | Path, cfg: EnvConfig) -> Policy:
    """A Policy for ``spec`` (see :func:`locate`); raises PolicyFileError / ValueError with a
    one-line message."""
    spec = str(locate(spec))
    if spec in BASELINES:
        return make_baseline(spec, cfg)
    path = Path(spec)
    if path.is_dir():
        return load_policy(policy_for_scenario(path, cfg.scenario), cfg)
    if path.suffix == ".zip":
        twin = zip_twin(path)
        if twin is not None and twin[1]:
            return twin[0]
        if twin is not None and importlib.util.find_spec("stable_baselines3") is None:
            raise PolicyFileError(
                f"{path}: its ONNX twin {path.with_suffix('.onnx')} was exported from another "
                "version of this zip, and stable-baselines3 (the [train] extra) is not installed to "
                f"run the zip itself: export it again (uavlink export {path}) where it is"
            )
        from uavlink.policies.sb3_policy import SB3Policy

        return SB3Policy(path)
    if path.suffix == ".onnx":
        from uavlink.policies.onnx_policy import OnnxPolicy

        return OnnxPolicy(path)
    raise PolicyFileError(f"{spec}: unknown policy file type (expected .zip or .onnx)")


def policy_for_scenario(folder: Path, scenario: str) -> Path:
    """``folder/<scenario>.zip`` (or .onnx), falling back to the mixed policy (``folder/mixed.zip``)."""
    found = policy_file(folder, scenario) or policy_file(folder, MIXED)
    if found is None:
        raise PolicyFileError(
            f"{folder}: no {scenario}.zip, {scenario}.onnx or {MIXED}.zip policy in this folder"
        )
    return found


def policy_file(folder: Path, name: str) -> Path | None:
    """``folder/<name>.zip``, else ``folder/<name>.onnx``; None when neither is a file."""
    return next((p for p in (folder / f"{name}.zip", folder / f"{name}.onnx") if p.is_file()), None)
