"""A sweep and its jobs: ``SweepSpec`` (what a sweep file says, checked: ``uavlink.sweep.sweep_file``)
expands into ``Job``s, each one train + evaluate run with stable keys.

A job's key is a short hash of its settings: a ``key_version`` and the job's full validated configs
(env, training, evaluation), so it names the same job in any sweep file, on any machine, however
the file spells or orders its keys, and changes whenever anything that could change its figures
changes. Job folders made under an older key version do not match and are run again.
"""

from __future__ import annotations

import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.fields import with_changes
from uavlink.errors import UserError
from uavlink.evaluation.tables import TABLE_ONE_BASELINES
from uavlink.policies.manifest import file_sha256

# Version of Job.settings(); 2: the full validated configs (1 hashed TrainConfig's flat fields with
# the warm start's and the optional ones left out when off, to keep older keys).
KEY_VERSION = 2
# Env fields added after KEY_VERSION 2 whose default reproduces every figure of before (the fleet's,
# at n_uavs = 1 bit for bit the single-UAV env): left out of a job's key while at that default, so
# existing results keep their keys. A new field whose default changes figures bumps KEY_VERSION.
NEUTRAL_ENV_DEFAULTS: dict[str, Any] = {
    "n_uavs": 1,
    "fleet_reuse": "full",
    "uav_separation_m": 20.0,
    "fleet_start_radius_m": 100.0,
    "place_cell_m": 0.0,
    "uav_motion": "instant",
    "place_model": "cells",
    "fleet_slots": 0,
}
# The same for the training's (nested) warm-start fields.
NEUTRAL_WARM_START_DEFAULTS: dict[str, Any] = {
    "leader_policy": "",
    "policy": "",
    "dagger_rounds": 0,
    "spread_m": None,
}
# The same for the training's own fields.
NEUTRAL_TRAIN_DEFAULTS: dict[str, Any] = {
    "validation_episodes": 0,
    "fleet_sizes_up_to": 0,
    "critic": "actor",
    "gsde_log_std": None,
}
# Warm-start fields that name a policy file: a job's key holds the file's bytes (its sha256), not only
# its path, so a re-shipped file makes the job (and a sweep record's figures of it) another one.
POLICY_FILE_FIELDS = ("leader_policy", "policy")
BASELINE_COLUMNS = TABLE_ONE_BASELINES  # a job evaluates Table I's baselines beside its policy


class SweepSpecError(UserError):
    """A sweep file that cannot run; the one-line message names the file and the key."""


