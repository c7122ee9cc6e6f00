"""The code's shape, read from the source with ``ast`` (nothing is imported): no import cycle between
the project's modules (imports inside functions and ``if TYPE_CHECKING:`` blocks included), every
import allowed by the layering table below (the table of docs/design/code.md and the
packages' docstrings; type-only imports aside), no module over 480 lines and no folder with more
than 12 modules."""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("uavlink", "sitl_stub")
# 400 lines on the hand-wrapped tree; `ruff format` lays calls out one argument a line where they do
# not fit, which grew uavlink and sitl_stub by 20 % (17,885 -> 21,472 lines): the same cap in
# formatted lines.
MAX_LINES = 480
MAX_MODULES = 12

# Which unit may import which (besides itself). A unit is a package, a top-level module of uavlink,
# or sitl_stub's own modules (``sitl_stub``: its composition root) apart from ``sitl_stub.launcher``,
# which uavlink's flight starts and which imports neither side.
_BELOW_ENV = {
    "uavlink.config",
    "uavlink.errors",
    "uavlink.seeding",
    "uavlink.radio",
    "uavlink.mobility",
}
_BELOW_POLICIES = _BELOW_ENV | {"uavlink.env", "uavlink.rollout"}
MAY_IMPORT: dict[str, set[str]] = {
    "uavlink.errors": set(),
    "uavlink.seeding": set(),
    "uavlink.config": {"uavlink.errors"},
    "uavlink.radio": {"uavlink.config", "uavlink.errors"},
    "uavlink.mobility": {"uavlink.config", "uavlink.errors"},
    "uavlink.mavlink": {"uavlink.errors"},
    "uavlink.env": _BELOW_ENV,
    "uavlink.rollout": {"uavlink.config", "uavlink.errors", "uavlink.seeding", "uavlink.env"},
    "uavlink.policies": _BELOW_POLICIES,
    "uavlink.fleet": {"uavlink.config", "uavlink.errors", "uavlink.env"},
    "uavlink.export": _BELOW_POLICIES | {"uavlink.policies"},
    "uavlink.learn": _BELOW_POLICIES | {"uavlink.policies"},
    "uavlink.evaluation": _BELOW_POLICIES | {"uavlink.policies"},
    "uavlink.sweep": _BELOW_POLICIES | {"uavlink.policies", "uavlink.learn", "uavlink.evaluation"},
    "sitl_stub.launcher": set(),
    "sitl_stub.core": {"uavlink.config", "uavlink.mavlink"},
    "sitl_stub.flight": {"sitl_stub.core", "uavlink.config", "uavlink.errors"},
    "sitl_stub.sim": {
        "sitl_stub.core",
        "uavlink.config",
        "uavlink.errors",
        "uavlink.env",
        "uavlink.mavlink",
    },
    "sitl_stub.mavlink": {
        "sitl_stub.core",
        "sitl_stub.flight",
        "sitl_stub.sim",
        "uavlink.config",
        "uavlink.errors",
        "uavlink.mavlink",
    },
    "sitl_stub": {
        "sitl_stub.core",
        "sitl_stub.flight",
        "sitl_stub.sim",
        "sitl_stub.mavlink",
        "sitl_stub.launcher",
        "uavlink.config",
        "uavlink.errors",
        "uavlink.env",
        "uavlink.mavlink",
        "uavlink.mobility",
    },
    "uavlink.plot": {"uavlink.errors", "uavlink.mavlink"},
    "uavlink.flight": {
        "uavlink.config",
        "uavlink.errors",
        "uavlink.mobility",
        "uavlink.env",
        "uavlink.mavlink",
        "uavlink.policies",
        "uavlink.plot",
        "sitl_stub.launcher",
    },
    "uavlink": {"uavlink.config", "uavlink.env"},  # the package itself: registers the Gymnasium id
}
MAY_IMPORT["uavlink.cli"] = {u for u in MAY_IMPORT if u.startswith("uavlink")}
MAY_IMPORT["uavlink.__main__"] = {"uavlink.cli"}  # python -m uavlink


