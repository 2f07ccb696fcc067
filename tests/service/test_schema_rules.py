"""The schema states what the engine refuses (issue 28, item 6): every refusal of the engine's
linkage checks (``engine/model/linkage.py``) is either stated by the OpenAPI schema (the request
model refuses it, and the OpenAPI file carries the keyword that says so) or listed in
docs/API.md as a rule joining several fields (the schema accepts it and the service answers
422 naming the field). A check added to the engine without a case here fails the count."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from engine.model.errors import EngineError
from engine.model.linkage import BarSpec, Limits, VertexSpec, build_linkage
from service.config import Settings
from service.main import create_app
from service.schemas.common import AnalysisRequest

ROOT = Path(__file__).resolve().parents[2]
OPENAPI = json.loads((ROOT / "openapi" / "openapi.json").read_text())
API_MD = (ROOT / "docs" / "API.md").read_text()
#: The service's limits in these tests (the settings' limit rule).
LIMITS = Limits(max_vertices=4, max_bars=6)


def square(**change: Any) -> dict[str, Any]:
    """A unit square with a diagonal, pinned at P: every rule satisfied; ``change`` edits
    vertices, bars or dimension."""
    body: dict[str, Any] = {
        "dimension": 2,
        "vertices": [{"id": "P", "position": [0.0, 0.0], "fixed": True},
                     {"id": "A", "position": [1.0, 0.0]}, {"id": "B", "position": [1.0, 1.0]},
                     {"id": "C", "position": [0.0, 1.0]}],
        "bars": [{"id": "a", "ends": ["P", "A"]}, {"id": "b", "ends": ["A", "B"]},
                 {"id": "c", "ends": ["B", "C"]}, {"id": "d", "ends": ["C", "P"]},
                 {"id": "e", "ends": ["P", "B"]}],
    }
    body.update(change)
    return body


def vertices(*edits: tuple[int, dict[str, Any]]) -> list[dict[str, Any]]:
    out = square()["vertices"]
    for k, edit in edits:
        out[k] = {**out[k], **edit}
    return out


def bars(*edits: tuple[int, dict[str, Any]]) -> list[dict[str, Any]]:
    out = square()["bars"]
    for k, edit in edits:
        out[k] = {**out[k], **edit}
    return out


# (engine's message fragment, linkage that breaks exactly that check,
#  OpenAPI keyword path that states it, or the docs/API.md rule that lists it)
SCHEMA = "schema"
CASES: list[tuple[str, dict[str, Any], tuple[str, ...] | str]] = [
    ("dimension must be 2 or 3", square(dimension=4),
     ("Linkage", "properties", "dimension", "enum")),
    ("needs at least one vertex", square(vertices=[], bars=[]),
     ("Linkage", "properties", "vertices", "minItems")),
    ("vertices exceed the limit", square(vertices=[*square()["vertices"],
                                                    {"id": "E", "position": [2.0, 2.0]}]),
     "at most `LINKAGE_MAX_VERTICES` vertices"),
    ("bars exceed the limit", square(bars=[*square()["bars"], {"id": "f", "ends": ["A", "C"]},
                                           {"id": "g", "ends": ["A", "C"]}]),
     "at most `LINKAGE_MAX_VERTICES` vertices and `LINKAGE_MAX_BARS` bars"),
    ("duplicate vertex id", square(vertices=vertices((1, {"id": "P"}))),
     "vertex ids are unique"),
    ("coordinates, expected 2", square(vertices=vertices((1, {"position": [1.0, 0.0, 0.0]}))),
     "each position has `dimension` coordinates"),
    # (JSON has no infinity: its numbers are finite, as the schema's "number" says)
    ("is not finite", square(vertices=vertices((1, {"position": [math.inf, 0.0]}))),
     ("Vertex", "properties", "position", "items", "type")),
    ("has a coordinate beyond", square(vertices=vertices((1, {"position": [2e100, 0.0]}))),
     ("Vertex", "properties", "position", "items", "maximum")),
    ("fixed must be a boolean or a list", square(vertices=vertices((1, {"fixed": [True]}))),
     "a per-axis `fixed` has `dimension` booleans"),
    ("duplicate bar id", square(bars=bars((1, {"id": "a"}))), "bar ids"),
    ("has no length and its ends coincide",
     square(vertices=vertices((2, {"position": [1.0, 0.0]}))),
     "a bar without `length` has ends at different positions"),
    ("a bar has exactly two ends", square(bars=bars((1, {"ends": ["A", "B", "C"]}))),
     ("Bar", "properties", "ends", "maxItems")),
    ("names unknown vertex", square(bars=bars((1, {"ends": ["A", "Z"]}))),
     "a bar's ends name vertices of the linkage"),
    ("to itself", square(bars=bars((1, {"ends": ["A", "A"]}))),
     ("Bar", "properties", "ends", "uniqueItems")),
    ("is not finite or beyond", square(bars=bars((1, {"length": 3e100}))),
     ("Bar", "properties", "length", "anyOf", 0, "maximum")),
    ("must be positive", square(bars=bars((1, {"length": 0.0}))),
     ("Bar", "properties", "length", "anyOf", 0, "exclusiveMinimum")),
    ("joins two fixed vertices", square(
        vertices=vertices((1, {"fixed": True})), bars=bars((0, {"length": 2.0}))),
     "a bar between two fully fixed vertices has the length of their distance"),
    ("below 1e-12 of the longest bar", square(
        vertices=vertices((2, {"position": [1.0, 1e-13]})), bars=bars()),
     "the shortest bar is at least 1e-12 of the longest"),
]


def specs(body: dict[str, Any]) -> tuple[int, list[VertexSpec], list[BarSpec]]:
    return (body["dimension"], [VertexSpec(**v) for v in body["vertices"]],
            [BarSpec(**b) for b in body["bars"]])


def openapi_at(path: tuple[str | int, ...]) -> Any:
    node: Any = OPENAPI["components"]["schemas"]
    for key in path:
        node = node[key]
    return node


def test_every_check_of_the_linkage_has_a_case():
    source = (ROOT / "engine" / "model" / "linkage.py").read_text()
    build = source[:source.index("def changeable_bar(")]  # the checks of build_linkage
    sites = re.findall(r"raise (?:InvalidLinkage|LimitExceeded)\(", build)
    assert len(sites) == len(CASES)


def test_the_unit_square_is_valid():
    build_linkage(*specs(square()), limits=LIMITS)
    AnalysisRequest.model_validate({"linkage": square()})


@pytest.mark.parametrize(("message", "body", "where"), CASES, ids=[c[0] for c in CASES])
def test_each_refusal_is_stated_by_the_schema_or_listed_as_a_rule(message, body, where):
    with pytest.raises(EngineError, match=re.escape(message)):
        build_linkage(*specs(body), limits=LIMITS)
    if isinstance(where, tuple):
        assert openapi_at(where) is not None  # (a KeyError where the schema does not say it)
        with pytest.raises(ValidationError):
            AnalysisRequest.model_validate({"linkage": body})
    else:
        bullets = [line for line in API_MD.splitlines() if line.startswith(("- ", "  "))]
        assert any(where in line for line in bullets), where
        AnalysisRequest.model_validate({"linkage": body})  # the schema cannot say it


#: A service whose limits are :data:`LIMITS` (no workers: the unit square's first order is
#: answered in the service's own process).
client = TestClient(create_app(Settings(max_vertices=LIMITS.max_vertices,
                                        max_bars=LIMITS.max_bars)))


@pytest.mark.parametrize(("message", "body", "where"),
                         [c for c in CASES if isinstance(c[2], str)],
                         ids=[c[0] for c in CASES if isinstance(c[2], str)])
def test_a_rule_beyond_the_schema_is_a_422_naming_the_field(message, body, where):
    r = client.post("/v1/analysis/rigidity", json={"linkage": body})
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    problem = r.json()
    assert problem["type"] in ("/problems/invalid-linkage", "/problems/limit-exceeded")
    assert message in problem["detail"] or message in json.dumps(problem["errors"])
    assert problem["errors"][0]["loc"][:2] == ["body", "linkage"]
    assert client.get("/health/live").status_code == 200


# The design loop's single-field rules (engine/design): the engine's message, the request model
# and the body that breaks it, and the OpenAPI keyword that states it.
DESIGN = {"linkage": square(), "targets": [{"branch_point": 0, "sign": 1}], "adjustable": ["b"]}
DESIGN_CASES = [
    ("engine/design/design.py", "sign must be 1 or -1", "DesignRequest",
     {**DESIGN, "targets": [{"branch_point": 0, "sign": 0}]}, ("TargetIn", "properties", "sign",
                                                                "anyOf", 0, "enum")),
    ("engine/design/design.py", "adjustable bars repeat", "DesignRequest",
     {**DESIGN, "adjustable": ["b", "b"]}, ("DesignRequest", "properties", "adjustable",
                                           "uniqueItems")),
    ("engine/design/robustness.py", "give at least one adjustable bar", "RobustnessRequest",
     {"linkage": square(), "adjustable": []}, ("RobustnessRequest", "properties", "adjustable",
                                               "anyOf", 0, "minItems")),
]


@pytest.mark.parametrize(("module", "message", "model", "body", "where"), DESIGN_CASES,
                         ids=[c[1] for c in DESIGN_CASES])
def test_the_design_loops_single_field_rules_are_in_the_schema(module, message, model, body,
                                                               where):
    from service.schemas.design import DesignRequest
    from service.schemas.robustness import RobustnessRequest

    assert message in (ROOT / module).read_text()  # the engine's own refusal
    assert openapi_at(where) is not None
    with pytest.raises(ValidationError):
        {"DesignRequest": DesignRequest, "RobustnessRequest": RobustnessRequest}[
            model].model_validate(body)
    valid = {**body, **({"adjustable": ["b"]} if model == "RobustnessRequest" else DESIGN)}
    {"DesignRequest": DesignRequest, "RobustnessRequest": RobustnessRequest}[
        model].model_validate(valid)


# -- presets, sweeps, critical-value axes and splitting ----------------------------------------
# Every refusal of the engine's checks of a preset's parameters (engine/catalogue), a sweep's
# names and values (engine/design/sweep.py, checked when the sweep is submitted), a
# critical-value slice's axes (engine/design/critical_values.py) and a splitting perturbation
# (engine/design/splitting.py and the bars it may change, engine/model/linkage.py) is stated by
# the OpenAPI schema (a keyword at a path of components.schemas, or of a preset route's query
# parameter: ("query", route, parameter, keyword)), listed in docs/API.md as a rule joining
# several fields and answered 422 naming the field, or not reachable through the service.

FOUR_BAR = {
    "dimension": 2,
    "vertices": [{"id": "P0", "position": [0.0, 0.0], "fixed": True},
                 {"id": "P1", "position": [1.0, 0.0], "fixed": True},
                 {"id": "A", "position": [0.5, 0.8660254037844386]},
                 {"id": "B", "position": [1.5, 0.8660254037844386]}],
    "bars": [{"id": "a", "ends": ["P0", "P1"]}, {"id": "L1", "ends": ["P0", "A"]},
             {"id": "L2", "ends": ["A", "B"]}, {"id": "L3", "ends": ["P1", "B"]}],
}
NOT_EXPOSED = "not exposed"


def _axes(first: dict[str, Any], second: dict[str, Any]) -> dict[str, Any]:
    return {"linkage": FOUR_BAR, "axes": [first, second]}


AXIS = {"bar": "L2", "min": 0.5, "max": 2.0}
OTHER = {"bar": "L3", "min": 0.5, "max": 2.0}

# (engine module, message fragment, request (method, path, body or query), where, loc named)
RULES: list[tuple[str, str, tuple[str, str, Any], tuple[Any, ...] | str, list[Any]]] = [
    ("engine/catalogue/presets.py", "admit no configuration",
     ("GET", "/v1/presets/four-bar", {"a": 10}),
     "a preset's parameters admit a configuration", ["query"]),
    ("engine/catalogue/presets.py", "an integer",
     ("GET", "/v1/presets/kl-chain", {"n": 3.5}),
     ("query", "/v1/presets/kl-chain", "n", "multipleOf"), ["query", "n"]),
    ("engine/catalogue/presets.py", "length must be positive",
     ("GET", "/v1/presets/four-bar", {"a": 0}),
     ("query", "/v1/presets/four-bar", "a", "exclusiveMinimum"), ["query", "a"]),
    ("engine/catalogue/presets.py", "must be one of",
     ("GET", "/v1/presets/four-bar", {"side": 0}),
     ("query", "/v1/presets/four-bar", "side", "enum"), ["query", "side"]),
    ("engine/catalogue/presets.py", "must lie in",
     ("GET", "/v1/presets/kl-chain", {"n": 1}),
     ("query", "/v1/presets/kl-chain", "n", "minimum"), ["query", "n"]),
    ("engine/catalogue/presets.py", "must lie in",  # the same check: gate below n
     ("GET", "/v1/presets/gated-kl-chain", {"n": 3}),
     "`gate` is below `n`", ["query", "gate"]),
    ("engine/catalogue/presets.py", "unknown parameter",
     ("GET", "/v1/presets/four-bar", {"zz": 1}),
     "a query parameter the preset does not have", ["query", "zz"]),
    ("engine/catalogue/presets.py", "must be finite",
     ("GET", "/v1/presets/four-bar", {"a": "inf"}),
     ("query", "/v1/presets/four-bar", "a", "type"), ["query", "a"]),
    ("engine/catalogue/presets.py", "gives no valid linkage",
     ("GET", "/v1/presets/three-prism", {"ratio": 0}),
     "give a valid linkage (no bar's ends coincide)", ["query", "ratio"]),
    # the builders' own checks lie outside the bounds resolve_parameters checks first
    ("engine/catalogue/catalogue.py", "must be even and between 8 and 200",
     ("GET", "/v1/presets/cn-symmetric-four-regular", {"n": 202}),
     ("query", "/v1/presets/cn-symmetric-four-regular", "n", "maximum"), ["query", "n"]),
    ("engine/catalogue/catalogue.py", "must lie between 2 and 2000",
     ("GET", "/v1/presets/rotor-chain-3d", {"n": 2001}),
     ("query", "/v1/presets/rotor-chain-3d", "n", "maximum"), ["query", "n"]),
    ("engine/catalogue/catalogue.py", "must be positive",
     ("GET", "/v1/presets/rotor-chain-3d", {"h": 0}),
     ("query", "/v1/presets/rotor-chain-3d", "h", "exclusiveMinimum"), ["query", "h"]),
    ("engine/catalogue/catalogue.py", "admit no configuration",
     ("GET", "/v1/presets/rotor-chain-3d", {"l": 10}),
     "a preset's parameters admit a configuration", ["query"]),
    ("engine/design/critical_values.py", "give exactly two axes",
     ("POST", "/v1/analysis/critical-values", {"linkage": FOUR_BAR, "axes": [AXIS]}),
     ("CriticalValuesRequest", "properties", "axes", "minItems"), ["body", "axes"]),
    ("engine/design/critical_values.py", "need 0 < min < max",
     ("POST", "/v1/analysis/critical-values", _axes({**AXIS, "min": 0.0}, OTHER)),
     ("AxisIn", "properties", "min", "exclusiveMinimum"), ["body", "axes", 0, "min"]),
    ("engine/design/critical_values.py", "need 0 < min < max",
     ("POST", "/v1/analysis/critical-values", _axes({**AXIS, "min": 2.0, "max": 1.0}, OTHER)),
     "a critical-values axis has `min < max`", ["body", "axes", 0]),
    ("engine/design/critical_values.py", "the two axes name the same bar",
     ("POST", "/v1/analysis/critical-values", _axes(AXIS, AXIS)),
     "the two axes name different bars", ["body", "axes", 1, "bar"]),
    ("engine/design/critical_values.py", "unknown method",
     ("POST", "/v1/analysis/critical-values", _axes(AXIS, OTHER)), NOT_EXPOSED, []),
    ("engine/model/linkage.py", "unknown bar",
     ("POST", "/v1/analysis/critical-values", _axes({**AXIS, "bar": "zz"}, OTHER)),
     "names a bar that may change", ["body", "axes", 0, "bar"]),
    ("engine/model/linkage.py", "joins two fixed vertices",
     ("POST", "/v1/analysis/splitting", {"linkage": FOUR_BAR, "perturbation": {"a": 0.1}}),
     "names a bar that may change", ["body", "perturbation", "a"]),
    ("engine/design/splitting.py", "must be finite",
     ("POST", "/v1/analysis/splitting",
      {"linkage": FOUR_BAR, "perturbation": {"L2": math.inf}}),
     ("SplittingRequest", "properties", "perturbation", "patternProperties"),
     ["body", "perturbation", "L2"]),
    ("engine/design/splitting.py", "would make the length non-positive",
     ("POST", "/v1/analysis/splitting", {"linkage": FOUR_BAR, "perturbation": {"L2": -5.0}}),
     "leaves every length positive", ["body", "perturbation", "L2"]),
    ("engine/design/sweep.py", "must be positive",
     ("POST", "/v1/sweeps",
      {"linkage": FOUR_BAR, "grid": {"L2": {"min": 0.0, "max": 2.0, "steps": 3}}}),
     "a bar's grid starts above 0", ["body", "grid", "L2", "min"]),
    ("engine/catalogue/presets.py", "must be one of",  # a preset's bounds at a grid point
     ("POST", "/v1/sweeps",
      {"preset": {"name": "four-bar"}, "grid": {"side": {"min": -1.0, "max": 1.0, "steps": 3}}}),
     "within that parameter's bounds at every point", ["body", "grid", "side"]),
    ("engine/design/sweep.py", "unknown parameter",
     ("POST", "/v1/sweeps",
      {"preset": {"name": "four-bar"}, "grid": {"zz": {"min": 1.0, "max": 2.0, "steps": 3}}}),
     "parameters of its preset", ["body", "grid", "zz"]),
]
#: The functions whose refusals RULES covers, by module (the whole module where None).
CHECKED = {
    "engine/catalogue/presets.py": None,
    "engine/catalogue/catalogue.py": None,
    "engine/design/critical_values.py": ("def _validate(", "def critical_value_slice("),
    "engine/model/linkage.py": ("def changeable_bar(",),
    "engine/design/splitting.py": ("def length_change(",),
    "engine/design/sweep.py": ("class BarFamily", "class PresetFamily"),
}


def _function(source: str, start: str) -> str:
    """The text of the top-level function or class beginning with ``start``."""
    head = source.index(start)
    tail = re.search(r"\n(?:def |class |@)", source[head + 1:])
    return source[head:] if tail is None else source[head:head + 1 + tail.start()]


def test_every_refusal_of_presets_sweeps_axes_and_splitting_has_a_case():
    for module, starts in CHECKED.items():
        source = (ROOT / module).read_text()
        text = source if starts is None else "".join(_function(source, s) for s in starts)
        sites = re.findall(r"raise (?:InvalidParameter|InvalidRequest|InvalidLinkage)\(", text)
        fragments = {case[1] for case in RULES if case[0] == module}
        # a refusal with its own message has its own case (two cases may share one site)
        assert len(sites) == len(fragments), module


def _query_schema(route: str, name: str) -> dict[str, Any]:
    operation = OPENAPI["paths"][route]["get"]
    return next(p["schema"] for p in operation["parameters"] if p["name"] == name)


@pytest.mark.parametrize(("module", "message", "call", "where", "loc"), RULES,
                         ids=[f"{c[0].rsplit('/', 1)[1]}: {c[1]}" for c in RULES])
def test_each_engine_refusal_is_stated_by_the_schema_or_a_rule_naming_the_field(
        module, message, call, where, loc):
    assert message in (ROOT / module).read_text()  # the engine's own refusal
    method, path, payload = call
    if where == NOT_EXPOSED:  # the service never passes it: no request can reach it
        assert "method" not in openapi_at(("CriticalValuesRequest", "properties"))
        return
    if isinstance(where, tuple) and where[0] == "query":
        schema = _query_schema(where[1], where[2])
        assert where[3] in schema or any(where[3] in s for s in schema.get("anyOf", [])), schema
    elif isinstance(where, tuple):
        assert openapi_at(where) is not None
    else:
        bullets = [line for line in API_MD.splitlines() if line.startswith(("- ", "  "))]
        assert any(where in line for line in bullets), where
    r = (client.get(path, params=payload) if method == "GET"
         else client.post(path, content=json.dumps(payload, allow_nan=True),
                          headers={"content-type": "application/json"}))
    assert r.status_code == 422, r.text
    assert r.headers["content-type"] == "application/problem+json"
    errors = r.json()["errors"]
    assert errors and errors[0]["loc"][:len(loc)] == loc, errors
    if isinstance(where, str):  # a rule: the engine's own message, at that field
        assert message in r.json()["detail"] or message in json.dumps(errors)
    assert client.get("/health/live").status_code == 200
