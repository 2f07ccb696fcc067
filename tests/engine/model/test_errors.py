"""The engine's failure style (engine/model/errors.py, issue 16 item 2), checked where a program
can:
results of iterative methods carry ``success``/``message``, nothing raises a bare
``RuntimeError``, linear algebra that raises on singular matrices is handled where it is called,
and a sparse eigensolver that does not converge becomes a :class:`NumericalFailure`."""

from __future__ import annotations

import ast
import dataclasses
import importlib
import pkgutil
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import engine
from engine.design.design import DesignResult
from engine.design.robustness import Margin
from engine.local.prestress import PrestressResult
from engine.model.constraints import ProjectionResult
from engine.model.errors import EngineError, InvalidRequest, NumericalFailure

ENGINE = Path(engine.__file__).parent

#: The public results of the iterative methods with one answer.
ITERATIVE_RESULTS = [ProjectionResult, Margin, DesignResult, PrestressResult]

#: Exceptions that must not leave engine code as such (a failure is NumericalFailure, bad
#: input an EngineError subclass).
BARE = {"RuntimeError", "Exception", "ArithmeticError", "FloatingPointError", "LinAlgError",
        "ValueError"}
#: Where a bare one is raised on purpose, and why.
BARE_ALLOWED = {
    # LAPACK's "illegal argument" (info < 0) is a bug in our call, never input or convergence.
    ("lu.py", "ValueError"),
}

#: Calls that raise on singular (or, for eigsh, unconverged) problems of finite entries, and the
#: exceptions a handler around them must catch.
RAISING_CALLS = {
    "solve": {"LinAlgError"},  # np.linalg.solve (not a factor's .solve: see _is_linalg_solve)
    "inv": {"LinAlgError"},
    "cholesky": {"LinAlgError"},
    "splu": {"RuntimeError"},
    "eigsh": {"ArpackError", "ArpackNoConvergence", "RuntimeError"},
    "svds": {"ArpackError", "ArpackNoConvergence", "RuntimeError"},
}
#: Calls guarded otherwise, and how.
CALLS_ALLOWED = {
    # the matrices were checked non-singular (finite, non-zero determinant) before the loop
    # and do not change in it (a chord method)
    ("batched.py", "solve"),
}


def engine_sources() -> list[Path]:
    return sorted(ENGINE.rglob("*.py"))


def field_types(cls: type) -> dict[str, object]:
    return {f.name: f.type for f in dataclasses.fields(cls)}


@pytest.mark.parametrize("cls", ITERATIVE_RESULTS, ids=lambda c: c.__name__)
def test_results_of_iterative_methods_are_frozen_with_success_and_message(cls):
    assert dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen
    types = field_types(cls)
    assert types.get("success") in (bool, "bool")
    assert types.get("message") in (str, "str")


def test_every_engine_dataclass_with_success_has_a_message():
    found = []
    for info in pkgutil.walk_packages(engine.__path__, "engine."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, type) and obj.__module__ == module.__name__ \
                    and dataclasses.is_dataclass(obj) and "success" in field_types(obj):
                found.append(obj)
                assert field_types(obj).get("message") in (str, "str"), obj
    assert set(ITERATIVE_RESULTS) <= set(found)


