"""MkDocs hook: the CLI and config reference pages, generated at build time from the code.

``docs/reference/cli.md`` and ``docs/reference/config.md`` carry a marker (an HTML comment such as
``<!-- generated: cli -->``); ``on_page_markdown`` replaces it with text built from the argparse
parsers (``uavlink.cli.build_parser``, ``sitl_stub.__main__.build_parser``) and the config
dataclasses (``uavlink.config``: each field's default, type, range, flag and help). Nothing generated
is committed, so nothing goes stale; ``tests/test_docs_site.py`` calls the same functions.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import io
import os
import re
import sys
import tokenize
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `mkdocs build` from the repository root without an install
    sys.path.insert(0, str(ROOT))

MARKER = re.compile(r"<!--\s*generated:\s*(\w+)\s*-->")
WIDTH = "100"  # argparse wraps help at $COLUMNS: fix it, so the page is the same everywhere


def _cell(text: Any) -> str:
    """Text for a Markdown table cell: one line, pipes escaped."""
    return re.sub(r"\s+", " ", str(text)).replace("|", "\\|").strip()


def _code(text: str) -> str:
    return f"`{text}`" if text else ""


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """A parser's sub-commands by name, in the order they were added ({} if it has none)."""
    for action in parser._actions:  # noqa: SLF001 - argparse keeps them nowhere public
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            return dict(action.choices.items())
    return {}


def _default(action: argparse.Action) -> Any:
    """An option's default as the table shows it: blank where it has none (None, a flag's False,
    SUPPRESS; 0 and 0.0 are shown, ``0 == False`` notwithstanding), the form in effect for a
    ``--x/--no-x`` pair, blank for the other flags (``store_true``, ``store_const``, ``count``)."""
    default = action.default
    if default is None or default is False or default is argparse.SUPPRESS:
        return ""
    if isinstance(action, argparse.BooleanOptionalAction):
        on, off = (o for o in action.option_strings if o.startswith("--"))
        return on if default else off
    return "" if action.nargs == 0 else default


def _options_table(parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()  # noqa: SLF001
    rows = ["| option | value | default | what |", "|---|---|---|---|"]
    for action in parser._actions:  # noqa: SLF001
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):  # noqa: SLF001
            continue
        if action.help == argparse.SUPPRESS:
            continue
        names = ", ".join(action.option_strings) or action.dest
        if action.option_strings and action.nargs != 0:
            value = formatter._format_args(action, action.dest.upper())  # noqa: SLF001
        elif not action.option_strings:
            value = formatter._format_args(action, action.dest)  # noqa: SLF001
        else:
            value = ""
        shown = _default(action)
        help_text = formatter._expand_help(action) if action.help else ""  # noqa: SLF001
        rows.append(
            f"| {_code(_cell(names))} | {_code(_cell(value))} | {_code(_cell(shown))} "
            f"| {_cell(help_text)} |"
        )
    return rows


def _usage(parser: argparse.ArgumentParser) -> str:
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        return parser.format_usage().strip()
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def _command_section(title: str, parser: argparse.ArgumentParser, level: str) -> list[str]:
    lines = [f"{level} `{title}`", ""]
    if parser.description:
        lines += [parser.description.strip(), ""]
    lines += ["```text", _usage(parser), "```", "", *_options_table(parser), ""]
    if parser.epilog:
        lines += [parser.epilog.strip(), ""]
    return lines


def cli_reference() -> str:
    """Markdown for every ``uavlink`` sub-command and for ``sitl-stub``, from their parsers."""
    from sitl_stub.__main__ import build_parser as sitl_parser
    from uavlink.cli import build_parser as uavlink_parser

    top = uavlink_parser()
    lines = [
        "## `uavlink`",
        "",
        (top.description or "").strip(),
        "",
        "```text",
        _usage(top),
        "```",
        "",
    ]
    for name, sub in subcommands(top).items():
        lines += _command_section(f"uavlink {name}", sub, "###")
    lines += _command_section("sitl-stub", sitl_parser(), "##")
    return "\n".join(lines)


