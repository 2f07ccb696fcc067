"""Every error path answers application/problem+json (RFC 9457) naming the offending field, and
leaves the service healthy."""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import service.config
from service.config import Settings

PROBLEM_JSON = "application/problem+json"
ENDPOINTS = ["/v1/analysis/rigidity", "/v1/analysis/second-order"]
JSON_HEADERS = {"content-type": "application/json"}

Json = Any
Loc = list[str | int]


# --------------------------------------------------------------------------- helpers


def assert_problem(r: httpx.Response, status: int) -> dict[str, Any]:
    """``r`` is an RFC 9457 problem with HTTP status ``status``; returns the body."""
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith(PROBLEM_JSON), r.headers["content-type"]
    body = r.json()
    assert isinstance(body, dict), body
    for key in ("type", "title", "detail"):
        assert isinstance(body.get(key), str) and body[key], (key, body)
    assert type(body.get("status")) is int and body["status"] == status, body
    return body


def assert_locs(body: dict[str, Any], loc: Loc) -> None:
    """Every entry of ``errors`` names exactly ``loc`` (and there is at least one)."""
    errors = body.get("errors")
    assert isinstance(errors, list) and errors, body
    for e in errors:
        assert isinstance(e.get("msg"), str) and e["msg"], e
        assert e.get("loc") == loc, (e, loc)


def assert_still_serving(client: Any) -> None:
    """The service answers normally after a bad request."""
    r = client.get("/health")
    assert r.status_code == 200, r.text
    assert r.json()["status"] == "ok"
    r = client.get("/v1/presets/four-bar")
    assert r.status_code == 200, r.text
    r = client.post("/v1/analysis/rigidity", json={"linkage": r.json()})
    assert r.status_code == 200, r.text
    assert r.json()["dof"] == 1


def expect(
    client: Any,
    r: httpx.Response,
    loc: Loc | None,
    status: int = 422,
    kind: str | None = None,
) -> dict[str, Any]:
    """Check a problem answer (with ``errors[].loc == loc`` unless None), then the service."""
    body = assert_problem(r, status)
    if loc is not None:
        assert_locs(body, loc)
    if kind is not None:
        assert body["type"].endswith(kind), body["type"]
    assert_still_serving(client)
    return body


@contextmanager
def settings_override(app: Any, value: Settings) -> Iterator[None]:
    key = service.config.get_settings
    before = app.dependency_overrides.get(key)
    app.dependency_overrides[key] = lambda: value
    try:
        yield
    finally:
        if before is None:
            app.dependency_overrides.pop(key, None)
        else:
            app.dependency_overrides[key] = before


@pytest.fixture(scope="module")
def four_bar(client: Any) -> dict[str, Any]:
    r = client.get("/v1/presets/four-bar")
    assert r.status_code == 200, r.text
    linkage = r.json()
    assert [v["id"] for v in linkage["vertices"]] == ["P1", "P2", "A", "B"]
    assert [b["id"] for b in linkage["bars"]] == ["L1", "L2", "L3"]
    return linkage


@pytest.fixture
def linkage(four_bar: dict[str, Any]) -> dict[str, Any]:
    """A fresh, mutable copy of the four-bar preset (P1, P2 pinned; A, B free)."""
    return copy.deepcopy(four_bar)


endpoints = pytest.mark.parametrize("url", ENDPOINTS, ids=["rigidity", "second-order"])


def vertex(vid: str, position: list[float], fixed: Json = False) -> dict[str, Any]:
    return {"id": vid, "position": position, "fixed": fixed}


def bar(bid: str, a: str, b: str, length: float | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"id": bid, "ends": [a, b]}
    if length is not None:
        out["length"] = length
    return out


# --------------------------------------------------------------------------- linkage errors


@endpoints
def test_unknown_vertex_in_bar_ends(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["bars"][0]["ends"][1] = "nowhere"
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 0, "ends", 1])


@endpoints
def test_duplicate_vertex_id(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["vertices"][3]["id"] = "A"
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices", 3, "id"])


@endpoints
def test_duplicate_bar_id(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["bars"][2]["id"] = "L1"
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 2, "id"])


