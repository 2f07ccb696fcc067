"""Configuration-space, critical-points, splitting and design endpoints through HTTP."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

FAST = {"angles": 24, "random_starts": 4}


def preset(client, name, **params):
    query = "&".join(f"{k}={v}" for k, v in params.items())
    r = client.get(f"/v1/presets/{name}?{query}")
    assert r.status_code == 200, r.text
    return r.json()


def post(client, path, body):
    r = client.post(path, json=body)
    assert r.status_code == 200, r.text
    return r.json()


def test_configuration_space_of_the_equilateral_four_bar(client):
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": preset(client, "four-bar"), "options": FAST})
    assert len(body["components"]) == 1
    assert [cp["kind"] for cp in body["critical_points"]] == ["branch"] * 3
    assert len(body["segments"]) == 6
    assert all(s["component"] == 0 and s["from"] != s["to"] for s in body["segments"])
    comp = body["components"][0]
    assert comp["closed"] and comp["through_start"]
    assert sorted(comp["critical_points"]) == [0, 1, 2]
    assert set(comp["positions"]) == {"P1", "P2", "A", "B"}
    a = np.array(comp["positions"]["A"])
    assert np.allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-9)
    assert set(comp["angles"]) == {"L1", "L3"} and set(comp["winding"]) == {"L1", "L3"}
    assert body["search"]["complete"] is True


def test_configuration_space_of_a_double_rocker(client):
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": preset(client, "four-bar", L2=0.9), "options": FAST})
    assert len(body["components"]) == 2 and body["segments"] == []
    assert [c["through_start"] for c in body["components"]].count(True) == 1
    for comp in body["components"]:
        assert comp["winding"] == {"L1": 0, "L3": 0}
        first = {k: v[0] for k, v in comp["positions"].items()}
        last = {k: v[-1] for k, v in comp["positions"].items()}
        assert first == last


def test_critical_points_and_near_misses(client):
    body = post(client, "/v1/analysis/critical-points",
                {"linkage": preset(client, "four-bar"), "options": FAST})
    assert len(body["critical_points"]) == 3 and body["near_misses"] == []
    for cp in body["critical_points"]:
        assert cp["residual"] <= 1e-9 and len(cp["tangents"]) == 2
        assert set(cp["self_stress"]) == {"L1", "L2", "L3"}
    body = post(client, "/v1/analysis/critical-points",
                {"linkage": preset(client, "four-bar", L2=1.01), "options": FAST})
    assert body["critical_points"] == [] and body["near_misses"]
    closest = min(m["length_gap"] for m in body["near_misses"])
    assert 1e-3 < closest < 1e-2  # L2 is 0.01 from the critical value a = 1


def test_splitting_endpoint(client):
    lk = preset(client, "four-bar")
    up = post(client, "/v1/analysis/splitting",
              {"linkage": lk, "perturbation": {"L2": 1e-3}, "options": FAST})
    down = post(client, "/v1/analysis/splitting",
                {"linkage": lk, "perturbation": {"L2": -1e-3}, "options": FAST})
    assert len(up["branch_points"]) == 3
    for a, b in zip(up["branch_points"], down["branch_points"], strict=True):
        assert a["index"] == b["index"] and a["sign"] == -b["sign"]
        assert len(a["connects"]) == 2
        assert {tuple(p) for p in a["connects"]}.isdisjoint({tuple(p) for p in b["connects"]})
        assert abs(a["delta"] - a["delta_linear"]) < 0.01 * abs(a["delta_linear"])


def test_splitting_signs_only_where_resolved(client):
    """The issue's case: the three-rotor at critical lengths with r1 + 0.05. Where the tip A is
    off the line P1-B, equilibrium at A leaves r1 and L1 unstressed: those branch points stay
    exactly critical, and their Delta (rounding) is sign 0, unresolved, without a pairing; the
    others keep a resolved sign with delta_error far below |delta|."""
    lk = preset(client, "three-rotor")
    body = post(client, "/v1/analysis/splitting",
                {"linkage": lk, "perturbation": {"r1": 0.05}, "options": FAST})
    seen = {True: 0, False: 0}
    for bp in body["branch_points"]:
        pos = bp["configuration"]
        p1, a, b = (np.array(pos[v]) for v in ("P1", "A", "B"))
        (ex, ey), (fx, fy) = a - p1, b - a
        on_line = bool(abs(ex * fy - ey * fx) < 1e-6)
        seen[on_line] += 1
        assert bp["resolved"] is on_line and (bp["sign"] != 0) is on_line, bp
        assert (abs(bp["delta"]) > bp["delta_error"]) is on_line
        assert len(bp["connects"]) == (2 if on_line else 0)
    assert seen == {True: 6, False: 6}


def test_design_endpoint(client):
    lk = preset(client, "three-rotor")
    body = post(client, "/v1/design/splitting", {
        "linkage": lk, "targets": [{"branch_point": 0, "sign": 1}],
        "adjustable": ["r1", "L1", "L2"], "options": FAST,
    })
    assert body["feasible"] is True and body["verified"] is True
    assert set(body["perturbation"]) == {"r1", "L1", "L2"}
    assert body["predicted"][0]["connects"] == body["predicted"][0]["traced_connects"]
    # A tied pair: two branch points whose splitting gradients g = 4 sigma L on the adjustable
    # bars are parallel (the paper's six tied pairs: their Delta always share a sign), found
    # from the critical-points answer (the same numbering as design's); opposite signs on them
    # cannot both hold.
    crit = post(client, "/v1/analysis/critical-points", {"linkage": lk, "options": FAST})
    length = {b["id"]: b["length"] for b in lk["bars"]}
    adjustable = ["r1", "L1", "L2"]
    grads = np.array([[4 * c["self_stress"][b] * length[b] for b in adjustable]
                      for c in crit["critical_points"]])
    grads /= np.linalg.norm(grads, axis=1, keepdims=True)
    cos = grads @ grads.T - 3 * np.eye(len(grads))
    i, j = (int(k) for k in np.unravel_index(np.argmax(cos), cos.shape))
    assert cos[i, j] > 1 - 1e-9 and i != j
    i, j = min(i, j), max(i, j)
    tied = post(client, "/v1/design/splitting", {
        "linkage": lk,
        "targets": [{"branch_point": i, "sign": 1}, {"branch_point": j, "sign": -1}],
        "adjustable": adjustable, "options": FAST,
    })
    assert tied["feasible"] is False and tied["verified"] is None
    assert tied["conflicts"][0]["branch_points"] == [i, j]


def test_errors_of_the_new_endpoints(client):
    two_dof = {"vertices": [{"id": "P", "position": [0, 0], "fixed": True},
                            {"id": "A", "position": [1, 0]}],
               "bars": []}
    r = client.post("/v1/analysis/configuration-space", json={"linkage": two_dof})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "linkage", "bars"]
    lk = preset(client, "four-bar")
    r = client.post("/v1/analysis/splitting",
                    json={"linkage": lk, "perturbation": {"nope": 1e-3}, "options": FAST})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "perturbation", "nope"]
    r = client.post("/v1/design/splitting", json={
        "linkage": lk, "targets": [{"branch_point": 7, "sign": 1}], "adjustable": ["L2"],
        "options": FAST})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "targets", 0, "branch_point"]
    r = client.post("/v1/analysis/configuration-space",
                    json={"linkage": lk, "options": {"angles": 0}})
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"][:3] == ["body", "options", "angles"]
    assert client.get("/health").status_code == 200


def test_gate_through_http(client):
    """Gated or not, from the windings of the configuration-space answer."""
    opts = {"max_components": 1, "angles": 12, "random_starts": 2}
    for d, turns in ((2.3, 1), (2.7, 0)):
        lk = preset(client, "gated-kl-chain", n=8, gate=4, D=d)
        body = post(client, "/v1/analysis/configuration-space", {"linkage": lk, "options": opts})
        comp = next(c for c in body["components"] if c["through_start"])
        assert {abs(comp["winding"][f"r{k}"]) for k in range(8)} == {turns}


def test_robustness_endpoint(client):
    lk = preset(client, "four-bar", L2=1.2)
    body = post(client, "/v1/analysis/robustness",
                {"linkage": lk, "adjustable": ["L2"], "options": FAST})
    assert body["success"] and abs(body["margin"] - 0.2) < 1e-7  # L2 = a + L1 - L3 = 1
    assert abs(body["nearest"]["L2"] - 1.0) < 1e-7 and body["nearest"]["L1"] == 1.0
    ys = [p[1] for p in body["critical_configuration"].values()]
    assert max(abs(y) for y in ys) < 1e-6
    assert body["method"] == "closed-form" and body["guarantee"] == "exact"
    assert body["search"]["complete"] is True and body["search"]["reason"] is None
    r = client.post("/v1/analysis/robustness", json={"linkage": lk, "adjustable": ["x"]})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "adjustable", 0]


SLIDER_CRANK = {
    "vertices": [
        {"id": "O", "position": [0.0, 0.0], "fixed": True},
        {"id": "B", "position": [0.7 * np.cos(0.9), 0.7 * np.sin(0.9)]},
        {"id": "P", "position": [0.7 * np.cos(0.9) + np.sqrt(1.6**2 - (0.7 * np.sin(0.9)) ** 2),
                                 0.0], "fixed": [False, True]},
    ],
    "bars": [{"id": "crank", "ends": ["O", "B"], "length": 0.7},
             {"id": "rod", "ends": ["B", "P"], "length": 1.6}],
}


@pytest.mark.slow
def test_robustness_of_a_slider_crank_is_its_branch_point(client):
    """crank = rod is the branch point: (1.6 - 0.7) / sqrt(2) with both bars, 0.9 with the
    rod; never the zero-length crank (a bar the service refuses as input)."""
    body = post(client, "/v1/analysis/robustness", {"linkage": SLIDER_CRANK})
    assert body["success"] and abs(body["margin"] - 0.9 / np.sqrt(2)) < 1e-7
    assert body["method"] == "multistart"
    assert body["guarantee"] == "upper-bound" and body["exact_margin"] is None
    assert body["guarantee_detail"].startswith("best local minimum over")
    assert body["search"]["complete"] is False and body["search"]["reason"] == "searched"
    assert body["search"]["starts_run"] == body["search"]["starts_planned"] > 0
    assert abs(body["nearest"]["crank"] - body["nearest"]["rod"]) < 1e-7
    conf = body["critical_configuration"]
    assert np.linalg.norm(np.subtract(conf["B"], conf["O"])) > 0.5
    body = post(client, "/v1/analysis/robustness",
                {"linkage": SLIDER_CRANK, "adjustable": ["rod"], "method": "multistart"})
    assert abs(body["margin"] - 0.9) < 1e-7 and abs(body["nearest"]["rod"] - 0.7) < 1e-7
    r = client.post("/v1/analysis/robustness",
                    json={"linkage": SLIDER_CRANK, "method": "closed-form"})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "method"]
    r = client.post("/v1/analysis/robustness", json={"linkage": SLIDER_CRANK, "method": "x"})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"][:2] == ["body", "method"]
    assert client.get("/health").status_code == 200


def test_robustness_multistart_on_a_four_bar_agrees_with_the_closed_form(client):
    lk = preset(client, "four-bar", L2=1.2)
    exact = post(client, "/v1/analysis/robustness", {"linkage": lk})
    general = post(client, "/v1/analysis/robustness",
                   {"linkage": lk, "method": "multistart", "options": FAST})
    assert general["method"] == "multistart" and exact["method"] == "closed-form"
    assert abs(general["margin"] - exact["margin"]) < 1e-7  # 0.2 / sqrt(3)
    assert abs(exact["margin"] - 0.2 / np.sqrt(3)) < 1e-9


def test_critical_values_endpoint(client):
    lk = preset(client, "four-bar", L2=1.2)
    body = post(client, "/v1/analysis/critical-values", {
        "linkage": lk, "axes": [{"bar": "L2", "min": 0.3, "max": 2.2},
                                {"bar": "L3", "min": 0.3, "max": 2.2}],
        "options": {"resolution": 16, "seeds_per_axis": 3},
    })
    assert body["curves"] and all(len(c) >= 2 for c in body["curves"])
    for curve in body["curves"]:
        for l2, l3 in curve:  # on L2 = L3 or L2 + L3 = 2 (a = L1 = 1)
            assert min(abs(l2 - l3), abs(l2 + l3 - 2)) < 1e-6
    assert {r["components"] for r in body["regions"]} == {1, 2}
    r = client.post("/v1/analysis/critical-values", json={
        "linkage": lk, "axes": [{"bar": "L2", "min": 0.3, "max": 2.2},
                                {"bar": "L2", "min": 0.3, "max": 2.2}]})
    assert r.status_code == 422 and r.json()["errors"][0]["loc"] == ["body", "axes", 1, "bar"]


def test_critical_values_without_the_homotopy_sweeps(client):
    """options.homotopy_paths_max = 0 skips the sweeps of the box's edges (a 3D two-rotor
    chain's take 400 paths each; it has no closed form): the curves come from the seed lengths,
    the answer is at best searched; the four-bar's closed form needs no sweep; out of bounds 422."""
    lk = preset(client, "rotor-chain-3d", n=2)
    axes = [{"bar": "r0b", "min": 1.3, "max": 1.9}, {"bar": "l0", "min": 1.2, "max": 1.8}]
    body = post(client, "/v1/analysis/critical-values", {
        "linkage": lk, "axes": axes,
        "options": {"resolution": 16, "seeds_per_axis": 2, "homotopy_paths_max": 0}})
    search = body["search"]
    assert search["sweeps_complete"] == 0 and search["sweep_paths"] == 0  # none followed
    assert "400 paths per sweep exceed the bound of 0" in search["argument_detail"]
    assert search["complete"] is False and search["reason"] == "searched"
    assert search["seed_lengths"] == 4 and body["curves"]
    assert all(r["components"] is not None for r in body["regions"])
    four = post(client, "/v1/analysis/critical-values", {
        "linkage": preset(client, "four-bar"), "options": {"homotopy_paths_max": 0},
        "axes": [{"bar": "L2", "min": 0.3, "max": 2.2}, {"bar": "L3", "min": 0.3, "max": 2.2}]})
    assert four["search"]["complete"] is True and four["search"]["method"] == "closed form"
    for bad in (-1, 8193, "0", 0.5):
        r = client.post("/v1/analysis/critical-values", json={
            "linkage": lk, "axes": axes, "options": {"homotopy_paths_max": bad}})
        assert r.status_code == 422
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["errors"][0]["loc"] == ["body", "options", "homotopy_paths_max"]