@cache
def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (path, is a package's __init__)."""
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            is_init = parts[-1] == "__init__"
            found[".".join(parts[:-1] if is_init else parts)] = (path, is_init)
    return found


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    skipped = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skipped.update(id(inner) for stmt in node.body for inner in ast.walk(stmt))
    return skipped


def _imports(modules: dict[str, tuple[Path, bool]], type_only: bool = False) -> dict[str, set[str]]:
    """Module -> the project modules it imports, anywhere in its body (functions too); with
    ``type_only``, the imports under ``if TYPE_CHECKING:`` too (a circle there is still two modules
    that need each other to be read)."""
    return _graph(tuple(modules.items()), type_only)


@cache
def _graph(
    items: tuple[tuple[str, tuple[Path, bool]], ...], type_only: bool
) -> dict[str, set[str]]:
    modules = dict(items)

    def owner(name: str) -> str | None:  # the project module that ``name`` is or lies in
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, (path, is_init) in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        skipped = set() if type_only else _type_checking_nodes(tree)
        targets = set()
        for node in ast.walk(tree):
            if id(node) in skipped:
                continue
            if isinstance(node, ast.Import):
                targets.update(owner(alias.name) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    package = name.split(".") if is_init else name.split(".")[:-1]
                    base = ".".join(
                        package[: len(package) - node.level + 1] + ([base] if base else [])
                    )
                # ``from a.b import c`` imports the module a.b.c where there is one, else a.b
                targets.update(
                    owner(f"{base}.{alias.name}")
                    if f"{base}.{alias.name}" in modules
                    else owner(base)
                    for alias in node.names
                )
        graph[name] = {t for t in targets if t is not None and t != name}
    return graph


def _unit(module: str) -> str:
    parts = module.split(".")
    if module == "sitl_stub.launcher" or len(parts) == 1:
        return module
    if parts[0] == "sitl_stub":
        is_package = (ROOT / "sitl_stub" / parts[1]).is_dir()
        return f"sitl_stub.{parts[1]}" if is_package else "sitl_stub"
    return f"uavlink.{parts[1]}"


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one member (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_graph_sees_imports_inside_functions_and_skips_type_checking() -> None:
    graph = _imports(_modules())
    # uavlink.cli's commands import what runs them inside the functions that run them
    cli = set().union(*(targets for name, targets in graph.items() if _unit(name) == "uavlink.cli"))
    assert {"uavlink.learn.training", "uavlink.evaluation.report", "uavlink.flight.fly"} <= cli
    assert "sitl_stub.launcher" in graph["uavlink.flight.vehicles"]  # inside started_vehicle()
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycle_type_only_ones_included() -> None:
    assert _cycles(_imports(_modules(), type_only=True)) == []


def test_every_import_follows_the_layering() -> None:
    graph = _imports(_modules())
    units = {_unit(m) for m in graph}
    assert units <= set(MAY_IMPORT), (
        f"place these in MAY_IMPORT (and docs/design/code.md): {units - set(MAY_IMPORT)}"
    )
    assert _cycles(MAY_IMPORT) == []  # the table itself is a layering
    wrong = sorted(
        f"{m} -> {t}"
        for m, targets in graph.items()
        for t in targets
        if _unit(t) != _unit(m) and _unit(t) not in MAY_IMPORT[_unit(m)]
    )
    assert wrong == []


def test_small_modules_and_folders() -> None:
    modules = _modules()
    long = {
        name: n
        for name, (path, _) in modules.items()
        if (n := len(path.read_text().splitlines())) > MAX_LINES
    }
    assert long == {}
    per_folder: dict[Path, int] = {}
    for path, _ in modules.values():
        per_folder[path.parent] = per_folder.get(path.parent, 0) + 1
    crowded = {
        str(folder.relative_to(ROOT)): n for folder, n in per_folder.items() if n > MAX_MODULES
    }
    assert crowded == {}


def test_every_package_says_what_it_holds_and_may_import() -> None:
    for name, (path, is_init) in _modules().items():
        if is_init and name not in PACKAGES:
            doc = ast.get_docstring(ast.parse(path.read_text())) or ""
            assert "May import" in doc, name