@dataclass
class Job:
    """One train + evaluate run: a scenario, a seed and one point of the grid, with its full configs."""

    sweep: str
    scenario: str
    seed: int
    point: dict[str, Any]  # this job's grid values, by qualified key ("env.radio.x", "train.x")
    env: EnvConfig
    train: TrainConfig
    eval: dict[str, int]
    file_sha256: dict[str, str] = field(
        default_factory=dict
    )  # POLICY_FILE_FIELDS' files, hashed where the job is made
    key: str = field(default="", init=False)

    def __post_init__(self) -> None:
        for name in POLICY_FILE_FIELDS:
            path = getattr(self.train.warm_start, name)
            if path and name not in self.file_sha256:
                try:
                    self.file_sha256[name] = file_sha256(Path(path))
                except OSError as exc:
                    raise SweepSpecError(
                        f"{self.sweep}: warm_start.{name} {path}: cannot read it "
                        f"({exc.strerror}); paths are relative to where the sweep runs"
                    ) from None
        self.key = hashlib.sha256(json.dumps(self.settings(), sort_keys=True).encode()).hexdigest()[
            :12
        ]

    @property
    def name(self) -> str:
        """The job's folder: readable prefix plus the key."""
        return f"{self.scenario}-seed{self.seed}-{self.key}"

    @property
    def setting(self) -> tuple[str, tuple[tuple[str, Any], ...]]:
        """What seeds are averaged over: the scenario and the grid point."""
        return self.scenario, tuple((k, _hashable(v)) for k, v in self.point.items())

    def settings(self) -> dict[str, Any]:
        """Everything that determines the job's figures; the key is its hash."""
        env = {
            k: v
            for k, v in self.env.to_dict().items()
            if k not in NEUTRAL_ENV_DEFAULTS or v != NEUTRAL_ENV_DEFAULTS[k]
        }
        train = {
            k: v
            for k, v in self.train.to_dict().items()
            if k not in NEUTRAL_TRAIN_DEFAULTS or v != NEUTRAL_TRAIN_DEFAULTS[k]
        }
        train["warm_start"] = {
            k: v
            for k, v in train["warm_start"].items()
            if k not in NEUTRAL_WARM_START_DEFAULTS or v != NEUTRAL_WARM_START_DEFAULTS[k]
        }
        for name, digest in self.file_sha256.items():
            train["warm_start"][f"{name}_sha256"] = digest
        return {
            "key_version": KEY_VERSION,
            "env": env,
            "train": train,
            "eval": {**self.eval, "policies": ["ppo", *BASELINE_COLUMNS]},
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            "sweep": self.sweep,
            "scenario": self.scenario,
            "seed": self.seed,
            "point": self.point,
            "env": self.env.to_dict(),
            "train": self.train.to_dict(),
            "eval": self.eval,
            "file_sha256": self.file_sha256,
            "key": self.key,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Job:
        job = cls(
            data["sweep"],
            data["scenario"],
            data["seed"],
            dict(data["point"]),
            EnvConfig.from_dict(data["env"]),
            TrainConfig.from_dict(data["train"]),
            dict(data["eval"]),
            dict(
                data.get("file_sha256")  # jobs.json before the start policy: the leader's only
                or ({"leader_policy": data["leader_sha256"]} if data.get("leader_sha256") else {})
            ),
        )
        if data.get("key", job.key) != job.key:
            raise ValueError(
                f"job {data['key']}: settings hash to {job.key} here (another uavlink version?)"
            )
        return job


@dataclass
class SweepSpec:
    name: str
    scenarios: list[str]
    seeds: list[int]
    train: dict[str, Any]  # TrainConfig changes by field path ("episodes", "warm_start.teacher")
    env: dict[str, Any]  # EnvConfig changes by field path ("r_max_m", "radio.shadowing")
    eval: dict[str, int]
    grid: dict[str, list[Any]]  # qualified key ("train.x", "env.x") -> values
    description: str = ""
    source: Path | None = None
    scenario_train: dict[str, dict[str, Any]] = field(
        default_factory=dict
    )  # scenario -> train changes
    scenario_env: dict[str, dict[str, Any]] = field(default_factory=dict)  # scenario -> env changes

    def points(self) -> list[dict[str, Any]]:
        keys = list(self.grid)
        return [
            dict(zip(keys, values, strict=True))
            for values in itertools.product(*self.grid.values())
        ]

    def configs(
        self, scenario: str, point: dict[str, Any], seed: int
    ) -> tuple[EnvConfig, TrainConfig]:
        """The validated configs of one job (a ConfigError naming the field if a value is bad)."""
        env = {
            **self.env,
            **self.scenario_env.get(scenario, {}),
            **{k[4:]: v for k, v in point.items() if k.startswith("env.")},
        }
        train = {
            **self.train,
            **self.scenario_train.get(scenario, {}),
            **{k[6:]: v for k, v in point.items() if k.startswith("train.")},
        }
        cfg = EnvConfig().replace(**env, scenario=scenario).validate()
        return cfg, with_changes(
            TrainConfig(), {**train, "seed": seed, "torch_threads": 1}
        ).validate(cfg)

    def jobs(self) -> list[Job]:
        """Scenario-major, then grid point, then seed."""
        return [
            Job(
                self.name,
                scenario,
                seed,
                point,
                *self.configs(scenario, point, seed),
                dict(self.eval),
            )
            for scenario in self.scenarios
            for point in self.points()
            for seed in self.seeds
        ]


def _hashable(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def describe_point(point: dict[str, Any]) -> str:
    """``radio.aoa_noise_deg=5 learning_rate=0.0001`` (section prefixes dropped), or ``default``."""
    if not point:
        return "default"
    return " ".join(f"{k.split('.', 1)[1]}={_fmt(v)}" for k, v in point.items())


def _fmt(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "x".join(str(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)