def test_robustness_job_stopped_by_its_deadline_answers_incomplete():
    """The job's deadline keyword reaches the engine: an expired deadline gives a valid
    response marked incomplete (reason "time"), not an error."""
    from engine.model.budget import Deadline
    from service import jobs
    from service.config import Settings
    from service.schemas.robustness import RobustnessRequest

    body = RobustnessRequest.model_validate({"linkage": SLIDER_CRANK})
    out = jobs.robustness_margin(body, Settings(), deadline=Deadline.after(0.0))
    assert out.search.complete is False and out.search.reason == "time"
    assert out.margin is None and out.success is False and out.method == "multistart"
    assert out.model_dump(mode="json")["search"]["reason"] == "time"


def pentagon_body(lengths=(1.0, 1.0, 1.0, 1.0, 1.0)):
    """A planar pentagon with the bar P0 P1 pinned (two degrees of freedom), at a convex
    configuration with the given lengths (the service projects it onto them)."""
    pts = [[0.0, 0.0], [lengths[0], 0.0]]
    th = 0.0
    for k in range(3):
        th += 2 * np.pi / 5
        pts.append([pts[-1][0] + lengths[k + 1] * np.cos(th),
                    pts[-1][1] + lengths[k + 1] * np.sin(th)])
    ids = ["P0", "P1", "A", "B", "C"]
    ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    return {"vertices": [{"id": i, "position": p, "fixed": i in ("P0", "P1")}
                         for i, p in zip(ids, pts, strict=True)],
            "bars": [{"id": f"b{k}", "ends": list(e), "length": x}
                     for k, (e, x) in enumerate(zip(ends, lengths, strict=True))]}