@endpoints
def test_three_coordinates_in_dimension_two(
    client: Any, linkage: dict[str, Any], url: str
) -> None:
    linkage["vertices"][2]["position"] = [0.5, 0.8660254037844386, 0.0]
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices", 2, "position"])


@endpoints
def test_two_coordinates_in_dimension_three(client: Any, url: str) -> None:
    linkage = {
        "dimension": 3,
        "vertices": [
            vertex("P", [0.0, 0.0, 0.0], True),
            vertex("A", [1.0, 0.0, 0.0]),
            vertex("B", [1.0, 1.0]),
        ],
        "bars": [bar("a", "P", "A"), bar("b", "A", "B", 1.0)],
    }
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices", 2, "position"])


def _raw_four_bar(four_bar: dict[str, Any], path: Loc, literal: str) -> bytes:
    """The four-bar request as JSON text with the value at ``path`` replaced by ``literal``."""
    marker = "__NON_FINITE__"
    body: dict[str, Any] = {"linkage": copy.deepcopy(four_bar)}
    node: Any = body
    for part in path[:-1]:
        node = node.setdefault(part, {}) if isinstance(part, str) else node[part]
    node[path[-1]] = marker
    text = json.dumps(body).replace(f'"{marker}"', literal)
    assert literal in text and marker not in text
    return text.encode()


@endpoints
@pytest.mark.parametrize(
    ("path", "literal"),
    [
        (["linkage", "vertices", 2, "position", 1], "NaN"),
        (["linkage", "vertices", 3, "position", 0], "Infinity"),
        (["linkage", "vertices", 0, "position", 0], "-Infinity"),
        (["linkage", "bars", 1, "length"], "NaN"),
        (["linkage", "bars", 2, "length"], "Infinity"),
        (["tolerances", "rank_rtol"], "NaN"),
        (["tolerances", "residual_atol"], "Infinity"),
    ],
    ids=lambda x: x if isinstance(x, str) else ".".join(map(str, x)),
)
def test_non_finite_number(
    client: Any, four_bar: dict[str, Any], url: str, path: Loc, literal: str
) -> None:
    content = _raw_four_bar(four_bar, path, literal)
    r = client.post(url, content=content, headers=JSON_HEADERS)
    expect(client, r, ["body", *path])


@endpoints
def test_bar_from_vertex_to_itself(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["bars"][1]["ends"] = ["B", "B"]
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 1, "ends"])


@endpoints
@pytest.mark.parametrize("length", [0, 0.0, -1.0])
def test_non_positive_length(
    client: Any, linkage: dict[str, Any], url: str, length: float
) -> None:
    linkage["bars"][1]["length"] = length
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 1, "length"])


@endpoints
def test_bar_between_pins_with_wrong_length(
    client: Any, linkage: dict[str, Any], url: str
) -> None:
    # P1 = (0, 0) and P2 = (1, 0) are pinned: a ground bar must have length 1.
    linkage["bars"].append(bar("ground", "P1", "P2", 1.5))
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 3, "length"])


@endpoints
def test_bar_between_pins_with_right_length_is_accepted(
    client: Any, linkage: dict[str, Any], url: str
) -> None:
    # The counterpart of the test above: the same bar with the pins' distance is fine.
    linkage["bars"].append(bar("ground", "P1", "P2", 1.0))
    r = client.post(url, json={"linkage": linkage})
    assert r.status_code == 200, r.text


@endpoints
@pytest.mark.parametrize(
    ("limits", "loc"),
    [
        (Settings(max_vertices=3), ["body", "linkage", "vertices"]),
        (Settings(max_bars=2), ["body", "linkage", "bars"]),
    ],
    ids=["vertices", "bars"],
)
def test_more_than_configured_limit(
    app: Any,
    client: Any,
    linkage: dict[str, Any],
    url: str,
    limits: Settings,
    loc: Loc,
) -> None:
    before = app.dependency_overrides.get(service.config.get_settings)
    with settings_override(app, limits):
        r = client.post(url, json={"linkage": linkage})
        # Within the limit, the same override lets a smaller request through.
        small = {"vertices": [vertex("P", [0.0, 0.0], True), vertex("A", [1.0, 0.0])],
                 "bars": [bar("r", "P", "A")]}
        ok = client.post(url, json={"linkage": small})
    assert ok.status_code == 200, ok.text
    assert app.dependency_overrides.get(service.config.get_settings) is before  # restored
    expect(client, r, loc, kind="limit-exceeded")


