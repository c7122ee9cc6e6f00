"""Sweep files: read a TOML sweep, check every key and value, and build its ``SweepSpec``.

A sweep file (``sweeps/tiny.toml`` is a commented example)::

    name = "table1"                   # folder under --out-root (default: the file's stem)
    scenarios = ["straight", "circular"]   # or "all"
    seeds = [0, 1, 2]                 # or a count: seeds = 3 means 0, 1, 2
    [train]                           # TrainConfig fields: the budget and PPO hyper-parameters
    episodes = 12000
    warm_start.teacher = "aoa"        # the warm start's fields (WarmStartConfig) are nested
    [scenario_train.circular]         # TrainConfig fields for one scenario's jobs only
    n_envs = 64
    [env]                             # EnvConfig fields; radio.x / area.x reach the nested configs
    "radio.shadowing" = true
    [scenario_env.no_move]            # EnvConfig fields for one scenario's jobs only
    place_model = "kriging"
    [eval]
    episodes = 100                    # evaluation episodes per policy (PPO, static, oracle, aoa)
    seed = 0                          # evaluation seed: every policy meets the same episodes
    [grid]                            # lists: the sweep runs every combination
    "radio.aoa_noise_deg" = [0.0, 10.0]
    learning_rate = [1e-4, 3e-4]      # train.x / env.x prefixes are accepted too

Every problem (unknown key, bad value, empty grid) raises ``SweepSpecError`` with one line naming
the key, before any job starts. The ``[train]``, ``[scenario_train.NAME]``, ``[env]``,
``[scenario_env.NAME]`` and ``[grid]`` values are the fields of ``TrainConfig`` and ``EnvConfig``, typed by their annotations
(``uavlink.config.fields.coerce``) and checked by their ``validate()``, as ``uavlink train`` checks
its flags. The warm start's fields are nested (``warm_start.teacher``, or a ``[train.warm_start]``
table); the old flat spelling (``warm_start_teacher``) still reads as the same field.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

from uavlink.config import SCENARIO_NAMES, SCENARIOS, EnvConfig, TrainConfig
from uavlink.config.fields import coerce, resolve
from uavlink.config.train import legacy_warm_start_key
from uavlink.sweep.spec import SweepSpec, SweepSpecError, describe_point

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the sweep extra installs tomli on 3.10
    import tomli as tomllib

TOP_KEYS = (
    "name",
    "description",
    "scenarios",
    "seeds",
    "train",
    "scenario_train",
    "env",
    "scenario_env",
    "eval",
    "grid",
)
EVAL_DEFAULTS: dict[str, int] = {"episodes": 100, "seed": 0}
# Config fields a sweep does not set, and why.
TRAIN_FIXED = {
    "seed": "set the top-level 'seeds'",
    "torch_threads": "workers pin torch to 1 thread",
    "checkpoint_every_steps": "sweep jobs keep no checkpoints",
}
ENV_FIXED = {"scenario": "set the top-level 'scenarios'"}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def load_spec(path: str | Path) -> SweepSpec:
    """Read and check a sweep file; every job's configs are built once here, so bad values fail now."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SweepSpecError(f"{path}: no such sweep file") from None
    except IsADirectoryError:
        raise SweepSpecError(
            f"{path} is a folder; give a sweep file (e.g. sweeps/tiny.toml)"
        ) from None
    except OSError as exc:
        raise SweepSpecError(f"{path}: cannot read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
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
    for key in data:
        if key not in TOP_KEYS:
            raise SweepSpecError(f"unknown key {key!r} (allowed: {', '.join(TOP_KEYS)})")
    name = data.get("name", default_name)
    if not isinstance(name, str) or not _NAME.match(name):
        raise SweepSpecError(
            f"key 'name' must be a folder name (letters, digits, _ . -), got {name!r}"
        )
    description = data.get("description", "")
    if not isinstance(description, str):
        raise SweepSpecError("key 'description' must be a string")
    scenarios, seeds = _scenarios(data), _seeds(data)

    train = _section(_table(data, "train"), "train", ("train",))
    env = _section(_table(data, "env"), "env", ("env",))
    per_scenario: dict[str, dict[str, dict[str, Any]]] = {"train": {}, "env": {}}
    for section, tables in per_scenario.items():
        for scenario, table in _table(data, f"scenario_{section}").items():
            if scenario not in scenarios or not isinstance(table, dict):
                raise SweepSpecError(
                    f"[scenario_{section}] key {scenario!r} must be a table named after one "
                    f"of the sweep's scenarios ({', '.join(scenarios)})"
                )
            tables[scenario] = _section(table, f"scenario_{section}.{scenario}", (section,))
    grid = _grid(data, {"train": train, "env": env}, per_scenario)

    spec = SweepSpec(
        name,
        scenarios,
        seeds,
        train,
        env,
        _evaluation(data),
        grid,
        description,
        scenario_train=per_scenario["train"],
        scenario_env=per_scenario["env"],
    )
    for scenario in spec.scenarios:  # build every config: validate() names the field of a bad value
        for point in spec.points():
            where = f"scenario {scenario}" + (
                f", grid point {describe_point(point)}" if point else ""
            )
            try:
                spec.configs(scenario, point, spec.seeds[0])
            except (TypeError, ValueError) as exc:
                raise SweepSpecError(f"{exc} ({where})") from None
    return spec


def _scenarios(data: dict[str, Any]) -> list[str]:
    scenarios = data.get("scenarios", list(SCENARIOS))
    if scenarios == "all":
        scenarios = list(SCENARIOS)
    if not isinstance(scenarios, list) or not scenarios:
        raise SweepSpecError(
            "key 'scenarios' must be \"all\" or a non-empty list of scenario names"
        )
    for s in scenarios:
        if s not in SCENARIO_NAMES:
            raise SweepSpecError(
                f"key 'scenarios': unknown scenario {s!r}; choose from {', '.join(SCENARIO_NAMES)}"
            )
    if len(set(scenarios)) != len(scenarios):
        raise SweepSpecError("key 'scenarios' lists a scenario twice")
    return list(scenarios)


def _seeds(data: dict[str, Any]) -> list[int]:
    seeds = data.get("seeds", [0])
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise SweepSpecError(f"key 'seeds' as a count must be >= 1, got {seeds}")
        seeds = list(range(seeds))
    if (
        not isinstance(seeds, list)
        or not seeds
        or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds)
    ):
        raise SweepSpecError(
            f"key 'seeds' must be a count or a non-empty list of integers >= 0, got {seeds!r}"
        )
    if len(set(seeds)) != len(seeds):
        raise SweepSpecError("key 'seeds' lists a seed twice")
    return list(seeds)


