"""3D hinged rotor chains through HTTP (issue 23): critical-points, configuration-space and
splitting answer complete with the argument ``derived`` from the chain's cells, and agree with
the dense-sampling references of tests/engine/space/test_witnesses.py and the stationary
distances of tests/engine/space/test_hinge_chain.py (never the engine's code)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree

from engine.catalogue.presets import build_preset
from engine.model.linkage import build_linkage
from tests.engine.space.test_hinge_chain import (
    completions,
    on_circle,
    regular_start,
    stationary,
)
from tests.engine.space.test_witnesses import circles_of, reference_components, reference_sheets

ROUTES = ("/v1/analysis/critical-points", "/v1/analysis/configuration-space",
          "/v1/analysis/splitting")


def post(client: Any, route: str, linkage: dict) -> dict:
    body: dict[str, Any] = {"linkage": linkage}
    if route.endswith("splitting"):
        body["perturbation"] = {"l0": 0.01}
    r = client.post(route, json=body)
    assert r.status_code == 200, r.text
    return r.json()


def engine_linkage(data: dict):
    from engine.model.linkage import BarSpec, VertexSpec

    return build_linkage(
        data["dimension"],
        [VertexSpec(v["id"], v["position"], v["fixed"]) for v in data["vertices"]],
        [BarSpec(b["id"], tuple(b["ends"]), b.get("length")) for b in data["bars"]])


@pytest.mark.parametrize("query", ["", "?n=3", "?n=4&tilt=0.7", "?n=3&tilt=1.4&h=0.3",
                                   "?n=4&tilt=1.4&h=0.3"])
def test_presets_are_derived_and_agree_with_dense_sampling(client, query):
    data = client.get(f"/v1/presets/rotor-chain-3d{query}").json()
    circles, lengths, _ = circles_of(engine_linkage(data))
    expected = reference_components(reference_sheets(circles, lengths, 20000))
    for route in ROUTES:
        answer = post(client, route, data)
        search = answer["search"]
        assert search["complete"] and search["argument"] == "derived", (route, search)
        assert search["argument_detail"]
        if "critical_points" in answer:
            assert answer["critical_points"] == []
        if route.endswith("configuration-space"):
            assert len(answer["components"]) == expected
            assert search["proved"]["components"] == {"count": expected, "exact": True}
        if route.endswith("critical-points"):
            assert search["proved"]["critical_points"] == {"count": 0, "exact": True}


def test_a_chain_at_a_critical_length_through_http(client):
    """n = 3 with coupler l1 at a saddle of its cell's squared distance: the critical points
    (branch points) are that saddle's completions, and splitting sees every one."""
    base = build_preset("rotor-chain-3d", {"n": 3})
    circles, lengths, tips = circles_of(base)
    saddles = [(x, v) for x, v, det in stationary(circles[1], circles[2]) if det < 0]
    x, value = max(saddles, key=lambda s: s[1])
    lengths_at = [lengths[0], float(np.sqrt(value))]
    expected = np.concatenate([completions(
        circles, lengths_at, 1, [on_circle(circles[1], np.array(y[0])),
                                 on_circle(circles[2], np.array(y[1]))])
        for y, v, det in stationary(circles[1], circles[2]) if abs(v - value) < 1e-8])
    assert len(expected) >= 1
    start = regular_start(circles, lengths_at)
    data = client.get("/v1/presets/rotor-chain-3d?n=3").json()
    ids = [v["id"] for v in data["vertices"]]
    for j, t in enumerate(tips):
        data["vertices"][t]["position"] = start[j].tolist()
    for bar in data["bars"]:
        if bar["id"] == "l1":
            bar["length"] = lengths_at[1]
    for route in ROUTES:
        answer = post(client, route, data)
        search = answer["search"]
        assert search["complete"] and search["argument"] == "derived", (route, search)
        if route.endswith("splitting"):
            assert len(answer["branch_points"]) == len(expected)
            continue
        found = np.array([[c["configuration"][ids[t]] for t in tips]
                          for c in answer["critical_points"]]).reshape(-1, 9)
        assert len(found) == len(expected)
        assert cKDTree(found).query(expected.reshape(len(expected), -1))[0].max() < 1e-5
        assert {c["kind"] for c in answer["critical_points"]} == {"branch"}
