"""Preset parameters at the edges of float64 (issue 11, item 5): every parameter of every
preset, huge, tiny and negative, answers 200 with a valid linkage or a 422 problem+json naming
the parameter, never a 500; each preset's parameters are documented in the OpenAPI file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from engine.catalogue.presets import _LENGTHS, PRESETS, Preset, build_preset, resolve_parameters
from engine.model.errors import InvalidParameter
from tests.service.test_uvicorn_process import ROOT

ALL_PARAMETERS = [(name, key) for name, p in PRESETS.items() for key in p.parameters]
#: Parameters that are angles (radians); every other parameter is a length, a coordinate, a scale
#: factor, a count or a side, none of which 1e308 can be.
ANGLES = frozenset({"theta", "theta1", "theta2", "phi", "twist", "tilt"})
EXTREMES = ["1e308", "-1e308", "1e200", "1e-300", "5e-324", "1.7976931348623157e308"]


def assert_named_problem(r: Any, key: str) -> dict[str, Any]:
    assert r.status_code == 422, r.text
    assert r.headers["content-type"].startswith("application/problem+json")
    body = r.json()
    assert body["status"] == 422 and body["type"] == "/problems/invalid-parameter"
    assert body["errors"][0]["loc"] == ["query", key], body
    assert body["detail"].startswith(f"query.{key}: ")
    return body


def assert_valid_linkage(lk: dict[str, Any]) -> None:
    pos = {v["id"]: np.array(v["position"]) for v in lk["vertices"]}
    assert all(np.all(np.isfinite(p)) for p in pos.values())
    for b in lk["bars"]:
        i, j = b["ends"]
        assert b["length"] > 0
        assert abs(np.linalg.norm(pos[i] - pos[j]) - b["length"]) <= 1e-8 * b["length"]


@pytest.mark.parametrize(("name", "key"), ALL_PARAMETERS)
def test_overflowing_parameters_answer_422_naming_the_parameter(client, name, key):
    """1e308 (the issue's ``four-bar?a=1e308``): lengths, coordinates and scale factors overflow
    when squared, counts and sides are out of range; angles are only angles (a valid linkage)."""
    r = client.get(f"/v1/presets/{name}?{key}=1e308")
    if key in ANGLES:
        assert r.status_code == 200, r.text
        assert_valid_linkage(r.json())
    else:
        body = assert_named_problem(r, key)
        if key in _LENGTHS:
            assert "1e+308" in body["detail"]


@pytest.mark.parametrize(("name", "key"), ALL_PARAMETERS)
@pytest.mark.parametrize("value", EXTREMES)
def test_extreme_parameters_never_fail_the_service(client, name, key, value):
    for url in (f"/v1/presets/{name}?{key}={value}",):
        r = client.get(url)
        assert r.status_code in (200, 422), r.text
        if r.status_code == 200:
            assert_valid_linkage(r.json())
        else:
            assert r.headers["content-type"].startswith("application/problem+json")
            loc = r.json()["errors"][0]["loc"]
            # named, or (lengths that assemble nowhere) the query as a whole
            assert loc in (["query", key], ["query"]), r.text


def test_the_generic_route_answers_alike(client):
    """``/v1/presets/{name}`` is the same route for a known name (kept for old clients)."""
    assert_named_problem(client.get("/v1/presets/four-bar?a=1e308"), "a")


def test_several_parameters_that_overflow_together_are_all_named(client):
    r = client.get("/v1/presets/four-bar?a=1e200&L1=1e200&L2=1e200&L3=1e200")
    assert r.status_code == 422, r.text
    body = r.json()
    assert body["errors"][0]["loc"] == ["query"]
    for key in ("a", "L1", "L2", "L3"):
        assert f"{key} = 1e+200" in body["detail"]


def test_a_preset_added_later_is_checked_without_a_change(client, monkeypatch):
    """The check is generic: a new preset whose geometry overflows, or misses its own lengths,
    is refused with the parameter named, by the engine and by the generic route."""
    from engine.model.linkage import BarSpec, VertexSpec

    def two_bars(p: dict[str, float]) -> Any:
        tip = [p["L"] * p["stretch"], 0.0]  # stretch != 1: the bar misses its length
        return ([VertexSpec("P", [0.0, 0.0], True), VertexSpec("A", tip)],
                [BarSpec("L", ("P", "A"), p["L"])])

    preset = Preset("probe", "test only", {"L": 1.0, "stretch": 1.0}, frozenset(), two_bars)
    monkeypatch.setitem(PRESETS, "probe", preset)
    assert build_preset("probe").n_bars == 1
    with pytest.raises(InvalidParameter) as err:
        build_preset("probe", {"stretch": 1.5})
    assert err.value.loc == ("stretch",) and "off its length" in err.value.message
    assert_named_problem(client.get("/v1/presets/probe?L=1e308"), "L")
    assert_named_problem(client.get("/v1/presets/probe?stretch=1e308"), "stretch")


def test_a_preset_beyond_the_size_limits_names_its_size_parameter():
    from engine.model.linkage import Limits

    with pytest.raises(InvalidParameter) as err:
        build_preset("kl-chain", {"n": 100}, Limits(max_vertices=50))
    assert err.value.loc == ("n",) and "200 vertices exceed the limit of 50" in err.value.message


def test_openapi_lists_each_presets_query_parameters():
    spec = json.loads((Path(ROOT) / "openapi" / "openapi.json").read_text())
    assert "/v1/presets/{name}" in spec["paths"]  # the existing URL is kept
    for name, preset in PRESETS.items():
        op = spec["paths"][f"/v1/presets/{name}"]["get"]
        params = {p["name"]: p for p in op["parameters"] if p["in"] == "query"}
        assert set(params) == set(preset.parameters), name
        for key, default in preset.parameters.items():
            assert not params[key]["required"]
            assert params[key]["schema"]["type"] == "number"
            assert f"default {default:g}" in params[key]["description"]
        assert {"200", "404", "422"} <= set(op["responses"])


# -- the schema's bounds are the engine's (issue 31, item 6) ----------------------------------

SPEC = json.loads((ROOT / "openapi" / "openapi.json").read_text())


def schema_of(name: str, key: str) -> dict[str, Any]:
    params = SPEC["paths"][f"/v1/presets/{name}"]["get"]["parameters"]
    schema: dict[str, Any] = next(p["schema"] for p in params if p["name"] == key)
    return schema


def schema_valid(schema: dict[str, Any], value: float) -> bool:
    """JSON Schema's meaning of the keywords a preset parameter may carry (written out here,
    independent of the code that emits them)."""
    return (("minimum" not in schema or value >= schema["minimum"])
            and ("exclusiveMinimum" not in schema or value > schema["exclusiveMinimum"])
            and ("maximum" not in schema or value <= schema["maximum"])
            and ("multipleOf" not in schema or (value / schema["multipleOf"]).is_integer())
            and ("enum" not in schema or value in schema["enum"]))


def engine_takes(name: str, overrides: dict[str, float]) -> bool:
    """The engine's bounds check alone (the geometry may refuse values it takes)."""
    try:
        resolve_parameters(name, overrides)
    except InvalidParameter:
        return False
    return True