def _evaluation(data: dict[str, Any]) -> dict[str, int]:
    evaluation = dict(EVAL_DEFAULTS)
    for key, value in _table(data, "eval").items():
        if key not in EVAL_DEFAULTS:
            raise SweepSpecError(
                f"[eval] unknown key {key!r} (allowed: {', '.join(EVAL_DEFAULTS)})"
            )
        if (
            isinstance(value, bool)
            or not isinstance(value, int)
            or value < (1 if key == "episodes" else 0)
        ):
            raise SweepSpecError(
                f"eval.{key} must be an integer >= {1 if key == 'episodes' else 0}, got {value!r}"
            )
        evaluation[key] = value
    return evaluation


def _grid(
    data: dict[str, Any],
    fixed: dict[str, dict[str, Any]],
    per_scenario: dict[str, dict[str, dict[str, Any]]],
) -> dict[str, list[Any]]:
    """[grid]'s values by qualified path; a key may not also be fixed in [train], [env] or a scenario's table."""
    grid: dict[str, list[Any]] = {}
    for key, values in _flatten(_table(data, "grid")).items():
        section, path = _qualify(key, "grid", ("train", "env"))
        qualified = f"{section}.{path}"
        if not isinstance(values, list):
            raise SweepSpecError(f"[grid] key {key!r} must be a list of values, got {values!r}")
        if not values:
            raise SweepSpecError(f"[grid] key {key!r} is empty: give at least one value")
        if path in fixed[section]:
            raise SweepSpecError(f"key {key!r} is set in both [{section}] and [grid]")
        if any(path in o for o in per_scenario[section].values()):
            raise SweepSpecError(f"key {key!r} is set in both [scenario_{section}] and [grid]")
        if qualified in grid:
            raise SweepSpecError(f"[grid] key {key!r} is given twice")
        coerced = [_coerce(section, path, v, f"[grid] key {key!r}") for v in values]
        if len({json.dumps(v) for v in coerced}) != len(coerced):
            raise SweepSpecError(f"[grid] key {key!r} repeats a value")
        grid[qualified] = coerced
    return grid


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


def _section(table: dict[str, Any], where: str, allow: tuple[str, ...]) -> dict[str, Any]:
    """A ``[train]``-like table's values by field path, typed as the fields are."""
    out: dict[str, Any] = {}
    for key, value in _flatten(table).items():
        section, path = _qualify(key, where, allow)
        if path in out:
            raise SweepSpecError(f"[{where}] key {key!r} sets {section}.{path} a second time")
        out[path] = _coerce(section, path, value, f"key '{where}.{key}'")
    return out


def _coerce(section: str, path: str, value: Any, label: str) -> Any:
    try:
        return coerce(TrainConfig if section == "train" else EnvConfig, path, value, label)
    except ValueError as exc:
        raise SweepSpecError(str(exc)) from None


def _train_path(key: str) -> str | None:
    """The TrainConfig field path a key names (the old flat ``warm_start_x`` too), else None."""
    if resolve(TrainConfig, key):
        return key
    legacy = legacy_warm_start_key(key)
    return None if legacy is None else f"warm_start.{legacy}"


def _env_path(key: str) -> str | None:
    """The EnvConfig field path a key names (a bare radio/area field too, as EnvConfig.replace), else None."""
    for path in (key, f"radio.{key}", f"area.{key}"):
        if resolve(EnvConfig, path):
            return path
    return None


def _qualify(key: str, where: str, allow: tuple[str, ...]) -> tuple[str, str]:
    """(section, field path) for a key as written: ``train.x``, ``env.x``, ``radio.x`` or a bare field."""
    head, _, tail = key.partition(".")
    if head in ("train", "env") and tail:
        section, name = head, tail
    else:  # a bare key: the table's own section, or in [grid] the config that has the field
        section, name = (
            (allow[0] if len(allow) == 1 else "train" if _train_path(key) else "env"),
            key,
        )
    path = _train_path(name) if section == "train" else _env_path(name)
    label = f"[{where}] key {key!r}"
    fixed = TRAIN_FIXED if section == "train" else ENV_FIXED
    if path in fixed:
        raise SweepSpecError(f"{label} cannot be set in a sweep: {fixed[path]}")
    if section not in allow or path is None:
        what = {
            "train": "a TrainConfig field (PPO hyper-parameter, budget, warm_start.x)",
            "env": "an EnvConfig field (radio.x and area.x for the nested ones)",
        }
        expected = " or ".join(what[s] for s in allow)
        raise SweepSpecError(f"{label} is unknown: not {expected}")
    return section, path