# --------------------------------------------------------------------------- schema errors


def _set(body: dict[str, Any], path: Loc, value: Json) -> None:
    node: Any = body
    for part in path[:-1]:
        node = node.setdefault(part, {}) if isinstance(part, str) else node[part]
    node[path[-1]] = value


@endpoints
@pytest.mark.parametrize(
    "path",
    [
        ["colour"],
        ["linkage", "colour"],
        ["linkage", "vertices", 2, "colour"],
        ["linkage", "bars", 1, "colour"],
        ["tolerances", "colour"],
    ],
    ids=["top", "linkage", "vertex", "bar", "tolerances"],
)
def test_unknown_field(client: Any, linkage: dict[str, Any], url: str, path: Loc) -> None:
    body: dict[str, Any] = {"linkage": linkage}
    _set(body, path, "red")
    r = client.post(url, json=body)
    expect(client, r, ["body", *path])


@endpoints
def test_position_as_string(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["vertices"][2]["position"] = "0.5, 0.87"
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices", 2, "position"])


@endpoints
def test_fixed_as_string(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["vertices"][2]["fixed"] = "yes"
    r = client.post(url, json={"linkage": linkage})
    body = expect(client, r, ["body", "linkage", "vertices", 2, "fixed"])
    assert len(body["errors"]) == 1 and "boolean" in body["errors"][0]["msg"]


@endpoints
@pytest.mark.parametrize("fixed", [[True], [True, False, True], []], ids=["1", "3", "0"])
def test_fixed_list_of_wrong_length(
    client: Any, linkage: dict[str, Any], url: str, fixed: list[bool]
) -> None:
    linkage["vertices"][2]["fixed"] = fixed
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices", 2, "fixed"])


@endpoints
def test_dimension_four(client: Any, linkage: dict[str, Any], url: str) -> None:
    linkage["dimension"] = 4
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "dimension"])


@endpoints
@pytest.mark.parametrize(
    "content", [b'{"linkage": ', b"{linkage: 1}", b"not json", b'{"linkage": {}]'], ids=repr
)
def test_malformed_json(client: Any, url: str, content: bytes) -> None:
    r = client.post(url, content=content, headers=JSON_HEADERS)
    body = expect(client, r, None)
    # The location is the body, optionally followed by the character offset of the error.
    for e in body["errors"]:
        assert e["loc"][0] == "body", e
        assert all(type(p) is int and 0 <= p <= len(content) for p in e["loc"][1:]), e


@endpoints
@pytest.mark.parametrize("headers", [JSON_HEADERS, {}], ids=["json", "no-content-type"])
def test_empty_body(client: Any, url: str, headers: dict[str, str]) -> None:
    r = client.post(url, content=b"", headers=headers)
    expect(client, r, ["body"])


@endpoints
def test_missing_linkage(client: Any, url: str) -> None:
    r = client.post(url, json={"tolerances": {"rank_rtol": 1e-8}})
    expect(client, r, ["body", "linkage"])


@endpoints
@pytest.mark.parametrize("value", [0, 0.0, 2, -1e-8, 1.0])
def test_rank_rtol_out_of_range(
    client: Any, linkage: dict[str, Any], url: str, value: float
) -> None:
    r = client.post(url, json={"linkage": linkage, "tolerances": {"rank_rtol": value}})
    expect(client, r, ["body", "tolerances", "rank_rtol"])


@endpoints
def test_no_nearby_solution(client: Any, url: str) -> None:
    # |PQ| = 10 but the two bars reach at most 2: no configuration anywhere.
    linkage = {
        "vertices": [
            vertex("P", [0.0, 0.0], True),
            vertex("Q", [10.0, 0.0], True),
            vertex("A", [5.0, 1.0]),
        ],
        "bars": [bar("PA", "P", "A", 1.0), bar("AQ", "A", "Q", 1.0)],
    }
    r = client.post(url, json={"linkage": linkage})
    expect(client, r, ["body", "linkage", "vertices"], kind="no-nearby-solution")