def edges(schema: dict[str, Any], default: float) -> list[float]:
    """Values at and just across each bound the schema states (and, without any, far out)."""
    step = schema.get("multipleOf")
    out = [default, 1e300, -1e300, 0.0, -1.0, 1.0]
    for key in ("minimum", "exclusiveMinimum", "maximum"):
        if key in schema:
            edge = float(schema[key])
            out += [edge, float(np.nextafter(edge, np.inf)), float(np.nextafter(edge, -np.inf))]
            if step:
                out += [edge + step, edge - step]
    if step:
        out += [default + step / 2]
    out += [float(c) for c in schema.get("enum", [])]
    return out


@pytest.mark.parametrize(("name", "key"), ALL_PARAMETERS)
def test_schema_bounds_are_the_engines_at_the_edges(name: str, key: str) -> None:
    schema = schema_of(name, key)
    default = float(PRESETS[name].parameters[key])
    gated = "gate" in PRESETS[name].parameters  # gate < n: the one bound between two
    for value in edges(schema, default):
        overrides = {key: value}
        if gated and key == "gate" and schema_valid(schema, value):  # n large enough
            n = schema_of(name, "n")
            overrides["n"] = max(float(n["minimum"]), min(float(n["maximum"]), value + 1))
        elif gated and key == "n":  # a gate below every n
            overrides["gate"] = 0.0
        assert engine_takes(name, overrides) == schema_valid(schema, value), (name, key, value)


def test_gate_below_n_is_stated_and_enforced(client: Any) -> None:
    schema = schema_of("gated-kl-chain", "gate")
    assert "less than n" in schema["description"]
    assert schema["maximum"] == schema_of("gated-kl-chain", "n")["maximum"] - 1
    for n in (2, 3, 10):
        assert engine_takes("gated-kl-chain", {"n": n, "gate": n - 1})
        assert not engine_takes("gated-kl-chain", {"n": n, "gate": n})
    assert client.get("/v1/presets/gated-kl-chain?n=3&gate=2").status_code == 200
    assert_named_problem(client.get("/v1/presets/gated-kl-chain?n=3&gate=3"), "gate")


def test_a_zero_length_is_outside_the_schema_and_refused(client: Any) -> None:
    assert not schema_valid(schema_of("four-bar", "a"), 0.0)
    assert_named_problem(client.get("/v1/presets/four-bar?a=0.0"), "a")
