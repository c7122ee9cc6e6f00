"""The policy contract: the env a policy runs in is the one its manifest records, plus explicit overrides.

Every consumer (``uavlink evaluate`` and its ``--against``, the results report, sweep evaluation,
``uavlink fly`` and, through fly, the embedded SITL's radio payload) gets its env here, so a policy
trained with ``--set action_mapping=polar-v1 --set r_max_m=8`` is evaluated and flown that way
without the user repeating it. On top of the manifest's env go the user's explicit overrides:
the scenario, the AoA noise and ``--set`` pairs. Two kinds of change are treated differently:

* what the policy was built for (``BUILT_FOR``: how its outputs become moves and what its input
  holds) cannot change: such an override is refused with one line naming both values;
* the world (radio physics, UE motion, episode length) may: evaluating a policy under other
  radio settings is a robustness study.

Training-time randomisation (``radio.aoa_noise_max_deg``) belongs to the training, not to the
policy's env: it is 0 here unless an override asks for it. Baselines have no manifest: they take
the env of the policy they are compared with, or the defaults plus the overrides when alone
(``explore`` with a memory of place added when that env has none).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from uavlink.config import EnvConfig, parse_settings
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError
from uavlink.policies.base import Policy
from uavlink.policies.loader import load_policy, locate, policy_for_scenario
from uavlink.policies.manifest import PolicyFileError
from uavlink.policies.registry import BASELINES, baseline_env

# Fields a policy was built for: its action mapping and its observation layout's inputs.
BUILT_FOR = (
    "action_mapping",
    "r_max_m",
    "memory",
    "place_cell_m",
    "place_model",
    "n_ues",
    "n_uavs",
    "fleet_slots",
    "area.half_width_m",
)
OVERRIDES_HELP = (
    f"A policy file runs in the env its manifest records; --scenario, --aoa-noise-deg and --set "
    f"override it. Radio physics and the world may be overridden (a robustness study); what "
    f"the policy was built for ({', '.join(BUILT_FOR)}) may not, except n_uavs within the "
    f"sizes an any-size fleet policy flies (fleet_slots K: 2 to K + 1 UAVs)."
)
# What compared policies may differ in: each flies with its own action mapping and memory, and with
# its own number of UAVs and its own memory of place over the same UEs and channel (a fleet against one UAV: the per-episode
# world streams do not depend on n_uavs, so the episodes pair as in docs/results.md's fleet ratios).
# How its UAV reaches a setpoint is a policy's too: motion draws nothing, so the episodes pair; and
# how a fleet uses its band (full reuse, or one cell and the others listening): the UEs' paths and the
# field do not depend on it.
PER_POLICY = (
    "action_mapping",
    "r_max_m",
    "memory",
    "place_cell_m",
    "place_model",
    "n_uavs",
    "fleet_slots",
    "uav_motion",
    "fleet_reuse",
)
# Training-time randomisation: off in a policy's env unless an override turns it on.
TRAINING_ONLY = "radio.aoa_noise_max_deg"


@dataclass(frozen=True)
class EnvOverrides:
    """What the user asks on top of a policy's env: ``--scenario``, ``--aoa-noise-deg``, ``--set``.
    None (and no settings) keeps the policy's value."""

    scenario: str | None = None
    aoa_noise_deg: float | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_command_line(
        cls, scenario: str | None, aoa_noise_deg: float | None, set_pairs: Sequence[str]
    ) -> EnvOverrides:
        """``--scenario``, ``--aoa-noise-deg`` and the ``--set KEY=VALUE`` pairs of a command line."""
        return cls(scenario, aoa_noise_deg, parse_settings(set_pairs))

    def on(self, scenario: str | None) -> EnvOverrides:
        """The same overrides on another scenario (None: the policy's own)."""
        return EnvOverrides(scenario, self.aoa_noise_deg, self.settings)

    def changes(self) -> dict[str, Any]:
        """The overrides as ``EnvConfig.replace`` keys (explicit flags win over ``--set``)."""
        changes = dict(self.settings)
        if self.scenario is not None:
            changes["scenario"] = self.scenario
        if self.aoa_noise_deg is not None:
            changes["aoa_noise_deg"] = self.aoa_noise_deg
        return changes


def manifest_env(manifest: Mapping[str, Any] | None) -> EnvConfig:
    """The env a manifest's policy was built for, without training-time randomisation
    (the defaults when there is no manifest)."""
    if manifest is None:
        return EnvConfig()
    return EnvConfig.from_dict(manifest["env_config"]).replace(**{TRAINING_ONLY: 0.0})


def apply_overrides(
    base: EnvConfig, overrides: EnvOverrides, built_for: str | None = None
) -> EnvConfig:
    """``base`` with ``overrides`` on top, validated (a bad key or value is a one-line
    ``ConfigError``). With ``built_for`` (the policy file's name), an override that changes a
    ``BUILT_FOR`` field is refused naming both values."""
    changes = overrides.changes()
    cfg = base.replace(**changes).validate()
    if built_for is not None:
        path = built_for_change(base, cfg)
        if path is not None:
            key = next((k for k in changes if k == path or k == path.rpartition(".")[2]), path)
            raise UserError(
                f"policy {built_for} was built for {path}={base.to_flat_dict()[path]!r}; "
                f"--set {key}={changes.get(key)} conflicts (drop the --set)"
            )
    return cfg


