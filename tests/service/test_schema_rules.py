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