def test_two_degrees_of_freedom_answer_surfaces(client):
    """The equilateral pentagon's space (modulo rotations) is a closed orientable surface of
    genus 4 (Kapovich and Millson; Farber and Schuetz: b1 = 8)."""
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": pentagon_body(), "options": {"surface_step": 0.4,
                                                         "random_starts": 2}})
    assert body["components"] == [] and body["segments"] == []
    (surf,) = body["surfaces"]
    assert surf["closed"] and surf["orientable"] and surf["genus"] == 4
    assert surf["betti_q"] == [1, 8, 1] and surf["betti_z2"] == [1, 8, 1]
    assert surf["euler"] == -6 and surf["morse_sum"] == -6 and surf["morse_agrees"]
    assert not any(surf["defects"].values())
    a, b = np.array(surf["positions"]["A"]), np.array(surf["positions"]["B"])
    assert np.allclose(np.linalg.norm(a - b, axis=1), 1.0, atol=1e-9)
    tri = np.array(surf["triangles"])
    assert tri.min() == 0 and tri.max() == len(a) - 1
    assert sum((-1) ** h["index"] for h in body["height_critical_points"]) == -6
    # proved within the default 512 paths: the linear-product start's 2^4 C(6, 4) = 240 (the
    # total degree's 1024 would not fit)
    assert body["search"]["complete"] and body["search"]["argument"] == "proved"
    assert body["search"]["homotopy_start"] == "linear product"
    assert body["search"]["homotopy_paths"] == 240
    assert len(body["search"]["height"]) == 5


