"""Sweep files: parse a TOML sweep, check every key and value, expand it into jobs with stable keys.

A sweep file (``sweeps/tiny.toml`` is a commented example)::

    name = "table1"                   # folder under --out-root (default: the file's stem)
    scenarios = ["straight", "circular"]   # or "all"
    seeds = [0, 1, 2]                 # or a count: seeds = 3 means 0, 1, 2
    [train]                           # TrainConfig fields: the budget and PPO hyper-parameters
    episodes = 12000
    [scenario_train.circular]         # TrainConfig fields for one scenario's jobs only
    n_envs = 64
    [env]                             # EnvConfig fields; radio.x / area.x reach the nested configs
    "radio.shadowing" = true
    [eval]
    episodes = 100                    # evaluation episodes per policy (PPO, static, oracle, aoa)
    seed = 0                          # evaluation seed: every policy meets the same episodes
    [grid]                            # lists: the sweep runs every combination
    "radio.aoa_noise_deg" = [0.0, 10.0]
    learning_rate = [1e-4, 3e-4]      # train.x / env.x prefixes are accepted too

Every problem (unknown key, bad value, empty grid) raises ``SweepSpecError`` with one line naming
the key, before any job starts. A job's key is a short hash of its full settings (the complete env
config, every PPO hyper-parameter, the evaluation settings), so it names the same job in any sweep
file, on any machine, and changes whenever anything that could change its figures changes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, get_type_hints

from uavlink.config import AreaConfig, EnvConfig, RadioConfig
from uavlink.errors import UserError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the sweep extra installs tomli on 3.10
    import tomli as tomllib

JOB_FORMAT = "uavlink-sweep-job-v1"
TOP_KEYS = ("name", "description", "scenarios", "seeds", "train", "scenario_train", "env", "eval", "grid")
EVAL_DEFAULTS: dict[str, int] = {"episodes": 100, "seed": 0}
BASELINE_COLUMNS = ("static", "oracle", "aoa")
# TrainConfig fields a sweep does not set, and why.
TRAIN_FIXED = {
    "seed": "set the top-level 'seeds'",
    "torch_threads": "workers pin torch to 1 thread",
    "checkpoint_every_steps": "sweep jobs keep no checkpoints",
    "extra": "not a hyper-parameter",
}
ENV_FIXED = {"scenario": "set the top-level 'scenarios'"}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class SweepSpecError(UserError):
    """A sweep file that cannot run; the one-line message names the file and the key."""


def _train_defaults() -> dict[str, Any]:
    """Default of every TrainConfig field; an optional one (default None) stands as a zero of its
    type (0 or 0.0), so that ``_coerce`` checks its values by that type."""
    from uavlink.training import TrainConfig  # numpy only; torch is imported by train()

    hints = get_type_hints(TrainConfig)
    defaults = {f.name: getattr(TrainConfig(), f.name) for f in dataclasses.fields(TrainConfig)}
    optional_zero = {int | None: 0, float | None: 0.0}
    return {name: optional_zero[hints[name]] if value is None else value for name, value in defaults.items()}


def _env_defaults() -> dict[str, Any]:
    """Default of every env field by its qualified name (``r_max_m``, ``radio.x``, ``area.x``)."""
    base = EnvConfig()
    out = {f.name: getattr(base, f.name) for f in dataclasses.fields(EnvConfig)
           if f.name not in ("radio", "area")}
    for prefix, sub, cls in (("radio", base.radio, RadioConfig), ("area", base.area, AreaConfig)):
        out.update({f"{prefix}.{f.name}": getattr(sub, f.name) for f in dataclasses.fields(cls)})
    return out


@dataclass
class Job:
    """One train + evaluate run: a scenario, a seed and one point of the grid."""

    sweep: str
    scenario: str
    seed: int
    point: dict[str, Any]  # this job's grid values, by qualified key ("radio.x", "train.x")
    env: dict[str, Any]  # env overrides (file + grid), qualified keys, scenario excluded
    train: dict[str, Any]  # TrainConfig overrides (file + grid), seed excluded
    eval: dict[str, int]
    key: str = field(default="", init=False)

    def __post_init__(self) -> None:
        self.key = hashlib.sha256(json.dumps(self.settings(), sort_keys=True).encode()).hexdigest()[:12]

    @property
    def name(self) -> str:
        """The job's folder: readable prefix plus the key."""
        return f"{self.scenario}-seed{self.seed}-{self.key}"

    @property
    def setting(self) -> tuple[str, tuple[tuple[str, Any], ...]]:
        """What seeds are averaged over: the scenario and the grid point."""
        return self.scenario, tuple((k, _hashable(v)) for k, v in self.point.items())

    def env_config(self) -> EnvConfig:
        return EnvConfig().replace(**self.env, scenario=self.scenario).validate()

    def train_config(self):
        from uavlink.training import TrainConfig

        values = dict(self.train)
        if "net_arch" in values:
            values["net_arch"] = tuple(values["net_arch"])
        return TrainConfig(**values, seed=self.seed, torch_threads=1)

    def settings(self) -> dict[str, Any]:
        """Everything that determines the job's figures; the key is its hash."""
        train = self.train_config().hyperparameters()
        for name in ("torch_threads", "checkpoint_every_steps", "extra"):
            train.pop(name, None)
        if not train["warm_start_teacher"]:  # off: its knobs change nothing (and keys stay as before)
            train = {k: v for k, v in train.items() if not k.startswith("warm_start_")}
        train = {k: v for k, v in train.items() if v is not None}  # None: an optional feature left off
        return {"format": JOB_FORMAT, "env": self.env_config().to_dict(), "train": train,
                "eval": {**self.eval, "policies": ["ppo", *BASELINE_COLUMNS]}}

    def to_dict(self) -> dict[str, Any]:
        return {"sweep": self.sweep, "scenario": self.scenario, "seed": self.seed, "point": self.point,
                "env": self.env, "train": self.train, "eval": self.eval, "key": self.key}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Job:
        job = cls(data["sweep"], data["scenario"], data["seed"], dict(data["point"]), dict(data["env"]),
                  dict(data["train"]), dict(data["eval"]))
        if data.get("key", job.key) != job.key:
            raise ValueError(f"job {data['key']}: settings hash to {job.key} here (another uavlink version?)")
        return job