# --------------------------------------------------------------------------- presets, routing


def test_unknown_preset(client: Any) -> None:
    r = client.get("/v1/presets/no-such-bar")
    expect(client, r, ["path", "name"], status=404)


@pytest.mark.parametrize(
    ("query", "loc"),
    [
        ("L2=long", ["query", "L2"]),
        ("L2=", ["query", "L2"]),
        ("colour=1", ["query", "colour"]),
        ("L2=-1", ["query", "L2"]),
        ("a=0", ["query", "a"]),
        ("L3=nan", ["query", "L3"]),
        ("L1=inf", ["query", "L1"]),
        ("side=0.5", ["query", "side"]),
    ],
)
def test_bad_preset_parameter(client: Any, query: str, loc: Loc) -> None:
    r = client.get(f"/v1/presets/four-bar?{query}")
    expect(client, r, loc)


@pytest.mark.parametrize("query", ["L2=5", "L1=0.1&L3=0.1&a=5"])
def test_preset_lengths_never_assemble(client: Any, query: str) -> None:
    r = client.get(f"/v1/presets/four-bar?{query}")
    body = expect(client, r, None)
    assert body["errors"], body
    for e in body["errors"]:
        assert e["loc"][:1] == ["query"], e


def test_preset_integer_parameter_not_integer(client: Any) -> None:
    r = client.get("/v1/presets/kl-chain?n=2.5")
    expect(client, r, ["query", "n"])


@endpoints
def test_get_on_post_route(client: Any, url: str) -> None:
    r = client.get(url)
    expect(client, r, None, status=405)
    assert r.headers["allow"] == "POST"  # RFC 9110: a 405 names the allowed methods


@pytest.mark.parametrize("method", ["PUT", "DELETE"])
def test_wrong_method_on_get_route(client: Any, method: str) -> None:
    r = client.request(method, "/v1/presets/four-bar")
    expect(client, r, None, status=405)


def test_a_405_allows_every_method_of_its_path(client: Any) -> None:
    """``Allow`` names every method the OpenAPI document gives the path (issue 28: ``OPTIONS
    /v1/jobs/{id}`` named GET only, ``/v1/jobs`` GET only), not only the first route's."""
    paths = client.get("/openapi.json").json()["paths"]
    assert set(paths["/v1/jobs/{job_id}"]) == {"get", "delete"}  # the case of the issue
    patterns = {t: re.compile(re.sub(r"\\\{[^}]+\\\}", "[^/]+", re.escape(t)) + "$")
                for t in paths}
    for template in paths:
        url = re.sub(r"\{[^}]+\}", "x1", template)
        # the methods of every template the URL fits (/v1/jobs/operations fits
        # /v1/jobs/{job_id} too, whose DELETE answers 404 there)
        methods = {m.upper() for t, p in patterns.items() if p.match(url) for m in paths[t]}
        r = client.request("OPTIONS", url)
        expect(client, r, None, status=405)
        assert r.headers["allow"] == ", ".join(sorted(methods)), url


@pytest.mark.parametrize("url", ["/nowhere", "/v1/analysis/nowhere", "/v2/presets"])
def test_unknown_route(client: Any, url: str) -> None:
    r = client.get(url)
    expect(client, r, None, status=404)
    r = client.post(url, json={})
    expect(client, r, None, status=404)


# --------------------------------------------------------------------------- fuzzing

_IDS = st.sampled_from(["P", "Q", "A", "B", "", "x" * 101, "P "])
_NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.sampled_from([0.0, -0.0, 1.0, 1e-300, 1e300]),
)
_SCALARS = st.one_of(st.none(), st.booleans(), _NUMBERS, st.text(max_size=10))
_JSONISH = st.recursive(
    _SCALARS,
    lambda children: st.one_of(
        st.lists(children, max_size=4),
        st.dictionaries(st.text(max_size=8), children, max_size=4),
    ),
    max_leaves=20,
)


