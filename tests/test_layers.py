"""The floors of the house (issue 29): engine imports point down only, and no module of the
engine or the service closes a circle of imports.

Every import counts, at the top of a module or inside a function, ``TYPE_CHECKING`` blocks
included: a function-local import that breaks a circle only hides a room in the wrong place.
The engine's floors, bottom to top: ``model`` (what a linkage is), ``catalogue`` (named linkages,
built from the model), ``local`` (one configuration), ``space`` (whole configuration spaces),
``design`` (from spaces to decisions)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FLOORS = ("model", "catalogue", "local", "space", "design")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for top in ("engine", "service") for p in (ROOT / top).rglob("*.py")}


def imports_of(path: Path, known: set[str]) -> set[str]:
    """The project's modules that ``path`` imports (a name imported from a package resolves
    to the package's submodule of that name where there is one)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name in known}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module not in known:
                continue
            for a in node.names:
                sub = f"{node.module}.{a.name}"
                out.add(sub if sub in known else node.module)
    return out


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports_of(path, known) - {name} for name, path in mods.items()}


def floor(name: str) -> int:
    parts = name.split(".")
    if parts[0] != "engine" or len(parts) == 1:
        return -1
    return FLOORS.index(parts[1])


def test_every_engine_module_lives_on_a_floor():
    stray = [n for n in modules() if n.startswith("engine.") and n.split(".")[1] not in FLOORS]
    assert not stray, f"engine modules outside the floors {FLOORS}: {stray}"


def test_engine_imports_point_down():
    up = [f"{a} -> {b}" for a, targets in graph().items() if a.startswith("engine")
          for b in targets if b.startswith("engine") and floor(b) > floor(a)]
    assert not up, f"imports that point up a floor: {up}"


def test_service_is_above_the_engine():
    up = [f"{a} -> {b}" for a, targets in graph().items() if a.startswith("engine")
          for b in targets if b.startswith("service")]
    assert not up, up


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return found


@pytest.mark.parametrize("top", ["engine", "service"])
def test_no_import_circles(top):
    g = {a: {b for b in t if b.startswith(top)} for a, t in graph().items() if a.startswith(top)}
    assert not cycles(g), f"import circles: {cycles(g)}"


def test_the_circle_finder_finds_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