@dataclass
class SweepSpec:
    name: str
    scenarios: list[str]
    seeds: list[int]
    train: dict[str, Any]
    env: dict[str, Any]
    eval: dict[str, int]
    grid: dict[str, list[Any]]  # qualified key -> values
    description: str = ""
    source: Path | None = None
    scenario_train: dict[str, dict[str, Any]] = field(default_factory=dict)  # scenario -> train overrides

    def points(self) -> list[dict[str, Any]]:
        keys = list(self.grid)
        return [dict(zip(keys, values, strict=True)) for values in itertools.product(*self.grid.values())]

    def jobs(self) -> list[Job]:
        """Scenario-major, then grid point, then seed."""
        out = []
        for scenario in self.scenarios:
            for point in self.points():
                env = dict(self.env)
                train = {**self.train, **self.scenario_train.get(scenario, {})}
                for key, value in point.items():
                    section, name = key.split(".", 1)
                    (train if section == "train" else env)[name] = value
                for seed in self.seeds:
                    out.append(Job(self.name, scenario, seed, point, env, train, dict(self.eval)))
        return out


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep file; every job's configs are built once here, so bad values fail now."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SweepSpecError(f"{path}: no such sweep file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SweepSpecError(f"{path}: cannot read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SweepSpecError(f"{path}: not valid TOML ({exc})") from None
    try:
        spec = parse_spec(data, default_name=path.stem)
    except SweepSpecError as exc:
        raise SweepSpecError(f"{path}: {exc}") from None
    spec.source = path
    return spec


