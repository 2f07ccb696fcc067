"""Prestress stability through HTTP: the certificates checked as a client would, with numpy
and nothing but the response and the linkage it posted."""

from __future__ import annotations

import numpy as np
import pytest


def client_energy(linkage, stress, flexes):
    """``Q`` of a stress ``{bar: w}`` on flexes ``[{vertex: [..]}]``: the energy
    ``sum_a w_a 2 |f_i - f_j|^2`` as a bilinear form (what a client computes by hand)."""
    q = np.zeros((len(flexes), len(flexes)))
    for bar in linkage["bars"]:
        i, j = bar["ends"]
        diffs = np.array([np.subtract(f[i], f[j]) for f in flexes])  # (k, d)
        q += 2.0 * stress[bar["id"]] * diffs @ diffs.T
    return q


def client_jacobian_times(linkage, vectors):
    """``J v`` for per-vertex vectors, from the positions (rows 2 (p_i - p_j))."""
    pos = {v["id"]: np.array(v["position"], float) for v in linkage["vertices"]}
    return np.array([2 * (pos[b["ends"][0]] - pos[b["ends"][1]])
                     @ (np.subtract(vectors[b["ends"][0]], vectors[b["ends"][1]]))
                     for b in linkage["bars"]])


def post(client, linkage):
    r = client.post("/v1/analysis/second-order", json={"linkage": linkage})
    assert r.status_code == 200, r.text
    return r.json()


@pytest.mark.parametrize("name", ["three-prism", "k33-conic", "cn-symmetric-four-regular"])
def test_stress_certificate_checks_on_the_client(client, name):
    lk = client.get(f"/v1/presets/{name}").json()
    body = post(client, lk)
    assert body["prestress_stable"] is True and body["second_order_rigid"] is True
    cert = body["certificate"]
    assert set(cert) == {"stress", "min_eigenvalue"}
    stress = cert["stress"]
    # a self-stress: sum over bars at each vertex of w_a (p_i - p_j) vanishes
    pos = {v["id"]: np.array(v["position"], float) for v in lk["vertices"]}
    force = {v: np.zeros(len(p)) for v, p in pos.items()}
    for b in lk["bars"]:
        i, j = b["ends"]
        force[i] += stress[b["id"]] * (pos[i] - pos[j])
        force[j] -= stress[b["id"]] * (pos[i] - pos[j])
    assert max(np.abs(f).max() for f in force.values()) < 1e-9
    # positive definite on the flexes the same response lists
    q = client_energy(lk, stress, body["zero_modes"])
    assert np.linalg.eigvalsh(q)[0] > 1e-6


@pytest.mark.parametrize("name", ["bricard-line", "bricard-plane", "three-prism-flexible",
                                  "k33-dixon"])
def test_flexible_presets_carry_a_dual_certificate_and_a_second_order_flex(client, name):
    lk = client.get(f"/v1/presets/{name}").json()
    body = post(client, lk)
    assert body["prestress_stable"] is False and body["second_order_rigid"] is False
    cert = body["certificate"]
    assert set(cert) == {"dual", "flexes", "dual_residual"}
    x = np.array(cert["dual"])
    assert np.linalg.eigvalsh(x)[0] >= -1e-12 and abs(np.trace(x) - 1) < 1e-12
    for f in cert["flexes"]:
        assert np.abs(client_jacobian_times(lk, f)).max() < 1e-9
    stress = body["self_stress"]  # these presets have one self-stress
    assert stress is not None
    assert abs(np.sum(client_energy(lk, stress, cert["flexes"]) * x)) < 1e-8
    flex = body["second_order_flex"]
    jv = client_jacobian_times(lk, flex["velocity"])
    ja = client_jacobian_times(lk, flex["acceleration"])
    energy = np.array([2 * np.sum(np.subtract(flex["velocity"][b["ends"][0]],
                                              flex["velocity"][b["ends"][1]]) ** 2)
                       for b in lk["bars"]])
    assert np.abs(jv).max() < 1e-9 and np.abs(ja + energy).max() < 1e-8


def test_several_stresses_and_flexes_through_http(client):
    """A collinear 3D star: two stresses, two flexes; kind stays 'degenerate' (one-stress
    classification) while the new fields decide."""
    lk = {
        "dimension": 3,
        "vertices": [{"id": "A", "position": [1, 0, 0]}]
        + [{"id": f"P{i}", "position": [x, 0, 0], "fixed": True} for i, x in enumerate((0, 2, 3))],
        "bars": [{"id": f"a{i}", "ends": ["A", f"P{i}"]} for i in range(3)],
    }
    body = post(client, lk)
    assert body["kind"] == "degenerate" and "2 self-stresses" in body["reason"]
    assert body["prestress_stable"] is True and body["second_order_rigid"] is True
    assert "prestress stable" in body["stability_reason"]
    q = client_energy(lk, body["certificate"]["stress"], body["zero_modes"])
    assert np.linalg.eigvalsh(q)[0] > 1e-6


def test_regular_point_is_flexible_not_stable(client):
    lk = client.get("/v1/presets/four-bar").json()
    body = post(client, lk)
    assert body["kind"] == "regular"
    assert body["prestress_stable"] is False and body["second_order_rigid"] is False
    assert body["second_order_flex"] is not None


@pytest.mark.parametrize(("query", "field"), [
    ("cn-symmetric-four-regular?n=9", "n"),
    ("rotor-chain-3d?h=-1", "h"),
    ("bricard-line?w=1", "w"),
])
def test_bad_catalogue_parameters_are_422_naming_the_field(client, query, field):
    r = client.get(f"/v1/presets/{query}")
    assert r.status_code == 422
    assert r.headers["content-type"].startswith("application/problem+json")
    assert field in r.text
    assert client.get("/health").status_code == 200