def test_two_degrees_of_freedom_compact_and_bounded(client):
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": pentagon_body(), "options": {"points": "compact",
                                                         "max_triangles": 200,
                                                         "homotopy_paths_max": 0}})
    (surf,) = body["surfaces"]
    assert surf["positions"]["shape"][1:] == [5, 2] and not surf["closed"]
    assert body["search"]["complete"] is False and body["search"]["reason"] == "budget"
    for bad in ({"max_triangles": 10}, {"surface_step": 0.0}, {"surface_step": "x"}):
        r = client.post("/v1/analysis/configuration-space",
                        json={"linkage": pentagon_body(), "options": bad})
        assert r.status_code == 422
        assert r.headers["content-type"].startswith("application/problem+json")
        assert "options" in r.text


def test_two_degrees_of_freedom_answer_size_is_estimated_first(app, client):
    """A triangle budget whose surfaces could exceed LINKAGE_MAX_POINTS is a 422 naming
    options before any work (the estimate: about half a mesh vertex per triangle)."""
    from service import config

    before = app.dependency_overrides[config.get_settings]
    app.dependency_overrides[config.get_settings] = lambda: before().replace(max_points=1000)
    try:
        r = client.post("/v1/analysis/configuration-space",
                        json={"linkage": pentagon_body(), "options": {"max_triangles": 5000}})
        ok = client.post("/v1/analysis/configuration-space",
                         json={"linkage": pentagon_body(),
                               "options": {"max_triangles": 1000, "homotopy_paths_max": 0,
                                           "random_starts": 0}})
    finally:
        app.dependency_overrides[config.get_settings] = before
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "options"]
    assert "max_triangles" in r.json()["errors"][0]["msg"]
    assert ok.status_code == 200, ok.text
    assert sum(len(s["triangles"]) for s in ok.json()["surfaces"]) <= 1000 + 12