def parse_spec(data: dict[str, Any], default_name: str = "sweep") -> SweepSpec:
    """Check a parsed sweep file; raises SweepSpecError naming the offending key."""
    from uavlink.mobility import MIXED, SCENARIOS

    for key in data:
        if key not in TOP_KEYS:
            raise SweepSpecError(f"unknown key {key!r} (allowed: {', '.join(TOP_KEYS)})")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not _NAME.match(name):
        raise SweepSpecError(f"key 'name' must be a folder name (letters, digits, _ . -), got {name!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise SweepSpecError("key 'description' must be a string")

    scenarios = data.get("scenarios", list(SCENARIOS))
    if scenarios == "all":
        scenarios = list(SCENARIOS)
    if not isinstance(scenarios, list) or not scenarios:
        raise SweepSpecError("key 'scenarios' must be \"all\" or a non-empty list of scenario names")
    for s in scenarios:
        if s not in (*SCENARIOS, MIXED):
            raise SweepSpecError(f"key 'scenarios': unknown scenario {s!r}; choose from "
                                 f"{', '.join(SCENARIOS)}, {MIXED}")
    if len(set(scenarios)) != len(scenarios):
        raise SweepSpecError("key 'scenarios' lists a scenario twice")

    seeds = data.get("seeds", [0])
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise SweepSpecError(f"key 'seeds' as a count must be >= 1, got {seeds}")
        seeds = list(range(seeds))
    if (not isinstance(seeds, list) or not seeds
            or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds)):
        raise SweepSpecError(f"key 'seeds' must be a count or a non-empty list of integers >= 0, got {seeds!r}")
    if len(set(seeds)) != len(seeds):
        raise SweepSpecError("key 'seeds' lists a seed twice")

    train_defaults, env_defaults = _train_defaults(), _env_defaults()
    train = {}
    for key, value in _flatten(_table(data, "train")).items():
        field_name = _qualify(key, "train", train_defaults, env_defaults, allow=("train",))[1]
        train[field_name] = _coerce(f"train.{field_name}", value, train_defaults[field_name])
    scenario_train: dict[str, dict[str, Any]] = {}
    for scenario, table in _table(data, "scenario_train").items():
        if scenario not in scenarios or not isinstance(table, dict):
            raise SweepSpecError(f"[scenario_train] key {scenario!r} must be a table named after one of "
                                 f"the sweep's scenarios ({', '.join(scenarios)})")
        overrides = scenario_train[scenario] = {}
        for key, value in _flatten(table).items():
            field_name = _qualify(key, f"scenario_train.{scenario}", train_defaults, env_defaults,
                                  allow=("train",))[1]
            overrides[field_name] = _coerce(f"scenario_train.{scenario}.{field_name}", value,
                                            train_defaults[field_name])
        _check_ranges("train", overrides)
    env = {}
    for key, value in _flatten(_table(data, "env")).items():
        field_name = _qualify(key, "env", train_defaults, env_defaults, allow=("env",))[1]
        env[field_name] = _coerce(f"env.{field_name}", value, env_defaults[field_name])

    evaluation = dict(EVAL_DEFAULTS)
    for key, value in _table(data, "eval").items():
        if key not in EVAL_DEFAULTS:
            raise SweepSpecError(f"[eval] unknown key {key!r} (allowed: {', '.join(EVAL_DEFAULTS)})")
        if isinstance(value, bool) or not isinstance(value, int) or value < (1 if key == "episodes" else 0):
            raise SweepSpecError(f"eval.{key} must be an integer >= {1 if key == 'episodes' else 0}, got {value!r}")
        evaluation[key] = value

    grid: dict[str, list[Any]] = {}
    for key, values in _flatten(_table(data, "grid")).items():
        section, field_name = _qualify(key, "grid", train_defaults, env_defaults, allow=("train", "env"))
        qualified = f"{section}.{field_name}"
        if not isinstance(values, list):
            raise SweepSpecError(f"[grid] key {key!r} must be a list of values, got {values!r}")
        if not values:
            raise SweepSpecError(f"[grid] key {key!r} is empty: give at least one value")
        if field_name in (train if section == "train" else env):
            raise SweepSpecError(f"key {key!r} is set in both [{section}] and [grid]")
        if section == "train" and any(field_name in o for o in scenario_train.values()):
            raise SweepSpecError(f"key {key!r} is set in both [scenario_train] and [grid]")
        if qualified in grid:
            raise SweepSpecError(f"[grid] key {key!r} is given twice")
        defaults = train_defaults if section == "train" else env_defaults
        coerced = [_coerce(qualified, v, defaults[field_name]) for v in values]
        if len({json.dumps(v) for v in coerced}) != len(coerced):
            raise SweepSpecError(f"[grid] key {key!r} repeats a value")
        grid[qualified] = coerced

    for section, values in (("train", train), ("env", env)):
        _check_ranges(section, values)
    for point_key, values in grid.items():
        section, field_name = point_key.split(".", 1)
        for v in values:
            _check_ranges(section, {field_name: v})

    spec = SweepSpec(name, list(scenarios), list(seeds), train, env, evaluation, grid, description,
                     scenario_train=scenario_train)
    for job in spec.jobs():
        merged = {**train_defaults, **job.train}
        if merged["n_envs"] * merged["n_steps"] < 2:
            raise SweepSpecError("keys 'train.n_envs' x 'train.n_steps' must be >= 2 (PPO's rollout buffer)")
    from uavlink.env.actions import ActionMapping

    for scenario in spec.scenarios:  # build every config: validate() names the field of a bad value
        for point in spec.points():
            changes = {**env, **{k[4:]: v for k, v in point.items() if k.startswith("env.")}}
            where = f"scenario {scenario}" + (f", grid point {describe_point(point)}" if point else "")
            try:
                cfg = EnvConfig().replace(**changes, scenario=scenario).validate()
            except (TypeError, ValueError) as exc:
                raise SweepSpecError(f"{exc} ({where})") from None
            try:
                ActionMapping(cfg.r_max_m, cfg.action_mapping)
            except ValueError as exc:
                raise SweepSpecError(f"key 'env.action_mapping': {exc} ({where})") from None
    return spec