def _maybe(strategy: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    """Either ``strategy`` or anything at all."""
    return st.one_of(strategy, strategy, strategy, _JSONISH)


def _optional_keys(**fields: st.SearchStrategy[Any]) -> st.SearchStrategy[dict[str, Any]]:
    return st.fixed_dictionaries({}, optional=fields)


_VERTEX = _optional_keys(
    id=_maybe(_IDS),
    position=_maybe(st.lists(_NUMBERS, max_size=4)),
    fixed=_maybe(st.one_of(st.booleans(), st.lists(st.booleans(), max_size=4))),
)
_BAR = _optional_keys(
    id=_maybe(_IDS),
    ends=_maybe(st.lists(_IDS, max_size=3)),
    length=_maybe(st.one_of(st.none(), _NUMBERS)),
)
_LINKAGE = _optional_keys(
    dimension=_maybe(st.sampled_from([2, 3, 4, 0, "2", 2.0])),
    vertices=_maybe(st.lists(_maybe(_VERTEX), max_size=5)),
    bars=_maybe(st.lists(_maybe(_BAR), max_size=5)),
)
_TOLERANCES = _optional_keys(
    rank_rtol=_maybe(_NUMBERS), residual_atol=_maybe(_NUMBERS), q_rtol=_maybe(_NUMBERS)
)
_COORD = st.one_of(
    st.floats(min_value=-3, max_value=3, allow_nan=False),
    st.integers(min_value=-3, max_value=3),
    _NUMBERS,
)


@st.composite
def _plausible_linkage(draw: st.DrawFn) -> dict[str, Any]:
    """Linkages that mostly pass the schema, so that the engine gets garbage too."""
    dim = draw(st.sampled_from([2, 2, 3]))
    ids = draw(st.lists(st.sampled_from("PQABCD"), min_size=1, max_size=5))
    coords = st.lists(_COORD, min_size=dim, max_size=dim) | st.lists(_COORD, max_size=4)
    fixed = st.booleans() | st.lists(st.booleans(), min_size=dim, max_size=dim)
    vertices = [
        {"id": vid, "position": draw(coords), "fixed": draw(fixed)} for vid in ids
    ]
    bar_ends = st.lists(st.sampled_from([*ids, "Z"]), min_size=2, max_size=2)
    bars = []
    for k in range(draw(st.integers(0, 6))):
        b: dict[str, Any] = {"id": draw(st.sampled_from([f"b{k}", "b0"])), "ends": draw(bar_ends)}
        if draw(st.booleans()):
            b["length"] = draw(st.floats(min_value=1e-3, max_value=5) | _NUMBERS)
        bars.append(b)
    return {"dimension": dim, "vertices": vertices, "bars": bars}


_REQUEST = st.one_of(
    _JSONISH,
    _optional_keys(linkage=_maybe(_LINKAGE), tolerances=_maybe(_TOLERANCES)),
    st.fixed_dictionaries({"linkage": _plausible_linkage()}, optional={"tolerances": _TOLERANCES}),
    st.fixed_dictionaries({"linkage": _plausible_linkage()}),
    st.fixed_dictionaries({"linkage": _plausible_linkage()}),
)


@settings(derandomize=True, max_examples=60, deadline=None)
@given(payload=_REQUEST)
def test_garbage_bodies_never_fail_the_service(client: Any, payload: Json) -> None:
    # json.dumps writes NaN / Infinity literals for non-finite floats, as a careless client would.
    content = json.dumps(payload).encode()
    for url in ENDPOINTS:
        r = client.post(url, content=content, headers=JSON_HEADERS)
        assert r.status_code < 500, (url, content, r.text)
        if r.is_success:
            assert r.headers["content-type"].startswith("application/json"), r.headers
            continue
        body = assert_problem(r, r.status_code)
        assert isinstance(body.get("errors"), list), body
        for e in body["errors"]:
            assert isinstance(e["loc"], list) and isinstance(e["msg"], str), e


def test_service_healthy_after_fuzzing(client: Any) -> None:
    assert_still_serving(client)