def built_for_change(built: EnvConfig, cfg: EnvConfig) -> str | None:
    """The first ``BUILT_FOR`` field (its ``replace`` key) in which ``cfg`` differs from ``built``, the
    env a policy was built for; None when they agree."""
    ours, theirs = built.to_flat_dict(), cfg.to_flat_dict()
    # An any-size fleet's policy (fleet_slots > 0) flies every fleet size its slots allow, which
    # EnvConfig.validate() checks: its n_uavs is where it trained, not what it was built for.
    sized = ("n_uavs",) if built.fleet_slots > 0 else ()
    return next(
        (path for path in BUILT_FOR if path not in sized and theirs[path] != ours[path]), None
    )


def check_policy_env(policy: Policy, cfg: EnvConfig) -> None:
    """Refuse to fly ``policy`` in ``cfg`` when it was not built for it (what ``evaluate_policy`` checks):
    the observation layout it reads, and for a policy file (one with a manifest) every ``BUILT_FOR``
    field of its manifest's env. Each refusal is one line saying how to get the env it flies in."""
    manifest = getattr(policy, "manifest", None)
    name = getattr(policy, "name", policy)
    if manifest is not None:
        path = getattr(policy, "path", None)
        how = (
            f"evaluate it in the env its manifest records: uavlink.policies.contract.load_with_env("
            f"[{str(path) if path else 'path'!r}], EnvOverrides()) gives (policy, env)"
        )
    elif name in BASELINES:
        how = (
            f"evaluate a baseline made for a world, make_baseline({name!r}, world), in "
            f"uavlink.policies.registry.baseline_env({name!r}, world)"
        )
    else:
        how = None
    layout: ObservationLayout | None = getattr(policy, "layout", None)
    if layout is not None:
        try:
            layout.check_matches(ObservationLayout.for_config(cfg), what=f"policy {name!r}")
        except UserError as exc:
            raise UserError(f"{exc}; {how}" if how else str(exc)) from None
    if manifest is not None:
        built = manifest_env(manifest)
        path = built_for_change(built, cfg)
        if path is not None:
            raise UserError(
                f"policy {name!r} was built for {path}={built.to_flat_dict()[path]!r}, not "
                f"{cfg.to_flat_dict()[path]!r}; {how}"
            )


def policy_env(
    policy: Policy, overrides: EnvOverrides, source: str | Path | None = None
) -> EnvConfig:
    """The env of a loaded policy: its manifest's (defaults for a baseline) plus ``overrides``."""
    manifest = getattr(policy, "manifest", None)
    if manifest is None:
        return apply_overrides(EnvConfig(), overrides)
    source = str(source or policy.name)
    cfg = apply_overrides(manifest_env(manifest), overrides, built_for=source)
    if policy.layout is not None:
        try:
            policy.layout.check_matches(ObservationLayout.for_config(cfg), what=f"policy {source}")
        except ValueError as exc:  # the manifest's layout disagrees with its own env config
            raise PolicyFileError(f"{source}: {exc}") from None
    return cfg


def resolve(spec: str | Path, scenario: str | None) -> str | Path:
    """A baseline name or a policy file; a folder resolves to its policy for ``scenario``."""
    if str(spec) in BASELINES or not Path(spec).is_dir():
        return spec
    if scenario is None:
        raise UserError(f"{spec} is a folder: name a scenario (--scenario) to pick its policy")
    return policy_for_scenario(Path(spec), scenario)


def load_with_env(
    specs: Sequence[str | Path], overrides: EnvOverrides
) -> list[tuple[Policy, EnvConfig]]:
    """Load the policies ``specs`` names (baselines, files, folders resolved per scenario), each
    with the env it runs in. Files get their own manifest's env; baselines get the first file's,
    so compared policies fly the same world. Files built for different worlds are refused: they
    could not fly the same episodes. Without a scenario in ``overrides``, a folder beside a file
    resolves to the file's own scenario (its manifest's)."""
    specs = [locate(spec) for spec in specs]
    defaults = apply_overrides(EnvConfig(), overrides)
    named = {
        str(spec): load_policy(spec, defaults)
        for spec in specs
        if str(spec) not in BASELINES and not Path(spec).is_dir()
    }  # a file's policy needs no env
    if overrides.scenario is None and named and any(Path(spec).is_dir() for spec in specs):
        own = next(iter(named))  # the folder's policy is the one for the first file's scenario
        overrides = overrides.on(policy_env(named[own], overrides, own).scenario)
        defaults = apply_overrides(EnvConfig(), overrides)
    resolved = [str(resolve(spec, overrides.scenario)) for spec in specs]
    files = {
        spec: named.get(spec) or load_policy(spec, defaults)
        for spec in resolved
        if spec not in BASELINES
    }
    envs = {spec: policy_env(policy, overrides, spec) for spec, policy in files.items()}
    first = next(iter(envs), None)
    world = envs[first] if first is not None else defaults
    for spec, cfg in envs.items():
        _check_same_world(first, world, spec, cfg)
    return [
        (files[spec], envs[spec])
        if spec in files
        else (load_policy(spec, world), baseline_env(spec, world))
        for spec in resolved
    ]


def _check_same_world(first: str | None, world: EnvConfig, spec: str, cfg: EnvConfig) -> None:
    """Compared policies may differ in ``PER_POLICY`` fields only."""
    ours = world.to_flat_dict()
    theirs = cfg.replace(**{key: ours[key] for key in PER_POLICY}).to_flat_dict()
    key = next((k for k, v in theirs.items() if ours[k] != v), None)
    if key is not None:
        hint = ": --scenario flies both on one" if key == "scenario" else ""
        raise UserError(
            f"{first} and {spec} were built for different envs ({key}={ours[key]!r} vs "
            f"{theirs[key]!r}); they cannot be compared on the same episodes{hint}"
        )