def _table(data: dict[str, Any], name: str) -> dict[str, Any]:
    table = data.get(name, {})
    if not isinstance(table, dict):
        raise SweepSpecError(f"key {name!r} must be a table ([{name}])")
    return table


def _flatten(table: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """TOML dotted keys (radio.x = 1) and sub-tables ([env.radio]) -> {"radio.x": 1}."""
    out: dict[str, Any] = {}
    for key, value in table.items():
        full = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(_flatten(value, f"{full}."))
        else:
            out[full] = value
    return out


def _qualify(key: str, where: str, train_defaults: dict[str, Any], env_defaults: dict[str, Any],
             allow: tuple[str, ...]) -> tuple[str, str]:
    """(section, field) for a key as written: ``train.x``, ``env.x``, ``radio.x`` or a bare field."""
    head, _, tail = key.partition(".")
    if head in ("train", "env") and tail:
        section, name = head, tail
    elif key in train_defaults:
        section, name = "train", key
    else:
        section, name = "env", key
    if section == "env" and name not in env_defaults:
        for prefix in ("radio", "area"):  # EnvConfig.replace also takes a bare radio/area field
            if f"{prefix}.{name}" in env_defaults:
                name = f"{prefix}.{name}"
    label = f"[{where}] key {key!r}"
    fixed = TRAIN_FIXED if section == "train" else ENV_FIXED
    if name in fixed:
        raise SweepSpecError(f"{label} cannot be set in a sweep: {fixed[name]}")
    if section not in allow or name not in (train_defaults if section == "train" else env_defaults):
        what = {"train": "a TrainConfig field (PPO hyper-parameter or budget)",
                "env": "an EnvConfig field (radio.x and area.x for the nested ones)"}
        expected = " or ".join(what[s] for s in allow)
        raise SweepSpecError(f"{label} is unknown: not {expected}")
    return section, name


def _coerce(key: str, value: Any, default: Any) -> Any:
    """Check ``value`` has the field's type; ints become floats where the field is a float."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise SweepSpecError(f"key {key!r} must be true or false, got {value!r}")
    elif isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise SweepSpecError(f"key {key!r} must be an integer, got {value!r}")
    elif isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SweepSpecError(f"key {key!r} must be a number, got {value!r}")
        value = float(value)
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise SweepSpecError(f"key {key!r} must be a string, got {value!r}")
    elif isinstance(default, tuple):
        if (not isinstance(value, list) or not value
                or any(isinstance(v, bool) or not isinstance(v, int) or v < 1 for v in value)):
            raise SweepSpecError(f"key {key!r} must be a non-empty list of positive integers, got {value!r}")
        value = [int(v) for v in value]
    return value


_TRAIN_RANGES: dict[str, tuple[float, float, bool]] = {  # field: (low, high, low inclusive)
    "episodes": (1, float("inf"), True), "n_envs": (1, float("inf"), True),
    "n_steps": (1, float("inf"), True), "batch_size": (2, float("inf"), True),
    "n_epochs": (1, float("inf"), True), "learning_rate": (0, float("inf"), False),
    "gamma": (0, 1, False), "gae_lambda": (0, 1, True), "max_grad_norm": (0, float("inf"), False),
    "clip_range": (0, float("inf"), False), "ent_coef": (0, float("inf"), True),
    "vf_coef": (0, float("inf"), True), "warm_start_episodes": (1, float("inf"), True),
    "warm_start_epochs": (1, float("inf"), True), "warm_start_sinr_span_db": (0, float("inf"), False),
    "warm_start_shadow_estimator_episodes": (1, float("inf"), True),
}


def _check_ranges(section: str, values: dict[str, Any]) -> None:
    if section != "train":
        return  # env values: EnvConfig.validate() checks them per job
    for name, value in values.items():
        if name not in _TRAIN_RANGES:
            continue
        low, high, inclusive = _TRAIN_RANGES[name]
        if not (low <= value if inclusive else low < value) or value > high or value != value:
            bound = f"{'>=' if inclusive else '>'} {low:g}" + (f" and <= {high:g}" if high != float("inf") else "")
            raise SweepSpecError(f"key 'train.{name}' must be {bound}, got {value!r}")


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