def test_no_engine_result_claims_success_by_default():
    """``success`` is stated by whoever builds a result: a default of True would let a new
    failure path report success without saying so (issue 16)."""
    defaulted = []
    for info in pkgutil.walk_packages(engine.__path__, "engine."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if isinstance(obj, type) and obj.__module__ == module.__name__ \
                    and dataclasses.is_dataclass(obj):
                defaulted += [f"{obj.__qualname__}.{f.name}" for f in dataclasses.fields(obj)
                              if f.name in ("success", "message")
                              and f.default is not dataclasses.MISSING]
    assert not defaulted, defaulted


def test_every_search_result_reports_with_a_search_report():
    """One report type for every search: explorations, critical searches, margins and slices
    (``complete`` computed in one place, :class:`engine.model.report.SearchReport`)."""
    from engine.design.critical_values import Slice
    from engine.model.report import SearchReport
    from engine.space.configuration_space import CriticalSearch, SpaceResult

    for cls in (SpaceResult, CriticalSearch, Margin, Slice):
        assert field_types(cls)["search"] in (SearchReport, "SearchReport"), cls


def raised_names(tree: ast.AST) -> list[tuple[str, int]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            name = exc.attr if isinstance(exc, ast.Attribute) else getattr(exc, "id", "")
            out.append((name, node.lineno))
    return out


def test_no_engine_module_raises_a_bare_runtime_error_or_value_error():
    offenders = [f"{path.relative_to(ENGINE)}:{line} raises {name}"
                 for path in engine_sources()
                 for name, line in raised_names(ast.parse(path.read_text()))
                 if name in BARE and (path.name, name) not in BARE_ALLOWED]
    assert not offenders, offenders


def _call_name(node: ast.Call) -> str:
    func = node.func
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


def _is_linalg_solve(node: ast.Call) -> bool:
    """``np.linalg.solve``/``inv``/``cholesky`` (dense: raise LinAlgError when singular), not
    the ``solve`` of a factorisation object."""
    func = node.func
    return isinstance(func, ast.Attribute) and isinstance(func.value, ast.Attribute) \
        and func.value.attr == "linalg"


def _caught(handler: ast.ExceptHandler) -> set[str]:
    if handler.type is None:
        return {"*"}
    types = handler.type.elts if isinstance(handler.type, ast.Tuple) else [handler.type]
    return {t.attr if isinstance(t, ast.Attribute) else getattr(t, "id", "") for t in types}


def unhandled_calls(tree: ast.AST) -> list[tuple[str, int]]:
    out: list[tuple[str, int]] = []

    def visit(node: ast.AST, caught: frozenset[str]) -> None:
        if isinstance(node, ast.Try):
            inner = caught | {name for h in node.handlers for name in _caught(h)}
            for child in node.body:
                visit(child, frozenset(inner))
            for child in [*node.handlers, *node.orelse, *node.finalbody]:
                visit(child, caught)
            return
        if isinstance(node, ast.Call):
            name = _call_name(node)
            needs = RAISING_CALLS.get(name)
            dense = name in ("solve", "inv", "cholesky")
            if needs and (not dense or _is_linalg_solve(node)) \
                    and not (caught & (needs | {"*", "Exception"})):
                out.append((name, node.lineno))
        for child in ast.iter_child_nodes(node):
            visit(child, caught)

    visit(tree, frozenset())
    return out


def test_linear_algebra_that_raises_on_singular_input_is_handled_where_it_is_called():
    offenders = [f"{path.relative_to(ENGINE)}:{line} calls {name} outside a try that handles it"
                 for path in engine_sources()
                 for name, line in unhandled_calls(ast.parse(path.read_text()))
                 if (path.name, name) not in CALLS_ALLOWED]
    assert not offenders, offenders


def test_the_checks_above_can_fail():
    tree = ast.parse("import numpy as np\n"
                     "def f(a, b):\n"
                     "    x = np.linalg.solve(a, b)\n"
                     "    try:\n"
                     "        y = np.linalg.solve(a, b)\n"
                     "    except np.linalg.LinAlgError:\n"
                     "        y = None\n"
                     "    raise RuntimeError('did not converge')\n")
    assert unhandled_calls(tree) == [("solve", 3)]
    assert raised_names(tree) == [("RuntimeError", 8)]


def test_numerical_failure_is_not_an_input_error():
    assert not issubclass(NumericalFailure, EngineError)
    assert issubclass(InvalidRequest, EngineError)


def test_lanczos_that_does_not_converge_is_a_numerical_failure(monkeypatch):
    from engine.local import sparse_null

    def no_convergence(*args, **kwargs):
        raise spla.ArpackNoConvergence("no convergence", np.zeros(0), np.zeros((0, 0)))

    monkeypatch.setattr(sparse_null.spla, "eigsh", no_convergence)
    jac = sp.random(40, 60, density=0.1, random_state=np.random.default_rng(0), format="csr")
    with pytest.raises(NumericalFailure, match="Lanczos did not converge"):
        sparse_null._sparse_null_spaces(jac, 1e-10)


def test_an_unknown_refine_method_is_an_input_error():
    from engine.catalogue.presets import build_preset
    from engine.local.critical import refine_critical
    from engine.model.constraints import Constraints
    from engine.model.tolerances import Tolerances

    lk = build_preset("four-bar")
    with pytest.raises(InvalidRequest, match="unknown method") as err:
        refine_critical(Constraints(lk), lk.coordinates(), Tolerances(), method="qr")
    assert err.value.loc == ("method",)
