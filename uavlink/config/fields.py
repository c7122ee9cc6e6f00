"""Config fields that carry their own help, range and flag; everything else is derived from them.

A field declared with ``setting(default, help, ...)`` holds, in one place, what the command line
(``add_options`` / ``from_options``), sweep files (``coerce``, ``resolve``) and ``validate()``
(``check_fields``) need: its default, help text, type (the annotation), range and flag. Nested
config dataclasses (``nested``) get their fields' flags prefixed: ``warm_start.episodes`` is
``--warm-start-episodes``. Imports nothing heavy: ``import uavlink.config`` stays light.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import math
import types
from collections.abc import Callable
from functools import cache
from typing import Any, TypeGuard, Union, get_args, get_origin, get_type_hints

from uavlink.errors import ConfigError

Namer = Callable[[str], str]  # field path ("warm_start.episodes") -> how the user wrote it


def setting(
    default: Any,
    help: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    flag: str | None = None,
    metavar: str | None = None,
    choices: tuple[str, ...] | None = None,
    paper: bool = False,
) -> Any:
    """A config field: its default and help, the range ``validate()`` checks ([low, high]; (low, high]
    with ``low_open``; an optional field may also be None), its flag (default ``--field-name``), and
    ``paper``: the value is the paper's, not our choice."""
    meta = {
        "help": help,
        "low": low,
        "high": high,
        "low_open": low_open,
        "flag": flag,
        "metavar": metavar,
        "choices": choices,
        "paper": paper,
    }
    return dataclasses.field(default=default, metadata=meta)


def bounded(default: Any, *, low: float, high: float | None = None, low_open: bool = False) -> Any:
    """A config field with only a range (``setting``'s, which ``check_fields`` checks and the config
    reference lists), its help kept in the comment above it."""
    return dataclasses.field(
        default=default, metadata={"low": low, "high": high, "low_open": low_open}
    )


def nested(cls: type, help: str) -> Any:
    """A field holding another config dataclass; its fields' flags carry this field's name."""
    return dataclasses.field(default_factory=cls, metadata={"help": help})


@cache
def _hints(cls: type) -> dict[str, Any]:
    return get_type_hints(cls)


def _is_config(hint: Any) -> TypeGuard[type]:
    """Whether an annotation names a nested config dataclass (annotations are classes, so a
    dataclass here is a class: the guard tells the type checker so)."""
    return dataclasses.is_dataclass(hint)


def _group(cls: type, path: str) -> type | None:
    """The nested config dataclass a dotted path names (``area``), or None if it names none."""
    head, _, tail = path.partition(".")
    hint = _hints(cls).get(head)
    if not _is_config(hint):
        return None
    return _group(hint, tail) if tail else hint


def _a(cls: type) -> str:
    """``an AreaConfig``, ``a RadioConfig``."""
    return f"{'an' if cls.__name__[0] in 'AEIOU' else 'a'} {cls.__name__}"


def kind(hint: Any) -> tuple[Any, bool]:
    """(base type, optional) of an annotation: ``int | None`` -> (int, True)."""
    if get_origin(hint) in (Union, types.UnionType):
        args = [a for a in get_args(hint) if a is not type(None)]
        return args[0], True
    return (tuple if get_origin(hint) is tuple else hint), False


def config_fields(cls: type) -> list[tuple[dataclasses.Field, Any]]:
    """(field, annotation) of every field of a config dataclass, in declaration order."""
    return [(f, _hints(cls)[f.name]) for f in dataclasses.fields(cls)]


def field_paths(cls: type, prefix: str = "") -> list[str]:
    """Every settable dotted path of a config dataclass (``radio.shadowing``), in declaration order."""
    paths = []
    for f, hint in config_fields(cls):
        nested_cls = hint if _is_config(hint) else None
        paths += field_paths(nested_cls, f"{prefix}{f.name}.") if nested_cls else [prefix + f.name]
    return paths


def resolve(cls: type, path: str) -> tuple[type, str] | None:
    """(the dataclass that owns it, field name) for a dotted field path, or None if there is none."""
    head, _, tail = path.partition(".")
    hint = _hints(cls).get(head)
    if hint is None:
        return None
    if _is_config(hint):
        return resolve(hint, tail) if tail else None
    return None if tail else (cls, head)


_WHAT = {
    bool: "true or false",
    int: "an integer",
    float: "a number",
    str: "a string",
    tuple: "a non-empty list of positive integers",
}


def coerce(cls: type, path: str, value: Any, label: str) -> Any:
    """``value`` as the field at ``path`` of ``cls`` takes it (ints become floats where the field is
    a float, a list becomes a tuple); a ``ConfigError`` naming ``label`` if it has the wrong type."""
    found = resolve(cls, path)
    if found is None:
        group = _group(cls, path)
        if (
            group is not None
        ):  # a nested config's own name: it takes that config, or its fields one by one
            first = dataclasses.fields(group)[0].name
            raise ConfigError(
                f"{label} is a nested config: pass {_a(group)}, or set its fields one by one "
                f"({label}.{first}=...), got {value!r}"
            )
        near = difflib.get_close_matches(path, field_paths(cls), n=3, cutoff=0.6)
        hint = (
            f"did you mean {' or '.join(near)}?"
            if near
            else f"the keys: the fields of {cls.__module__}.{cls.__name__}"
        )
        raise ConfigError(f"unknown config key {label!r} ({hint})")
    owner, name = found
    base, optional = kind(_hints(owner)[name])
    if value is None and optional:
        return None
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if base is bool:
        ok = isinstance(value, bool)
    elif base is int:
        ok = number and isinstance(value, int)
    elif base is float:
        ok, value = number, float(value) if number else value
    elif base is tuple:
        ok = (
            isinstance(value, (list, tuple))
            and len(value) > 0
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in value)
        )
        value = tuple(value) if ok else value
    else:
        ok = isinstance(value, base)
    if not ok:
        raise ConfigError(f"{label} must be {_WHAT.get(base, base.__name__)}, got {value!r}")
    return value