def linkage_body(lk) -> dict:
    """A Linkage as the API's body (vertices with their fixed axes, bars with lengths)."""
    return {"vertices": [{"id": v, "position": [float(x) for x in p],
                          "fixed": [bool(f) for f in fx]}
                         for v, p, fx in zip(lk.vertex_ids, lk.positions, lk.fixed, strict=True)],
            "bars": [{"id": b, "ends": [lk.vertex_ids[int(i)], lk.vertex_ids[int(j)]],
                      "length": float(n)}
                     for b, (i, j), n in zip(lk.bar_ids, lk.ends, lk.lengths, strict=True)]}


def test_spherical_five_bar_is_derived_through_http(client):
    """A spherical five-bar (3D, D = 2: 4,608 paths of the Lagrange homotopy, past the default
    512) is complete by the five-bar chain's argument: one genus-3 surface, as the dense grid of
    its crank angles (B where three spheres meet) says."""
    from tests.engine.space.surfaces.conftest import (
        spherical_five_bar,
        spherical_five_bar_reference,
    )

    lengths = (1.2, 0.6, 1.0, 0.9, 0.7)
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": linkage_body(spherical_five_bar(*lengths)) | {"dimension": 3}})
    search = body["search"]
    assert search["complete"] and search["argument"] == "derived", search
    assert "24 paths" in search["argument_detail"] and search["homotopy_paths"] == 4608
    assert [s["euler"] for s in body["surfaces"]] == spherical_five_bar_reference(*lengths)
    (surf,) = body["surfaces"]
    assert surf["closed"] and surf["orientable"] and surf["morse_agrees"]
    assert surf["betti_q"] == [1, 2 - surf["euler"], 1]
    a, b = np.array(surf["positions"]["A"]), np.array(surf["positions"]["B"])
    assert np.allclose(np.linalg.norm(b, axis=1), 1.0, atol=1e-9)
    assert np.allclose(np.linalg.norm(a - b, axis=1), 1.0, atol=1e-9)
    assert body["critical_points"] == []


