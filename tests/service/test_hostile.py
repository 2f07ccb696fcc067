"""Hostile input, one test per class (issue 6), on every POST endpoint where it applies.

Each class gets a 4xx problem+json naming the field, or a 200 whose fields say what happened
(``critical``, ``kind``, ``search.complete``); never a 5xx, never a hang, and the service keeps
answering afterwards (``expect`` checks it).
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from tests.service.test_errors import JSON_HEADERS, assert_problem, assert_still_serving, expect

Json = Any
SMALL = {"angles": 8, "random_starts": 2, "max_components": 4}


def four_bar(scale: float = 1.0, shift: float = 0.0, theta: float = 1.0) -> Json:
    """The equilateral four-bar at rotor angle ``theta``, scaled and then shifted."""
    pts = {"P1": (0.0, 0.0), "P2": (1.0, 0.0), "A": (math.cos(theta), math.sin(theta))}
    # B closes the rhombus P1-A-B-P2 (all four sides 1): a point of the configuration space.
    pts["B"] = (1.0 + pts["A"][0], pts["A"][1])
    return {
        "vertices": [
            {"id": k, "position": [shift + scale * x for x in p], "fixed": k.startswith("P")}
            for k, p in pts.items()
        ],
        "bars": [{"id": "L1", "ends": ["P1", "A"]}, {"id": "L2", "ends": ["A", "B"]},
                 {"id": "L3", "ends": ["P2", "B"]}],
    }


def bodies(linkage: Json) -> dict[str, Json]:
    """A well-formed request for every POST endpoint around ``linkage``."""
    return {
        "/v1/analysis/rigidity": {"linkage": linkage},
        "/v1/analysis/second-order": {"linkage": linkage},
        "/v1/analysis/critical-points": {"linkage": linkage, "options": SMALL},
        "/v1/analysis/configuration-space": {"linkage": linkage, "options": SMALL},
        "/v1/analysis/splitting": {"linkage": linkage, "perturbation": {"L2": 1e-3},
                                   "options": SMALL},
        "/v1/design/splitting": {"linkage": linkage, "targets": [{"branch_point": 0, "sign": 1}],
                                 "adjustable": ["L2"], "options": SMALL},
        "/v1/analysis/critical-values": {
            "linkage": linkage, "axes": [{"bar": "L2", "min": 0.5, "max": 1.5},
                                         {"bar": "L3", "min": 0.5, "max": 1.5}],
            "options": {"resolution": 8, "seeds_per_axis": 2}},
        "/v1/analysis/robustness": {"linkage": linkage, "options": SMALL},
        "/v1/figures/linkage": {"linkage": linkage, "show": ["zero_modes", "self_stress"]},
        "/v1/figures/configuration-space": {"linkage": linkage, "options": SMALL},
        "/v1/figures/critical-values": {
            "linkage": linkage, "axes": [{"bar": "L2", "min": 0.5, "max": 1.5},
                                         {"bar": "L3", "min": 0.5, "max": 1.5}],
            "options": {"resolution": 8, "seeds_per_axis": 2}},
        "/v1/figures/splitting": {"linkage": linkage, "perturbation": {"L2": 1e-3},
                                  "options": SMALL},
    }


POST = list(bodies(four_bar()))
every_post = pytest.mark.parametrize("url", POST, ids=[u.rsplit("/", 2)[-2] + "/" +
                                                       u.rsplit("/", 1)[-1] for u in POST])


@every_post
@pytest.mark.parametrize("content", [b'{"linkage": ', b"{'linkage': {}}", b"\xff\xfe",
                                     b"[1, 2", b"null"], ids=repr)
def test_malformed_json(client: Any, url: str, content: bytes) -> None:
    r = client.post(url, content=content, headers=JSON_HEADERS)
    body = expect(client, r, None)
    assert body["errors"][0]["loc"][0] == "body"


@every_post
@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_literals(client: Any, url: str, literal: str) -> None:
    text = _dumps(bodies(four_bar())[url]).replace('"position": [0.0, 0.0]',
                                                   f'"position": [{literal}, 0.0]', 1)
    assert literal in text
    r = client.post(url, content=text.encode(), headers=JSON_HEADERS)
    expect(client, r, ["body", "linkage", "vertices", 0, "position", 0])


@every_post
@pytest.mark.parametrize("where,value,loc", [
    (("linkage", "vertices", 2, "position"), "1, 2", ["body", "linkage", "vertices", 2,
                                                      "position"]),
    (("linkage", "bars", 0, "ends"), "P1", ["body", "linkage", "bars", 0, "ends"]),
    (("linkage", "dimension"), "2", ["body", "linkage", "dimension"]),
    (("linkage", "bars", 1, "length"), True, ["body", "linkage", "bars", 1, "length"]),
    (("linkage", "vertices", 2, "position", 0), "0.5", ["body", "linkage", "vertices", 2,
                                                        "position", 0]),
], ids=["position-string", "ends-string", "dimension-string", "length-bool", "coord-string"])
def test_wrong_types(client: Any, url: str, where: tuple[str | int, ...], value: Json,
                     loc: list[str | int]) -> None:
    body = copy.deepcopy(bodies(four_bar())[url])
    _set(body, where, value)
    r = client.post(url, json=body)
    expect(client, r, loc)


@pytest.mark.parametrize("field,value", [("seed", False), ("max_points", 100.0),
                                         ("angles", "8"), ("strain_tol", "0.01")])
def test_wrong_types_in_options(client: Any, field: str, value: Json) -> None:
    """No silent coercion: a boolean is not a seed, a float is not a point budget."""
    body = {"linkage": four_bar(), "options": {**SMALL, field: value}}
    r = client.post("/v1/analysis/configuration-space", json=body)
    expect(client, r, ["body", "options", field])


@every_post
def test_unknown_fields(client: Any, url: str) -> None:
    body = copy.deepcopy(bodies(four_bar())[url])
    body["linkage"]["vertices"][1]["mass"] = 1.0
    r = client.post(url, json=body)
    expect(client, r, ["body", "linkage", "vertices", 1, "mass"])
    r = client.post(url, json={**bodies(four_bar())[url], "callback": "http://x"})
    expect(client, r, ["body", "callback"])


@pytest.mark.parametrize("mutate,loc", [
    (lambda lk: lk.update(dimension=1_000_000), ["body", "linkage", "dimension"]),
    (lambda lk: lk.update(dimension=1), ["body", "linkage", "dimension"]),
    (lambda lk: lk["vertices"][2].update(position=[0.0] * 10_000),
     ["body", "linkage", "vertices", 2, "position"]),
    (lambda lk: lk["vertices"][2].update(position=[]),
     ["body", "linkage", "vertices", 2, "position"]),
    (lambda lk: lk["vertices"][0].update(fixed=[True] * 50),
     ["body", "linkage", "vertices", 0, "fixed"]),
], ids=["dimension-1e6", "dimension-1", "10k-coordinates", "no-coordinates", "50-axes"])
def test_absurd_dimensions(client: Any, mutate: Any, loc: list[str | int]) -> None:
    for url in ("/v1/analysis/rigidity", "/v1/analysis/configuration-space"):
        body = copy.deepcopy(bodies(four_bar())[url])
        mutate(body["linkage"])
        r = client.post(url, json=body)
        expect(client, r, loc)


def test_absurd_sizes_are_refused_before_any_work(client: Any) -> None:
    """A million vertices is over LINKAGE_MAX_VERTICES: refused as too large (422), fast."""
    n = 60_000
    linkage = {"vertices": [{"id": f"v{k}", "position": [float(k), 0.0]} for k in range(n)],
               "bars": [{"id": "b", "ends": ["v0", "v1"]}]}
    r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
    body = expect(client, r, ["body", "linkage", "vertices"])
    assert body["type"].endswith("limit-exceeded")


@every_post
def test_coincident_vertices_joined_by_a_bar(client: Any, url: str) -> None:
    """Two vertices at one point joined by a bar of unstated length: a zero-length bar."""
    linkage = four_bar()
    linkage["vertices"][3]["position"] = list(linkage["vertices"][2]["position"])
    r = client.post(url, json={**bodies(linkage)[url], "linkage": linkage})
    expect(client, r, ["body", "linkage", "bars", 1, "length"])


def test_coincident_vertices_with_stated_lengths_are_analysed(client: Any) -> None:
    """Coincident positions are legal when the lengths are stated: the configuration is
    projected onto the constraints first, and the answer reports how far it moved."""
    linkage = four_bar()
    linkage["vertices"][3]["position"] = list(linkage["vertices"][2]["position"])
    for bar in linkage["bars"]:
        bar["length"] = 1.0
    r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["projection_distance"] > 0.1 and body["projection_residual"] <= 1e-9
    pos = {v: np.array(p) for v, p in body["configuration"].items()}
    for a, b in (("P1", "A"), ("A", "B"), ("P2", "B")):
        assert abs(np.linalg.norm(pos[a] - pos[b]) - 1.0) <= 1e-9


@every_post
@pytest.mark.parametrize("length", [0.0, -0.0, 1e-320])
def test_zero_length_geometry(client: Any, url: str, length: float) -> None:
    linkage = four_bar()
    linkage["bars"][1]["length"] = length
    r = client.post(url, json={**bodies(linkage)[url], "linkage": linkage})
    body = assert_problem(r, 422)
    assert body["errors"][0]["loc"][:4] == ["body", "linkage", "bars", 1]
    assert_still_serving(client)


@pytest.mark.parametrize("scale", [1e-12, 1e-6, 1e6, 1e12])
def test_tiny_and_huge_linkages_are_analysed_like_unit_ones(client: Any, scale: float) -> None:
    """Scale invariance: rank, zero modes, stresses and the local kind do not depend on units;
    the default residual tolerance follows the median bar length (echoed in the answer)."""
    unit = client.post("/v1/analysis/second-order", json={"linkage": four_bar()}).json()
    r = client.post("/v1/analysis/second-order", json={"linkage": four_bar(scale)})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["kind"] == unit["kind"] == "regular"
    assert body["tolerances"]["residual_atol"] == pytest.approx(1e-9 * scale)
    rig = client.post("/v1/analysis/rigidity", json={"linkage": four_bar(scale)}).json()
    rig_unit = client.post("/v1/analysis/rigidity", json={"linkage": four_bar()}).json()
    assert (rig["rank"], rig["dof"], rig["critical"]) == (rig_unit["rank"], 1, False)
    for v in ("A", "B"):  # unit zero modes, so scale-free
        np.testing.assert_allclose(rig["zero_modes"][0][v], rig_unit["zero_modes"][0][v],
                                   atol=1e-9)


@pytest.mark.parametrize("scale", [1e-6, 1e12])
def test_tiny_and_huge_configuration_spaces(client: Any, scale: float) -> None:
    """The equilateral four-bar's three branch points, drawn in micrometres or in 1e12 units.
    (Before the scale-aware tolerance, 1e-6 ran for minutes and found spurious branches.)"""
    r = client.post("/v1/analysis/critical-points",
                    json={"linkage": four_bar(scale), "options": {"random_starts": 4}})
    assert r.status_code == 200, r.text
    body = r.json()
    assert [c["kind"] for c in body["critical_points"]] == ["branch"] * 3
    assert body["search"]["complete"] is True


@every_post
def test_coordinates_far_from_the_origin_are_refused(client: Any, url: str) -> None:
    """Unit bars near x = 1e12: float64 holds positions there only to ~1e-4, so no answer could
    meet residual_atol; the answer says so at the offending position."""
    linkage = four_bar(shift=1e12)
    r = client.post(url, json={**bodies(linkage)[url], "linkage": linkage})
    body = expect(client, r, None)
    loc = body["errors"][0]["loc"]
    assert loc[:3] == ["body", "linkage", "vertices"] and loc[4] == "position"
    assert "resolved" in body["detail"]


def test_all_collinear_linkage(client: Any) -> None:
    """Three bars stretched straight between pins 3 apart: critical and rigid (a point)."""
    linkage = {"vertices": [{"id": "P1", "position": [0, 0], "fixed": True},
                            {"id": "A", "position": [1, 0]}, {"id": "B", "position": [2, 0]},
                            {"id": "P2", "position": [3, 0], "fixed": True}],
               "bars": [{"id": "a", "ends": ["P1", "A"]}, {"id": "b", "ends": ["A", "B"]},
                        {"id": "c", "ends": ["B", "P2"]}]}
    rig = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
    assert rig.status_code == 200, rig.text
    assert rig.json()["critical"] is True and len(rig.json()["self_stresses"]) == 1
    second = client.post("/v1/analysis/second-order", json={"linkage": linkage})
    assert second.status_code == 200 and second.json()["kind"] == "rigid", second.text
    # A free collinear chain: rigid motions counted apart (3 in the plane), one flex.
    free = {"vertices": [{"id": k, "position": [float(i), 0.0]} for i, k in enumerate("ABC")],
            "bars": [{"id": "a", "ends": ["A", "B"]}, {"id": "b", "ends": ["B", "C"]}]}
    r = client.post("/v1/analysis/rigidity", json={"linkage": free})
    assert r.status_code == 200, r.text
    assert (r.json()["trivial_motions"], r.json()["dof"]) == (3, 1)
    # Tracing needs one degree of freedom with something fixed: a clear 422.
    r = client.post("/v1/analysis/configuration-space", json={"linkage": free})
    expect(client, r, ["body", "linkage", "bars"])


@every_post
def test_all_coincident_linkage(client: Any, url: str) -> None:
    linkage = four_bar()
    for v in linkage["vertices"]:
        v["position"] = [0.5, 0.5]
    r = client.post(url, json={**bodies(linkage)[url], "linkage": linkage})
    body = expect(client, r, None)
    assert body["errors"][0]["loc"][:3] == ["body", "linkage", "bars"]


def test_all_coincident_with_stated_lengths_and_nothing_fixed(client: Any) -> None:
    """Everything at one point, nothing pinned, lengths stated: projected apart, answered."""
    linkage = {"vertices": [{"id": k, "position": [0.0, 0.0]} for k in "ABC"],
               "bars": [{"id": "a", "ends": ["A", "B"], "length": 1.0},
                        {"id": "b", "ends": ["B", "C"], "length": 1.0},
                        {"id": "c", "ends": ["C", "A"], "length": 1.0}]}
    r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
    assert r.status_code == 200, r.text
    body = r.json()
    # The escape from the stationary start (every J = 0) reaches an equilateral triangle.
    assert body["projection_residual"] <= 1e-9 and body["input_residual"] == 1.0
    assert (body["rank"], body["dof"], body["trivial_motions"]) == (3, 0, 3)
    pos = {v: np.array(p) for v, p in body["configuration"].items()}
    for a, b in ("AB", "BC", "CA"):
        assert abs(np.linalg.norm(pos[a] - pos[b]) - 1.0) <= 1e-9


def _set(obj: Json, path: tuple[str | int, ...], value: Json) -> None:
    for key in path[:-1]:
        obj = obj[key]
    obj[path[-1]] = value


def _dumps(obj: Json) -> str:
    import json

    return json.dumps(obj)


@pytest.mark.parametrize("atol", [1.0, 1e-3, 2e-6])
def test_residual_tolerance_that_is_not_small_against_the_bars(client: Any, atol: float) -> None:
    """Configurations that far off the lengths are no points of the configuration space (the
    tracer wandered for minutes at 1e-3): at most 1e-6 of the median bar length."""
    r = client.post("/v1/analysis/critical-points",
                    json={"linkage": four_bar(), "tolerances": {"residual_atol": atol}})
    body = expect(client, r, ["body", "tolerances", "residual_atol"])
    assert "median" in body["detail"]
    ok = client.post("/v1/analysis/rigidity",
                     json={"linkage": four_bar(1e7 * atol), "tolerances": {"residual_atol": atol}})
    assert ok.status_code == 200, ok.text  # the same value is fine for bars 1e7 times longer


@pytest.mark.parametrize("field,value,loc", [
    ("adjustable", ["nope"], ["adjustable", 0]),
    ("targets", [{"branch_point": 0, "sign": 0}], ["targets", 0, "sign"]),
])
def test_design_refuses_bad_requests_before_exploring(monkeypatch: Any, field: str, value: Json,
                                                     loc: list[str | int]) -> None:
    from pydantic import ValidationError

    from engine.model.errors import InvalidRequest
    from service import jobs
    from service.config import Settings
    from service.schemas.design import DesignRequest

    def explore(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("explored before validating the request")

    monkeypatch.setattr(jobs, "explore", explore)
    body = {**bodies(four_bar())["/v1/design/splitting"], field: value}
    if field == "targets":  # the schema states it (issue 28: sign is 1 or -1) ...
        with pytest.raises(ValidationError) as invalid:
            DesignRequest.model_validate(body)
        assert list(invalid.value.errors()[0]["loc"]) == loc
        # ... and the engine still refuses it when given past the schema
        request = DesignRequest.model_validate({**body, field: [{"branch_point": 0, "sign": 1}]})
        request.targets[0].sign = 0
    else:
        request = DesignRequest.model_validate(body)
    with pytest.raises(InvalidRequest) as err:
        jobs.design_splitting(request, Settings())
    assert list(err.value.loc) == loc
