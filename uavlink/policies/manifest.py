"""The manifest every policy file carries: what it observes, how its actions map, how it was made.

Stored as ``uavlink_manifest.json`` inside an SB3 zip (and as ONNX metadata for exported models).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import platform
import zipfile
from importlib import metadata
from pathlib import Path
from typing import Any

from uavlink.config import EnvConfig
from uavlink.env.actions import ActionMapping
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError

MANIFEST_FORMAT = "uavlink-policy-v1"
MANIFEST_NAME = "uavlink_manifest.json"


class PolicyFileError(UserError):
    """A policy file that cannot be used; the message says which file and why."""


def package_versions() -> dict[str, str]:
    versions = {"python": platform.python_version()}
    for name in (
        "uavlink",
        "numpy",
        "gymnasium",
        "stable-baselines3",
        "torch",
        "onnxruntime",
        "onnx",
    ):
        with contextlib.suppress(metadata.PackageNotFoundError):
            versions[name] = metadata.version(name)
    return versions


def build_manifest(cfg: EnvConfig, training: dict[str, Any]) -> dict[str, Any]:
    return {
        "format": MANIFEST_FORMAT,
        "observation_layout": ObservationLayout.for_config(cfg).to_dict(),
        "action_mapping": ActionMapping.for_config(cfg).to_dict(),
        "env_config": cfg.to_dict(),
        "training": training,
        "versions": package_versions(),
    }


def check_manifest(manifest: Any, source: str) -> dict[str, Any]:
    """Validate the manifest's shape; raise PolicyFileError naming ``source`` otherwise."""
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        raise PolicyFileError(
            f"{source}: not a uavlink policy manifest (format {MANIFEST_FORMAT!r} expected)"
        )
    for key in ("observation_layout", "action_mapping", "env_config"):
        if key not in manifest:
            raise PolicyFileError(f"{source}: manifest lacks {key!r}")
    try:
        ObservationLayout.from_dict(manifest["observation_layout"])
        ActionMapping.from_dict(manifest["action_mapping"])
        EnvConfig.from_dict(manifest["env_config"])
    except (TypeError, ValueError) as exc:
        raise PolicyFileError(f"{source}: manifest is malformed ({exc})") from None
    return manifest


def read_zip_manifest(path: Path) -> dict[str, Any]:
    """The manifest inside an SB3 policy zip; clear errors for missing, corrupt or foreign files."""
    if not path.is_file():
        raise PolicyFileError(f"{path}: no such policy file")
    try:
        with zipfile.ZipFile(path) as archive:
            if MANIFEST_NAME not in archive.namelist():
                raise PolicyFileError(f"{path}: zip has no {MANIFEST_NAME}; not a uavlink policy")
            manifest = json.loads(archive.read(MANIFEST_NAME))
    except (zipfile.BadZipFile, EOFError, OSError) as exc:
        raise PolicyFileError(f"{path}: corrupt or truncated policy zip ({exc})") from None
    except json.JSONDecodeError as exc:
        raise PolicyFileError(f"{path}: manifest is not valid JSON ({exc})") from None
    return check_manifest(manifest, str(path))


def write_zip_manifest(path: Path, manifest: dict[str, Any]) -> None:
    """Add (or replace) the manifest inside a zip, and write it beside the zip as JSON for readers."""
    with zipfile.ZipFile(path) as archive:
        entries = [
            (info, archive.read(info))
            for info in archive.infolist()
            if info.filename != MANIFEST_NAME
        ]
    # Entries keep their own timestamps and the manifest takes the newest of them, not the clock:
    # the same policy and manifest give the same bytes (a re-shipped policy shows no diff).
    stamp = max((info.date_time for info, _ in entries), default=(1980, 1, 1, 0, 0, 0))
    tmp = path.with_suffix(path.suffix + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
        for info, data in entries:
            archive.writestr(info, data)
        archive.writestr(
            zipfile.ZipInfo(MANIFEST_NAME, stamp),
            json.dumps(manifest, indent=2, sort_keys=True),
            compress_type=zipfile.ZIP_DEFLATED,
        )
    tmp.replace(path)
    path.with_suffix(".json").write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
