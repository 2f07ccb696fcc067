"""Configuration-space, critical-points, splitting and design endpoints through HTTP."""

from __future__ import annotations

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
    """options.homotopy_paths_max = 0 skips the sweeps of the box's edges (the three-rotor's
    take 400 paths each): the curves come from the seed lengths, the answer is at best
    searched; the four-bar's closed form needs no sweep and stays complete; out of bounds 422."""
    lk = preset(client, "three-rotor")
    axes = [{"bar": "r2", "min": 0.4, "max": 2.5}, {"bar": "r3", "min": 0.4, "max": 2.5}]
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
    assert body["search"]["reason"] == "searched"  # 1024 homotopy paths beyond 512
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