@pytest.mark.slow
@pytest.mark.parametrize("l1", [0.49, 1.4])
def test_gated_chain_driven_from_another_rotor_through_http(client, l1):
    """A 3-rotor gated chain given as bars, driven from rotor 0 (0.3, a crank) and not from its
    gate rotor 1 (0.8, a rocker): the exploration's total and gated are the chain rules', equal
    to dense sampling of rotor 0 with circle intersections (gated at L1 = 0.49, 4 components;
    not at 1.4, 16)."""
    from tests.engine.space.test_gate_transfer import build
    from tests.gated_reference import sampled_general_chain

    xs, r, couplers, gate, d, l2 = (0.0, 1.0, 2.0), (0.3, 0.8, 1.5), (1.0, 1.5), 1, 2.0, 2.0
    lk, pins = build(xs, r, couplers, gate, d, l1, l2)
    sliders = np.array([pins[gate] + [0.0, -d], pins[gate] + [0.0, d]])
    comps, turns = sampled_general_chain(pins, np.array(r), np.array(couplers), gate, sliders,
                                         l1, l2, samples=3000)
    body = post(client, "/v1/analysis/configuration-space",
                {"linkage": linkage_body(lk), "options": FAST})
    search = body["search"]
    assert search["components_total"] == comps
    assert "driven from rotor r0" in search["components_total_rule"]
    assert search["gated"] is (not turns), search["gated_reason"]


def grashof_margin(a: float, lengths: np.ndarray) -> float:
    """The four-bar's distance, moving L1, L2, L3, to its critical lengths: the planes
    ``a = s1 L1 + s2 L2 + s3 L3`` (all joints on a line), ``|a - s . L| / sqrt(3)``, over the
    planes whose foot keeps every length positive (asserted nearer than the others)."""
    valid, blocked = [np.inf], [np.inf]
    for signs in itertools.product((1.0, -1.0), repeat=3):
        s = np.array(signs)
        foot = lengths + (a - s @ lengths) / 3.0 * s
        (valid if foot.min() > 0 else blocked).append(abs(a - s @ lengths) / np.sqrt(3.0))
    assert min(valid) <= min(blocked)
    return float(min(valid))


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1e-3, 3.95, 1e3])
def test_multistart_margin_through_http_is_scale_invariant(client, scale):
    """The issue's case through HTTP: the multistart's margin on a four-bar drawn at scales
    1e-3..1e3 is the Grashof margin (computed here) times the scale, names its guarantee (an
    upper bound) and carries the exact closed-form margin it was compared with."""
    a, lengths = 1.3, np.array([0.9, 1.5, 0.8])
    lk = preset(client, "four-bar", a=a * scale, L1=lengths[0] * scale,
                L2=lengths[1] * scale, L3=lengths[2] * scale, theta=0.4)
    body = post(client, "/v1/analysis/robustness",
                {"linkage": lk, "method": "multistart", "options": FAST})
    expected = grashof_margin(a, lengths) * scale
    assert body["method"] == "multistart" and body["success"], body
    assert body["guarantee"] == "upper-bound" and body["guarantee_detail"]
    assert body["margin"] == pytest.approx(expected, rel=1e-7)
    assert body["exact_margin"] == pytest.approx(expected, rel=1e-9)


@pytest.mark.slow
def test_design_predictions_are_signed_only_where_resolved(client):
    """Design with only r1 and L1 adjustable on the three-rotor: at the branch points where the
    tip A is off the line P1-B (read here from the critical-points answer's configurations),
    equilibrium at A leaves r1 and L1 unstressed, so no change of theirs moves Delta: a design
    for one is infeasible with that reason, no sign claimed; an on-line target is signed beyond
    its own error and verified by tracing."""
    lk = preset(client, "three-rotor")
    crit = post(client, "/v1/analysis/critical-points", {"linkage": lk, "options": FAST})
    on_line = []
    for cp in crit["critical_points"]:
        pos = cp["configuration"]
        p1, a, b = (np.array(pos[v]) for v in ("P1", "A", "B"))
        (ex, ey), (fx, fy) = a - p1, b - a
        on_line.append(bool(abs(ex * fy - ey * fx) < 1e-6))
    signed = on_line.index(True)
    body = post(client, "/v1/design/splitting", {
        "linkage": lk, "targets": [{"branch_point": signed, "sign": 1}],
        "adjustable": ["r1", "L1"], "options": FAST})
    (p,) = body["predicted"]
    assert p["branch_point"] == signed and p["sign"] == 1 and abs(p["delta"]) > p["delta_error"]
    assert body["verified"] is True and p["connects"] == p["traced_connects"]
    undecided = on_line.index(False)
    body = post(client, "/v1/design/splitting", {
        "linkage": lk, "targets": [{"branch_point": undecided, "sign": 1}],
        "adjustable": ["r1", "L1"], "options": FAST})
    assert body["feasible"] is False and body["predicted"] == [] and body["verified"] is None
    (conflict,) = body["conflicts"]
    assert conflict["branch_points"] == [undecided]
    assert "do not change how this point splits" in conflict["reason"]