def field_comments(cls: type) -> dict[str, str]:
    """A dataclass's field comments from its source: the ``#`` lines just above a field and the one
    at the end of its line, joined (what a field declared without ``setting(help=...)`` says)."""
    source = inspect.getsource(cls)
    comments: dict[int, str] = {}
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            comments[token.start[0]] = token.string.lstrip("#").strip()
    out: dict[str, str] = {}
    lines = source.splitlines()
    for number, line in enumerate(lines, start=1):
        match = re.match(r"\s{4}(\w+)\s*:", line)
        if not match or line.strip().startswith("#"):
            continue
        above, k = [], number - 1
        while k in comments and lines[k - 1].strip().startswith("#"):
            above.insert(0, comments[k])
            k -= 1
        inline = comments.get(number) if not line.strip().startswith("#") else None
        out[match.group(1)] = " ".join([*above, *([inline] if inline else [])])
    return out


def env_choices() -> dict[str, tuple[str, ...]]:
    """The named values of the env's string fields (``uavlink.config.env``'s tuples)."""
    from uavlink.config import env

    return {
        "scenario": env.SCENARIO_NAMES,
        "uav_motion": env.UAV_MOTIONS,
        "action_mapping": env.ACTION_MAPPINGS,
        "place_model": env.PLACE_MODELS,
        "fleet_reuse": env.FLEET_REUSE,
        "radio.shadowing_model": env.SHADOWING_MODELS,
    }


def _range(meta: Any, choices: tuple[str, ...] | None = None) -> str:
    choices = meta.get("choices") or choices
    if choices:
        return ", ".join(f"`{c}`" if c else "`''` (none)" for c in choices)
    low, high = meta.get("low"), meta.get("high")
    if low is None and high is None:
        return ""
    left = "(" if meta.get("low_open") else "["
    return f"{left}{_bound(low, '-inf')}, {_bound(high, 'inf')}]"


def _bound(value: Any, unbounded: str) -> str:
    """A range's end: an int exactly (a seed's 2147483647, not 2.14748e+09), a float by ``:g``."""
    if value is None:
        return unbounded
    return str(value) if isinstance(value, int) else f"{value:g}"


def _type_name(hint: Any) -> str:
    return getattr(hint, "__name__", None) or str(hint).replace("typing.", "")


def config_rows(cls: type, how: str, prefix: str = "", flag_prefix: str = "") -> list[str]:
    """Table rows for every field of a config dataclass, nested ones flattened as dotted keys.
    ``how``: ``"set"`` (set with ``--set key=value``) or ``"flag"`` (its own option)."""
    from uavlink.config.fields import config_fields

    notes = field_comments(cls)
    rows = []
    for field, hint in config_fields(cls):
        key = prefix + field.name
        if dataclasses.is_dataclass(hint):
            rows += config_rows(hint, how, key + ".", f"{flag_prefix}{field.name}_")
            continue
        meta = field.metadata
        default = field.default
        if how == "flag":
            flag = meta.get("flag") or "--" + (flag_prefix + field.name).replace("_", "-")
            setter = f"`{flag}`"
        else:
            setter = f"`--set {key}=...`"
        paper = " (the paper's value)" if meta.get("paper") else ""
        what = meta.get("help") or notes.get(field.name, "")
        rows.append(
            f"| `{key}` | {_cell(_type_name(hint))} | `{_cell(repr(default))}` "
            f"| {_cell(_range(meta, env_choices().get(key)))} | {setter} | {_cell(what)}{paper} |"
        )
    return rows


def config_reference() -> str:
    """Markdown tables of the env's and the training's config fields, from ``uavlink.config``."""
    from uavlink.config import EnvConfig, TrainConfig

    head = ["| key | type | default | range | set with | what |", "|---|---|---|---|---|---|"]
    parts = []
    for cls, how in ((EnvConfig, "set"), (TrainConfig, "flag")):
        doc = inspect.getdoc(cls) or ""
        parts += [
            f"## `{cls.__module__.rsplit('.', 1)[0]}.{cls.__name__}`",
            "",
            doc,
            "",
            *head,
            *config_rows(cls, how),
            "",
        ]
    return "\n".join(parts)


GENERATORS = {"cli": cli_reference, "config": config_reference}


def expand(markdown: str) -> str:
    """``markdown`` with each ``<!-- generated: NAME -->`` marker replaced by its generated text."""
    return MARKER.sub(lambda m: GENERATORS[m.group(1)](), markdown)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:  # noqa: ARG001
    return expand(markdown)
