"""Rooms read at once (issue 29): no module under engine/ or service/ over MAX_MODULE_LINES lines,
no function (or method) over MAX_FUNCTION_LINES, counted from its ``def`` line to its last line
(decorators left out), the numba kernel included."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 100


def modules() -> list[Path]:
    return sorted(p for top in ("engine", "service") for p in (ROOT / top).rglob("*.py")
                  if "__pycache__" not in p.parts)


def function_lengths(source: str) -> list[tuple[str, int, int]]:
    """(qualified name, first line, lines) of every function and method, nested ones
    included: from the ``def`` line (not the decorators) to the last line of its body."""
    out: list[tuple[str, int, int]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                end = child.end_lineno if child.end_lineno is not None else child.lineno
                out.append((name, child.lineno, end - child.lineno + 1))
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return out


def test_the_counts_are_those_of_the_rule() -> None:
    """The counter against functions whose lengths are known: decorators left out, the
    docstring and the last line counted, methods and nested functions found."""
    source = '''
import functools


@functools.cache
@functools.wraps(print)
def a():
    """Doc."""

    return 1


class B:
    @staticmethod
    def c(x):
        def d():
            return x
        return d
'''
    assert function_lengths(source) == [("a", 7, 4), ("B.c", 15, 4), ("B.c.d", 16, 2)]


@pytest.mark.parametrize("path", modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_module_over_the_limit(path: Path) -> None:
    lines = len(path.read_text().splitlines())
    assert lines <= MAX_MODULE_LINES, f"{path.relative_to(ROOT)}: {lines} lines"


@pytest.mark.parametrize("path", modules(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_function_over_the_limit(path: Path) -> None:
    long = [f"{name} (line {line}): {n} lines"
            for name, line, n in function_lengths(path.read_text()) if n > MAX_FUNCTION_LINES]
    assert not long, f"{path.relative_to(ROOT)}: {long}"