def check_fields(config: Any, name: Namer) -> None:
    """Type (``coerce``'s check, the value shown by repr) and range of every field, as ``setting``
    declared them; a nested config must be its dataclass (its own ``validate()`` checks its fields)."""
    for f, hint in config_fields(type(config)):
        value, path = getattr(config, f.name), f.name
        if _is_config(hint):
            if not isinstance(value, hint):
                raise ConfigError(f"{name(path)} must be {_a(hint)}, got {value!r}")
            continue
        coerce(type(config), f.name, value, name(path))
        low, high, low_open = (
            f.metadata.get("low"),
            f.metadata.get("high"),
            f.metadata.get("low_open"),
        )
        choices = f.metadata.get("choices")
        if value is None or isinstance(value, (bool, str, tuple)):
            if choices is not None and value not in choices:
                raise ConfigError(
                    f"{name(path)} must be one of {', '.join(map(repr, choices))}, got {value!r}"
                )
            continue
        if not math.isfinite(value):
            raise ConfigError(f"{name(path)} must be a finite number, got {value!r}")
        if low is not None and (value <= low if low_open else value < low):
            positive = (low == 0 and low_open) or (low == 1 and isinstance(value, int))
            bound = "positive" if positive else f"{'>' if low_open else '>='} {low:g}"
            raise ConfigError(f"{name(path)} must be {bound}, got {value!r}")
        if high is not None and value > high:
            raise ConfigError(
                f"{name(path)} must be <= {high if isinstance(high, int) else format(high, 'g')}, got {value!r}"
            )


def with_changes(config: Any, changes: dict[str, Any]) -> Any:
    """A copy of a (nested) config dataclass with fields changed by dotted path."""
    top: dict[str, Any] = {}
    inner: dict[str, dict[str, Any]] = {}
    for path, value in changes.items():
        head, _, tail = path.partition(".")
        if tail:
            inner.setdefault(head, {})[tail] = value
        else:
            top[head] = value
    for head, sub in inner.items():
        top[head] = with_changes(getattr(config, head), sub)
    return dataclasses.replace(config, **top)


def flag_of(cls: type, path: str, prefix: str = "") -> str:
    """The command-line flag of the field at ``path`` (``warm_start.episodes``)."""
    head, _, tail = path.partition(".")
    if tail:
        return flag_of(_hints(cls)[head], tail, f"{prefix}{head}_")
    field = next(f for f in dataclasses.fields(cls) if f.name == head)
    return field.metadata.get("flag") or "--" + (prefix + head).replace("_", "-")


class _OrOff(tuple):
    """argparse choices that also take ``""`` (a field's "off", its default) without naming it where
    argparse lists the choices (``invalid choice: 'x' (choose from 'aoa', ...)``)."""

    def __contains__(self, value: object) -> bool:
        return value == "" or tuple.__contains__(self, value)


def add_options(parser: argparse.ArgumentParser, cls: type, prefix: str = "") -> None:
    """One option per field of ``cls`` (nested configs' fields prefixed), with the field's default
    and help; ``from_options`` turns the parsed namespace back into the config."""
    defaults = cls()
    for f, hint in config_fields(cls):
        if _is_config(hint):
            add_options(parser, hint, f"{prefix}{f.name}_")
            continue
        default, meta = getattr(defaults, f.name), f.metadata
        base, _ = kind(hint)
        shown = "" if default in (None, "") else " (default: %(default)s)"
        if isinstance(default, tuple):  # as it is typed: 128 128 128
            shown = f" (default: {' '.join(map(str, default))})"
        options: dict[str, Any] = {
            "dest": prefix + f.name,
            "default": default,
            "help": meta["help"] + shown,
        }
        if base is bool:
            options["action"] = argparse.BooleanOptionalAction
        elif base is tuple:
            options.update(nargs="+", type=int, metavar="N")
        else:
            options["type"] = base
        for key in ("metavar", "choices"):
            if meta.get(key) is not None:
                options[key] = meta[key]
        if "" in options.get("choices", ()):
            options["choices"] = _OrOff(c for c in options["choices"] if c)
        parser.add_argument(
            meta.get("flag") or "--" + (prefix + f.name).replace("_", "-"), **options
        )


def from_options(cls: type, args: argparse.Namespace, prefix: str = "") -> Any:
    """The config ``add_options``' flags describe, from the parsed namespace (not yet validated)."""
    values = {}
    for f, hint in config_fields(cls):
        if _is_config(hint):
            values[f.name] = from_options(hint, args, f"{prefix}{f.name}_")
        else:
            value = getattr(args, prefix + f.name)
            values[f.name] = tuple(value) if isinstance(value, list) else value
    return cls(**values)


SEED_MAX = (
    2**31 - 1
)  # a run's seed is 0..SEED_MAX: the vehicle reports a flight's in an int32 (NAMED_VALUE_INT)


def check_seed(value: int, label: str = "seed") -> int:
    """``value`` if it is a seed every seeded part takes (0..SEED_MAX), else a one-line ConfigError."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= SEED_MAX:
        raise ConfigError(f"{label} must be an integer in 0..{SEED_MAX}, got {value!r}")
    return value