@pytest.mark.parametrize("change", [0.08, -0.08])
def test_two_degrees_of_freedom_splitting_resolves_the_cones(client, change):
    """At lengths (2, 1, 1, 1, 1) the pentagon space has four cones (the collinear pentagons);
    a change of bar b2 resolves each into one sheet or two, and the predicted difference of
    the Euler characteristics on the two sides is Farber and Schuetz's (b_i = a_i + a_{2-i},
    computed here), as the re-meshing says."""
    from itertools import combinations

    def betti(lengths):
        longest = int(np.argmax(lengths))
        others = [k for k in range(5) if k != longest]

        def a(i):
            return sum(1 for sub in combinations(others, i)
                       if lengths[longest] + sum(lengths[k] for k in sub) < sum(lengths) / 2)
        return [a(i) + a(2 - i) for i in range(3)]

    base = np.array([2.0, 1.0, 1.0, 1.0, 1.0])
    d_l = np.array([0.0, 0.0, change, 0.0, 0.0])
    body = post(client, "/v1/analysis/splitting",
                {"linkage": pentagon_body(tuple(base)), "perturbation": {"b2": change},
                 "options": {"time_budget_s": 60}})
    surf = body["surface"]
    assert body["branch_points"] == [] and len(surf["cones"]) == 4
    for cone in surf["cones"]:
        assert max(abs(p[1]) for p in cone["configuration"].values()) < 1e-8  # collinear
        assert cone["sheets"] in (1, 2) and cone["euler_change"] == 2 * cone["sheets"] - 3
        q = cone["q_eigenvalues"]
        assert min(q) < 0 < max(q)
    plus, minus = betti(base + d_l), betti(base - d_l)
    chi = [b[0] - b[1] + b[2] for b in (plus, minus)]
    assert surf["predicted_euler_difference"] == chi[0] - chi[1]
    assert surf["euler"] == chi and surf["betti_q"] == [plus, minus]
    assert surf["predicted_betti_q"] == [plus, minus]
    assert surf["verified"]


