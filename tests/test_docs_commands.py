"""The commands the current docs give (README.md and every page of the docs site under docs/, but the
experiment log) parse: each ``uavlink ...`` and ``sitl-stub ...`` in a code span or block goes
through its program's real parser, so a renamed or removed flag fails here rather than in a
reader's shell. Commands with
placeholders (``S``, ``DIR``, ``...``) are left out; nothing is run."""

from __future__ import annotations

import contextlib
import io
import re
import shlex

import pytest
from support.cli import ROOT, cli_json

from sitl_stub.__main__ import build_parser as sitl_parser
from uavlink.cli import build_parser as uavlink_parser

# README.md and every Markdown page under docs/ (the site's pages)
DOCS = [
    "README.md",
    *sorted(path.relative_to(ROOT).as_posix() for path in (ROOT / "docs").rglob("*.md")),
]
PROGRAMS = {"uavlink": uavlink_parser, "sitl-stub": sitl_parser}
PLACEHOLDER = re.compile(r"^[A-Z][A-Z0-9_]*$|\.\.\.|[<>\[\]{}|]|^-?[A-Z]$|^[A-Z]\+")


def _commands(text: str) -> list[str]:
    """``uavlink``/``sitl-stub`` commands in code spans (joined across lines) and code blocks."""
    blocks = re.findall(r"```[a-z]*\n(.*?)```", text, re.S)
    prose = re.sub(r"```[a-z]*\n.*?```", "", text, flags=re.S)
    found = [re.sub(r"\s+", " ", span).strip() for span in re.findall(r"`([^`]+)`", prose)]
    for block in blocks:
        found += [line.split(" #")[0].strip() for line in block.replace("\\\n", " ").splitlines()]
    return [c for c in found if c.split(" ", 1)[0] in PROGRAMS and " " in c]


def _fragment(words: list[str]) -> bool:
    """A mention rather than a command: a bare sub-command (`uavlink plot`), or one that ends on an
    option whose value the sentence goes on to give (`uavlink evaluate --seed`)."""
    parser = PROGRAMS[words[0]]()
    if words[0] == "uavlink":
        if len(words) < 3:
            return True
        parser = parser._subparsers._group_actions[0].choices.get(words[1], parser)  # noqa: SLF001
    action = parser._option_string_actions.get(words[-1])  # noqa: SLF001
    return action is not None and action.nargs != 0


def _concrete() -> list[tuple[str, str]]:
    out = []
    for doc in DOCS:
        for command in _commands((ROOT / doc).read_text()):
            try:
                words = shlex.split(command)
            except ValueError:
                continue
            if not any(PLACEHOLDER.search(w) for w in words[1:]) and not _fragment(words):
                out.append((doc, command))
    return sorted(set(out))


COMMANDS = _concrete()


def test_the_docs_give_commands_to_check():
    assert len(COMMANDS) >= 40, COMMANDS  # the extraction still finds the docs' commands
    pages = {doc for doc, _ in COMMANDS}
    for page in ("README.md", "docs/get-started/first-flight.md", "docs/guides/flying.md"):
        assert page in pages, sorted(pages)  # the site's pages are read, not only the README


@pytest.mark.parametrize(("doc", "command"), COMMANDS)
def test_a_command_in_the_docs_parses(doc: str, command: str) -> None:
    program, *argv = shlex.split(command)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            PROGRAMS[program]().parse_args(argv)
        except SystemExit as exc:
            assert exc.code == 0, f"{doc}: `{command}`: {err.getvalue().strip()}"


PYTHON_PAGE = "docs/reference/api/index.md"  # the Python API's front page (was README.md's)


@pytest.mark.slow  # loads a policy (torch)
def test_the_api_pages_python_runs_and_prints_what_the_cli_prints(monkeypatch) -> None:
    """The Python API page's blocks, run from the repository root; the shipped policy's figure is
    the one its comment gives, `uavlink evaluate --policy policies/circular.zip --episodes 3`'s."""
    monkeypatch.chdir(ROOT)
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / PYTHON_PAGE).read_text(), re.S)
    assert len(blocks) >= 2
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        for block in blocks:
            exec(compile(block, PYTHON_PAGE, "exec"), {})  # noqa: S102 - the page's own code
    printed = out.getvalue().split()
    # the figure the README's comment gives, and what the CLI gives for the same episodes
    [quoted] = re.findall(
        r"print\(rate\)  # (\d+\.\d{6}) to 6 decimals", (ROOT / PYTHON_PAGE).read_text()
    )
    cli = cli_json(
        "evaluate", "--policy", "policies/circular.zip", "--episodes", "3", "--seed", "0", "--json"
    )
    assert round(float(printed[0]), 6) == float(quoted) == cli["mean_rate_mbps"], (
        printed,
        quoted,
        cli,
    )
    assert 4.0 < float(printed[1]) < 8.0, printed


FLEET_PAGE = "docs/guides/fleets.md"


@pytest.mark.slow  # flies a fleet episode, and the CLI's evaluation of it
def test_the_fleet_guides_python_flies_a_shipped_policy_as_evaluate_does(monkeypatch) -> None:
    """The fleet guide's blocks: a PettingZoo episode of the shipped any-size hotspot policy at D = 3
    gives the figure its comment quotes, which is `uavlink evaluate`'s for the same episode."""
    monkeypatch.chdir(ROOT)
    text = (ROOT / FLEET_PAGE).read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 2
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        for block in blocks:
            exec(compile(block, FLEET_PAGE, "exec"), {})  # noqa: S102 - the page's own code
    printed = out.getvalue().split("\n")
    assert printed[0] == "['uav_0', 'uav_1']"
    [quoted] = re.findall(r"# (\d+\.\d{6}) Mbps, as the evaluation", text)
    cli = cli_json(
        "evaluate",
        "--policy",
        "fleet/hotspot",
        "--set",
        "n_uavs=3",
        "--episodes",
        "1",
        "--seed",
        "0",
        "--json",
    )
    assert float(printed[1]) == float(quoted) == cli["mean_rate_mbps"], (printed, quoted, cli)
