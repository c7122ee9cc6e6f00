"""The docs site stays true to the code: every SPEC citation in the tree names a heading of the
repository's specification (docs/spec.md), the generated CLI and config references cover every
sub-command, option and config field, the README's links resolve, and nothing refers to a
specification outside the repository. The reference text is built in-process with the MkDocs hook's
own functions (docs/hooks/reference.py); one slow test runs ``mkdocs build --strict``."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys

import pytest
from support.cli import ROOT

from sitl_stub.__main__ import build_parser as sitl_parser
from uavlink.cli import build_parser as uavlink_parser
from uavlink.config import EnvConfig, TrainConfig
from uavlink.config.fields import field_paths

SPEC_PAGE = ROOT / "docs" / "spec.md"
# A citation: the word, then one quoted heading or two joined by "and"; a Python comment may wrap it.
CITATION = re.compile(r'\bSPEC\s+"([^"]+)"(?:\s+and\s+"([^"]+)")?')
SKIP_DIRS = {".git", ".venv", "site", "build", "runs", "results", "__pycache__", "node_modules"}
TEXT = {".py", ".md", ".toml", ".yml", ".yaml", ".cfg", ".txt", ".json"}


def _hook():
    spec = importlib.util.spec_from_file_location(
        "docs_reference_hook", ROOT / "docs/hooks/reference.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _files():
    for path in sorted(ROOT.rglob("*")):
        rel = path.relative_to(ROOT)
        if any(part in SKIP_DIRS or part.endswith(".egg-info") for part in rel.parts):
            continue
        if path.is_file() and (path.suffix in TEXT or path.name in ("Makefile", "README.md")):
            yield rel.as_posix(), path.read_text(errors="replace")


def _normal(text: str) -> str:
    """A citation as one line: a wrap, with a Python comment's `#`, becomes one space."""
    return re.sub(r"\s+", " ", re.sub(r"\n\s*#?\s*", " ", text)).strip()


def spec_headings() -> set[str]:
    """Every heading of docs/spec.md, as text (backticks dropped)."""
    found = re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", SPEC_PAGE.read_text(), re.M)
    return {h.replace("`", "").strip() for h in found}


def citations() -> list[tuple[str, str]]:
    out = []
    for rel, text in _files():
        for match in CITATION.finditer(text):
            out += [(rel, _normal(name)) for name in match.groups() if name]
    return out


@pytest.mark.slow
def test_every_spec_citation_names_a_heading_of_the_spec_page() -> None:
    found = citations()
    assert len(found) >= 30, found  # the search still finds the tree's citations
    headings = spec_headings()
    missing = sorted({(rel, name) for rel, name in found if name not in headings})
    assert not missing, f"SPEC citations naming no heading of docs/spec.md: {missing}"


def test_the_spec_page_has_the_sections_the_project_needs() -> None:
    headings = spec_headings()
    for name in (
        "Radio model",
        "UE mobility scenarios",
        "The learning problem",
        "Observation",
        "Action",
        "Reward",
        "Baselines every evaluation reports",
        "A spatially consistent channel",
        "The limit, and a memory of place",
        "A fleet",
        "What the paper reports",
    ):
        assert name in headings, sorted(headings)


@pytest.mark.slow
def test_nothing_refers_to_a_specification_outside_the_repository() -> None:
    outside = "../" + "shared"  # spelled apart, so this file does not match itself
    found = [rel for rel, text in _files() if outside in text]
    assert not found, found


def test_the_cli_reference_covers_every_subcommand_and_option() -> None:
    hook = _hook()
    text = hook.cli_reference()
    commands = hook.subcommands(uavlink_parser())
    assert {"evaluate", "train", "fly", "plot", "export", "sweep", "keygen"} <= set(commands)
    for name, parser in [
        *((f"uavlink {n}", p) for n, p in commands.items()),
        ("sitl-stub", sitl_parser()),
    ]:
        assert f"`{name}`" in text, name
        section = text.split(f"`{name}`", 1)[1]
        for action in parser._actions:  # noqa: SLF001
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}" in section or f", {option}" in section, (name, option)


def test_the_config_reference_covers_every_field() -> None:
    text = _hook().config_reference()
    for cls in (EnvConfig, TrainConfig):
        for path in field_paths(cls):
            assert f"| `{path}` |" in text, path
    assert "`--set radio.shadowing_model=...`" in text
    assert "`--warm-start-episodes`" in text  # a nested training field's flag


def test_the_reference_pages_carry_the_hooks_markers() -> None:
    hook = _hook()
    for page, name in (("cli", "cli"), ("config", "config")):
        markdown = (ROOT / "docs" / "reference" / f"{page}.md").read_text()
        assert f"<!-- generated: {name} -->" in markdown
        assert "<!-- generated" not in hook.expand(markdown)


def test_the_readmes_links_resolve_and_it_stays_a_front_door() -> None:
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 150
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme) + re.findall(
        r'src="([^"]+)"', readme
    )
    assert targets
    for target in targets:
        if "://" not in target:
            assert (ROOT / target).exists(), target


@pytest.mark.slow  # builds the whole site, mkdocstrings included (~10 s)
def test_the_site_builds_strictly(tmp_path) -> None:
    pytest.importorskip("mkdocs")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-4000:]
    assert (tmp_path / "site" / "reference" / "cli" / "index.html").exists()