@pytest.mark.slow
@pytest.mark.parametrize("sheets", [1, 2])
def test_two_degrees_of_freedom_design_resolves_the_cones_as_asked(client, sheets):
    """Design at the pentagon's critical lengths (2, 1, 1, 1, 1): every cone asked for one
    sheet (the designed change lengthens the free bars) or two (shortens them); the re-meshed
    b0, b1 and Euler characteristics at L + dL and L - dL are Farber and Schuetz's for those
    lengths, and their difference is the predicted one."""
    from tests.engine.space.surfaces.conftest import pentagon_betti

    base = (2.0, 1.0, 1.0, 1.0, 1.0)
    body = post(client, "/v1/design/splitting", {
        "linkage": pentagon_body(base), "adjustable": ["b1", "b2", "b3", "b4"],
        "targets": [{"branch_point": k, "sheets": sheets} for k in range(4)],
        "options": {"time_budget_s": 60}})
    assert body["feasible"] and body["predicted"] == [] and body["verified"] is True
    d_l = np.array([0.0] + [body["perturbation"][f"b{k}"] for k in range(1, 5)])
    surf = body["surface"]
    assert surf["targets_met"] and surf["remeshed_complete"]
    assert [c["sheets"] for c in surf["cones"]] == [sheets] * 4
    assert surf["asked"] == [c["sign"] for c in surf["cones"]]
    plus, minus = (list(pentagon_betti(tuple(np.array(base) + s * d_l))) for s in (1, -1))
    assert surf["betti_q"] == [plus, minus]
    chi = [b[0] - b[1] + b[2] for b in (plus, minus)]
    assert surf["euler"] == chi
    assert surf["euler_change"] == 4 * (2 * sheets - 3)
    assert surf["predicted_betti_q"] == [plus, minus]
    assert surf["critical_betti_q"] == [1, 2 - (chi[0] + chi[1]) // 2, 1]
    assert surf["predicted_euler_difference"] == 2 * surf["euler_change"] == chi[0] - chi[1]
    assert body["search"]["complete"] and body["search"]["argument"] == "proved"


def test_two_degrees_of_freedom_design_refusals(client):
    """sheets on a one-degree-of-freedom linkage (or neither sheets nor sign), sheets and sign
    together, no cone of that number: each a 422 problem naming the field."""
    cases = [
        ({"linkage": preset(client, "four-bar"),
          "targets": [{"branch_point": 0, "sheets": 1}], "adjustable": ["L2"]},
         ["body", "targets", 0, "sheets"]),
        ({"linkage": preset(client, "four-bar"), "targets": [{"branch_point": 0}],
          "adjustable": ["L2"]}, ["body", "targets", 0, "sign"]),
        ({"linkage": pentagon_body((2.0, 1.0, 1.0, 1.0, 1.0)),
          "targets": [{"branch_point": 0, "sheets": 1, "sign": 1}], "adjustable": ["b2"]},
         ["body", "targets", 0, "sheets"]),
        ({"linkage": pentagon_body((2.0, 1.0, 1.0, 1.0, 1.0)),
          "targets": [{"branch_point": 9, "sheets": 2}], "adjustable": ["b2"],
          "options": {"time_budget_s": 30}},
         ["body", "targets", 0, "branch_point"]),
        ({"linkage": pentagon_body((2.0, 1.0, 1.0, 1.0, 1.0)),
          "targets": [{"branch_point": 0, "sheets": 3}], "adjustable": ["b2"]},
         ["body", "targets", 0, "sheets"]),
    ]
    for request, loc in cases:
        r = client.post("/v1/design/splitting", json=request)
        assert r.status_code == 422, r.text
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["errors"][0]["loc"][:len(loc)] == loc
    assert client.get("/health").status_code == 200


def test_spherical_five_bar_splitting_at_a_cone_is_derived_through_http(client):
    """A spherical five-bar at a cone (``L3`` puts ``A``, ``B``, ``C`` on one great circle; the
    cone homotopy would need 4,608 paths, past the default 512): splitting and design take the
    chain's derived cone (24 paths) and answer complete, ``derived``, with the Euler
    characteristics at ``L3 +- dL`` of the dense crank-angle grid (``B`` where three spheres
    meet) and their difference predicted."""
    from tests.engine.design.test_surface_critical import AT_CONE, cone_lengths
    from tests.engine.space.surfaces.conftest import (
        spherical_five_bar,
        spherical_five_bar_reference,
    )

    lengths, _ = cone_lengths(*AT_CONE)
    lk = linkage_body(spherical_five_bar(*lengths)) | {"dimension": 3}

    def chi(change: float) -> list[int]:
        return [sum(spherical_five_bar_reference(*np.add(lengths, (0, 0, 0, s * change, 0))))
                for s in (1, -1)]

    body = post(client, "/v1/analysis/splitting", {"linkage": lk, "perturbation": {"L3": 0.05}})
    search, surf = body["search"], body["surface"]
    assert search["complete"] and search["argument"] == "derived", search
    assert "24 paths" in search["argument_detail"] and search["cone_search_paths"] == 24
    (cone,) = surf["cones"]
    assert cone["sheets"] in (1, 2) and min(cone["q_eigenvalues"]) < 0 < max(cone["q_eigenvalues"])
    want = chi(0.05)
    assert surf["euler"] == want and surf["predicted_euler_difference"] == want[0] - want[1] != 0
    assert surf["verified"] and surf["predicted_betti_q"] == surf["betti_q"]
    design = post(client, "/v1/design/splitting", {
        "linkage": lk, "adjustable": ["L3"], "targets": [{"branch_point": 0, "sheets": 1}]})
    assert design["feasible"] and design["verified"] is True
    assert design["search"]["complete"] and design["search"]["argument"] == "derived"
    got = design["surface"]
    assert got["targets_met"] and [c["sheets"] for c in got["cones"]] == [1]
    assert got["euler"] == chi(design["perturbation"]["L3"]) and got["euler_change"] == -1


def test_a_cone_homotopy_over_its_bound_is_named_through_http(client):
    """No five-bar chain (``B``'s third bar to ``G1``) and 4,608 paths of the cone homotopy: the
    splitting answers incomplete, naming the count and the bound, without running them."""
    from tests.engine.design.test_surface_critical import AT_CONE, cone_lengths
    from tests.engine.space.surfaces.conftest import spherical_five_bar

    lengths, _ = cone_lengths(*AT_CONE)
    lk = linkage_body(spherical_five_bar(*lengths, pin_b="G1")) | {"dimension": 3}
    body = post(client, "/v1/analysis/splitting", {"linkage": lk, "perturbation": {"L3": 0.05},
                                                   "options": {"time_budget_s": 4}})
    search = body["search"]
    assert not search["complete"] and search["argument"] is None
    assert "4608 paths exceed the bound of 512" in search["argument_detail"], search
    assert search["method"] == "cone homotopy and re-meshing"
    assert search["cone_search_paths"] == 4608 and body["surface"]["cones"] == []
