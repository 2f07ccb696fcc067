"""Analysis endpoints through HTTP (httpx on the ASGI app)."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from engine.model import tolerances as engine_tolerances


def four_bar(client, **params):
    query = "&".join(f"{k}={v}" for k, v in params.items())
    r = client.get(f"/v1/presets/four-bar?{query}")
    assert r.status_code == 200
    return r.json()


def move(linkage, **where):
    for v in linkage["vertices"]:
        if v["id"] in where:
            v["position"] = list(where[v["id"]])
    return linkage


def assert_normalised(vectors):
    """API.md: unit 2-norm, largest-magnitude entry positive (among entries equal in magnitude
    to 1e-8, the first)."""
    for vec in vectors:
        flat = np.concatenate([np.atleast_1d(x) for x in vec.values()])
        assert abs(np.linalg.norm(flat) - 1.0) < 1e-12
        mags = np.abs(flat)
        assert flat[np.argmax(mags >= (1 - 1e-8) * mags.max())] > 0


def test_rigidity_of_a_generic_four_bar(client):
    r = client.post("/v1/analysis/rigidity", json={"linkage": four_bar(client, theta=1.0)})
    assert r.status_code == 200
    body = r.json()
    assert (body["rank"], body["expected_dof"], body["dof"]) == (3, 1, 1)
    assert body["critical"] is False and body["self_stresses"] == []
    assert body["trivial_motions"] == 0
    assert len(body["singular_values"]) == 3 and body["singular_values_complete"]
    assert set(body["zero_modes"][0]) == {"P1", "P2", "A", "B"}
    assert body["zero_modes"][0]["P1"] == [0.0, 0.0]
    assert_normalised(body["zero_modes"])
    tf = body["tangent_form"]
    assert tf["orientation"] in (-1, 1) and tf["log10_magnitude"] is not None
    np.testing.assert_allclose(
        np.abs(np.concatenate(list(tf["vector"].values()))),
        np.abs(np.concatenate(list(body["zero_modes"][0].values()))),
        atol=1e-12,
    )
    default = engine_tolerances.Tolerances()
    assert body["tolerances"] == {
        "rank_rtol": default.rank_rtol,
        "residual_atol": default.residual_atol,
        "q_rtol": default.q_rtol,
    }


def test_rigidity_at_a_branch_point(client):
    lk = move(four_bar(client), A=(-1, 0), B=(0, 0))
    body = client.post("/v1/analysis/rigidity", json={"linkage": lk}).json()
    assert body["critical"] is True
    assert body["dof"] == 2 and len(body["self_stresses"]) == 1
    stress = body["self_stresses"][0]
    assert set(stress) == {"L1", "L2", "L3"}
    np.testing.assert_allclose(np.abs(list(stress.values())), 1 / np.sqrt(3))
    assert_normalised(body["zero_modes"])
    assert_normalised(body["self_stresses"])
    assert body["tangent_form"]["orientation"] == 0
    assert body["tangent_form"]["log10_magnitude"] is None


def test_tolerances_are_echoed(client):
    tol = {"rank_rtol": 1e-6, "residual_atol": 1e-7, "q_rtol": 1e-5}
    body = client.post(
        "/v1/analysis/rigidity", json={"linkage": four_bar(client), "tolerances": tol}
    ).json()
    assert body["tolerances"] == tol


def test_second_order_branch_point_through_http(client):
    lk = move(four_bar(client), A=(1, 0), B=(0, 0))
    r = client.post("/v1/analysis/second-order", json={"linkage": lk})
    assert r.status_code == 200
    body = r.json()
    assert body["kind"] == "branch" and body["reason"] is None
    assert len(body["zero_modes"]) == 2 and len(body["tangents"]) == 2
    q = np.array(body["q"])
    assert q.shape == (2, 2)
    np.testing.assert_allclose(np.linalg.eigvalsh(q)[::-1], body["q_eigenvalues"], atol=1e-12)
    assert_normalised(body["tangents"])
    assert_normalised(body["zero_modes"])
    pos = {k: np.array(v) for k, v in body["configuration"].items()}
    for t in body["tangents"]:
        vel = {k: np.array(v) for k, v in t.items()}
        # a tangent is a zero mode: each bar's length is stationary
        for i, j in (("P1", "A"), ("A", "B"), ("P2", "B")):
            assert abs((pos[i] - pos[j]) @ (vel[i] - vel[j])) < 1e-12
    for c in body["tangent_coefficients"]:
        assert abs(np.array(c) @ q @ np.array(c)) < 1e-10


@pytest.mark.parametrize("dim", [2, 3])
def test_second_order_rigid_straight_chain(client, dim):
    zero = [0.0] * dim
    lk = {
        "dimension": dim,
        "vertices": [
            {"id": "P", "position": zero, "fixed": True},
            {"id": "A", "position": [1.0] + zero[1:]},
            {"id": "Q", "position": [2.0] + zero[1:], "fixed": True},
        ],
        "bars": [{"id": "a", "ends": ["P", "A"]}, {"id": "b", "ends": ["A", "Q"]}],
    }
    body = client.post("/v1/analysis/second-order", json={"linkage": lk}).json()
    assert body["kind"] == "rigid" and body["tangents"] == []
    assert len(body["zero_modes"]) == dim - 1
    assert all(x > 0 for x in body["q_eigenvalues"])


def test_second_order_regular_and_degenerate(client):
    body = client.post("/v1/analysis/second-order", json={"linkage": four_bar(client)}).json()
    assert body["kind"] == "regular" and body["self_stress"] is None and body["q"] is None
    r = client.get("/v1/presets/three-rotor?phi=0")
    lk = move(r.json(), B=(0, 0), A=(0.6, 0.8), C=(1, 0))
    body = client.post("/v1/analysis/second-order", json={"linkage": lk}).json()
    assert body["kind"] == "degenerate" and "non-isolated" in body["reason"]


def test_projection_is_reported(client):
    lk = {
        "vertices": [
            {"id": "P1", "position": [0.0, 0.0], "fixed": True},
            {"id": "A", "position": [0.309, 0.951]},
        ],
        "bars": [{"id": "r1", "ends": ["P1", "A"], "length": 1.0}],
    }
    body = client.post("/v1/analysis/rigidity", json={"linkage": lk}).json()
    assert body["input_residual"] > 1e-5
    assert body["projection_residual"] <= 1e-9
    assert 0 < body["projection_distance"] < 1e-4
    assert abs(np.linalg.norm(body["configuration"]["A"]) - 1.0) < 1e-9


def test_free_triangle_and_tetrahedron(client):
    tri = {
        "vertices": [
            {"id": k, "position": p}
            for k, p in zip("abc", [[0, 0], [1, 0], [0.3, 0.8]], strict=True)
        ],
        "bars": [{"id": e, "ends": list(e)} for e in ("ab", "bc", "ca")],
    }
    body = client.post("/v1/analysis/rigidity", json={"linkage": tri}).json()
    assert (body["trivial_motions"], body["dof"], body["zero_modes"]) == (3, 0, [])
    assert body["tangent_form"] is None
    pts = [[0, 0, 0], [1, 0, 0], [0.2, 0.9, 0], [0.3, 0.3, 0.8]]
    tet = {
        "dimension": 3,
        "vertices": [{"id": k, "position": p} for k, p in zip("abcd", pts, strict=True)],
        "bars": [
            {"id": a + b, "ends": [a, b]} for i, a in enumerate("abcd") for b in "abcd"[i + 1 :]
        ],
    }
    body = client.post("/v1/analysis/rigidity", json={"linkage": tet}).json()
    assert (body["trivial_motions"], body["dof"], body["critical"]) == (6, 0, False)


def test_gated_chain_with_slider(client):
    lk = client.get("/v1/presets/gated-kl-chain?n=12&gate=6").json()
    g = next(v for v in lk["vertices"] if v["id"] == "G")
    assert g["fixed"] == [True, False]
    body = client.post("/v1/analysis/rigidity", json={"linkage": lk}).json()
    assert body["dof"] == 1 and body["critical"] is False
    assert body["zero_modes"][0]["G"][0] == 0.0  # the slider's fixed axis does not move
    assert body["tangent_form"]["orientation"] in (-1, 1)


def test_numerical_failure_is_a_problem_not_a_crash(client, monkeypatch):
    """If the engine cannot give a trustworthy answer, the client gets problem+json (never 500)."""
    from engine.model.errors import NumericalFailure
    from service import jobs

    def fail(*args, **kwargs):
        raise NumericalFailure("inconsistent sparse null spaces (test)")

    monkeypatch.setattr(jobs, "first_order", fail)  # small linkages run in-process
    r = client.post("/v1/analysis/rigidity", json={"linkage": four_bar(client)})
    assert r.status_code == 422
    assert r.headers["content-type"].startswith("application/problem+json")
    assert r.json()["type"] == "/problems/numerical-failure"
    assert "inconsistent" in r.json()["detail"]
    monkeypatch.undo()
    again = client.post("/v1/analysis/rigidity", json={"linkage": four_bar(client)})
    assert again.status_code == 200


def test_rigidity_of_a_large_chain_through_the_worker(client):
    """A 150-rotor chain (M = 300): the sparse method, in a worker process (the request and
    the response cross by pickle), with the invariants checked on the JSON."""
    linkage = client.get("/v1/presets/kl-chain?n=150").json()
    r = client.post("/v1/analysis/rigidity", json={"linkage": linkage})
    assert r.status_code == 200
    body = r.json()
    assert body["method"] == "sparse-eigsh" and not body["singular_values_complete"]
    assert (body["rank"], body["dof"], body["self_stresses"], body["critical"]) == (
        299, 1, [], False)
    assert_normalised(body["zero_modes"])
    assert_normalised([body["tangent_form"]["vector"]])
    assert body["tangent_form"]["orientation"] in (-1, 1)
    # J z = 0 from the JSON alone: each bar's length is stationary along the zero mode
    pos = body["configuration"]
    z = body["zero_modes"][0]
    for bar in linkage["bars"]:
        a, b = bar["ends"]
        rate = np.dot(np.subtract(pos[a], pos[b]), np.subtract(z[a], z[b]))
        assert abs(rate) < 1e-10
    s = np.sort(body["singular_values"])
    assert s[0] > 1e-3 and np.isclose(body["singular_values"][0], s[-1])


def test_rigidity_response_is_what_validation_would_build():
    """rigidity_out skips validation (model_construct): the result must validate to the same
    model and JSON, and survive the trip back from a worker (pickle) unchanged."""
    import pickle

    from engine.catalogue.presets import build_preset
    from engine.local.rigidity import first_order
    from engine.model.constraints import on_constraints
    from engine.model.tolerances import Tolerances
    from service import mappers
    from service.schemas.analysis import RigidityResponse

    for name, params in (("four-bar", {}), ("kl-chain", {"n": 120}), ("three-rotor", {})):
        at, proj = on_constraints(build_preset(name, params), Tolerances())
        out = mappers.rigidity_out(at, first_order(at), proj)
        again = RigidityResponse.model_validate(out.model_dump())
        assert again == out and again.model_dump_json() == out.model_dump_json()
        back = pickle.loads(pickle.dumps(out))
        assert type(back) is RigidityResponse and back == out
        assert back.model_dump_json() == out.model_dump_json()
        assert back.model_fields_set == out.model_fields_set


def test_request_linkage_survives_pickling_as_columns():
    """The request goes to a worker as columns; it must come back as the same validated models
    (with the same fields set, so that defaults stay distinguishable from given values)."""
    import pickle

    from service.schemas.common import AnalysisRequest

    req = AnalysisRequest.model_validate({
        "linkage": {
            "dimension": 2,
            "vertices": [
                {"id": "P", "position": [0.0, 0.0], "fixed": True},
                {"id": "S", "position": [1.0, 0.0], "fixed": [False, True]},
                {"id": "A", "position": [0.5, 0.8]},
            ],
            "bars": [{"id": "a", "ends": ["P", "A"]}, {"id": "b", "ends": ["A", "S"],
                                                       "length": 1.0}],
        },
        "tolerances": {"rank_rtol": 1e-9},
    })
    back = pickle.loads(pickle.dumps(req))
    assert back == req and back.model_dump_json() == req.model_dump_json()
    for x, y in zip(back.linkage.vertices + back.linkage.bars,
                    req.linkage.vertices + req.linkage.bars, strict=True):
        assert type(x) is type(y) and x.model_fields_set == y.model_fields_set
    assert back.linkage.model_fields_set == req.linkage.model_fields_set
    assert back.tolerances == req.tolerances


def test_prestress_within_q_rtol_of_the_boundary_is_null(client):
    """7 collinear vertices in 3D (10 bars, 10 flexes, 4 stresses), prestress stable by an
    exact rational certificate (tests/engine/local/test_certificates.py) with a margin below the
    default q_rtol: null with the reason (it was a definite false), true at q_rtol = 1e-9."""
    xs = [1, 2, 3, 6, 7, 8, 12]
    edges = [(2, 3), (0, 6), (0, 4), (1, 2), (0, 5), (1, 5), (1, 4), (2, 4), (3, 5), (1, 6)]
    lk = {"dimension": 3,
          "vertices": [{"id": f"v{i}", "position": [x, 0, 0]} for i, x in enumerate(xs)],
          "bars": [{"id": f"e{k}", "ends": [f"v{a}", f"v{b}"]} for k, (a, b) in enumerate(edges)]}
    r = client.post("/v1/analysis/second-order", json={"linkage": lk})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["prestress_stable"] is None and body["second_order_rigid"] is None
    assert "borderline" in body["stability_reason"] and body["certificate"] is None
    r = client.post("/v1/analysis/second-order",
                    json={"linkage": lk, "tolerances": {"q_rtol": 1e-9}})
    assert r.status_code == 200, r.text
    assert r.json()["prestress_stable"] is True
    # the exact reference, here too: a rational stress whose stress matrix on the vertices
    # off {0, 1} is positive definite by exact pivots (prestress stable, proved)
    from tests.engine.local.test_certificates import (
        EDGES,
        XS,
        exact_collinear_stress,
        positive_definite,
    )

    assert (xs, edges) == (XS, EDGES)
    w = exact_collinear_stress()
    omega = [[Fraction(0)] * len(xs) for _ in xs]
    for k, (i, j) in enumerate(edges):
        omega[i][i] += w[k]
        omega[j][j] += w[k]
        omega[i][j] -= w[k]
        omega[j][i] -= w[k]
    assert positive_definite([row[2:] for row in omega[2:]])
