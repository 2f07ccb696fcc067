"""Preset endpoints."""

import numpy as np
import pytest

from tests.engine.space.surfaces.conftest import pentagon_betti, spherical_five_bar_reference
from tests.service.test_spatial_polygons import CASES as QUADRILATERALS
from tests.service.test_spatial_polygons import (
    check_positions,
    closed_manifold,
    reference_labels,
    references_agree,
)


def test_list_presets(client):
    r = client.get("/v1/presets")
    assert r.status_code == 200
    body = {p["name"]: p for p in r.json()}
    assert {"four-bar", "three-rotor", "kl-chain", "gated-kl-chain"} <= set(body)
    catalogue = {"tetrahedron", "octahedron", "bricard-line", "bricard-plane", "three-prism",
                 "three-prism-flexible", "k33-conic", "k33-dixon", "cn-symmetric-four-regular",
                 "rotor-chain-3d"}
    mechanisms = {"pentagon", "five-bar", "spherical-four-bar", "sphere-slider",
                  "spherical-five-bar", "spatial-quadrilateral"}
    planar = {"four-bar", "three-rotor", "kl-chain", "gated-kl-chain"}
    assert set(body) == planar | catalogue | mechanisms
    assert body["tetrahedron"]["dimension"] == 3 and body["four-bar"]["dimension"] == 2
    assert {"a", "L1", "L2", "L3"} <= set(body["four-bar"]["parameters"])
    assert {"a", "r1", "r2", "r3", "L1", "L2", "phi"} <= set(body["three-rotor"]["parameters"])
    assert {"n", "a", "r", "l"} <= set(body["kl-chain"]["parameters"])
    assert {"n", "a", "r", "l", "gate", "D", "L1", "L2"} <= set(
        body["gated-kl-chain"]["parameters"]
    )


def test_preset_with_parameters_is_a_linkage_on_its_configuration_space(client):
    r = client.get("/v1/presets/four-bar?L2=1.1&a=1.2")
    assert r.status_code == 200
    lk = r.json()
    lengths = {b["id"]: b["length"] for b in lk["bars"]}
    assert lengths["L2"] == 1.1
    pos = {v["id"]: np.array(v["position"]) for v in lk["vertices"]}
    for b in lk["bars"]:
        i, j = b["ends"]
        assert abs(np.linalg.norm(pos[i] - pos[j]) - b["length"]) < 1e-12
    assert pos["P2"].tolist() == [1.2, 0.0]
    # and it round-trips into an analysis without projection
    body = client.post("/v1/analysis/rigidity", json={"linkage": lk}).json()
    assert body["projection_distance"] == 0.0 and body["dof"] == 1


def test_kl_chain_size(client):
    lk = client.get("/v1/presets/kl-chain?n=25").json()
    assert len(lk["vertices"]) == 50 and len(lk["bars"]) == 49


def space_of(client, query: str, arguments: tuple[str, ...] = ("proved",)) -> dict:
    lk = client.get(f"/v1/presets/{query}")
    assert lk.status_code == 200, lk.text
    r = client.post("/v1/analysis/configuration-space", json={"linkage": lk.json()})
    assert r.status_code == 200, (query, r.text[:500])
    body = r.json()
    assert body["search"]["complete"], (query, body["search"])
    assert body["search"]["reason"] is None and body["search"]["argument"] in arguments
    return body


#: (query, lengths (L0..L4) of the polygon): the five-bar is a pentagon too, its ground a as L0.
POLYGONS = [
    ("pentagon", (1.0, 1.0, 1.0, 1.0, 1.0)),
    ("pentagon?L0=2&L1=1&L2=1.4&L3=1.6&L4=1", (2.0, 1.0, 1.4, 1.6, 1.0)),
    ("five-bar", (1.0, 1.0, 1.3, 1.2, 1.0)),
    ("five-bar?a=2&L2=1.4&L3=1.6", (2.0, 1.0, 1.4, 1.6, 1.0)),
]


@pytest.mark.slow
@pytest.mark.parametrize(("query", "lengths"), POLYGONS)
def test_planar_polygon_presets_against_farber_schuetz(client, query, lengths):
    """The configuration space of a pinned-bar pentagon is the planar polygon space (modulo
    orientation-preserving isometries): its Betti numbers by Farber and Schuetz's closed form
    (tests/engine/space/surfaces/conftest.py), over Z/2 and Q; connected, so one surface."""
    body = space_of(client, query)
    assert body["search"]["dof"] == 2
    betti = list(pentagon_betti(lengths))
    assert [s["betti_q"] for s in body["surfaces"]] == [betti]
    assert [s["betti_z2"] for s in body["surfaces"]] == [betti]
    surface = body["surfaces"][0]
    assert surface["closed"] and surface["orientable"] and surface["morse_agrees"]
    assert surface["euler"] == betti[0] - betti[1] + betti[2]


@pytest.mark.slow
@pytest.mark.parametrize("lengths", [(1.0, 2.0, 1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0, 2.0)])
def test_pentagon_through_nearly_flat_cones_is_proved(client, lengths):
    """At (1, 2, 1, 1, 1) and (1, 1, 1, 1, 2) the pentagon's four cones are nearly flat or
    narrow (one |lam| about 0.1 against 2 to 3.6): complete and proved, one surface pinched
    at the four collinear pentagons, its Euler characteristic the mean of Farber and
    Schuetz's on the two sides of the lengths along a generic change (-2)."""
    from tests.engine.space.surfaces.test_cones import chi_reference

    query = "pentagon?" + "&".join(f"L{k}={x}" for k, x in enumerate(lengths))
    lk = client.get(f"/v1/presets/{query}")
    assert lk.status_code == 200, lk.text
    r = client.post("/v1/analysis/configuration-space",
                    json={"linkage": lk.json(), "options": {"time_budget_s": 120}})
    assert r.status_code == 200, r.text[:500]
    body = r.json()
    assert body["search"]["complete"] and body["search"]["argument"] == "proved", body["search"]
    chi = chi_reference(lengths)
    assert chi == -2
    (surf,) = body["surfaces"]
    assert surf["closed"] and surf["morse_agrees"] and surf["inverted_triangles"] == 0
    assert surf["euler"] == surf["morse_sum"] == chi and surf["genus"] is None
    assert surf["betti_q"] == surf["betti_z2"] == [1, 2 - chi, 1]
    assert len(surf["apexes"]) == surf["defects"]["pinched_vertices"] == 4
    for k in surf["apexes"]:  # collinear: every vertex on the x axis
        assert max(abs(p[k][1]) for p in surf["positions"].values()) < 1e-8


@pytest.mark.slow
def test_sphere_slider_is_a_torus(client):
    """For every B on its circle, A runs on the circle where the spheres about P and B meet: an
    orientable circle bundle over a circle, a torus (b = 1, 2, 1)."""
    body = space_of(client, "sphere-slider")
    assert body["search"]["dof"] == 2
    assert [s["betti_q"] for s in body["surfaces"]] == [[1, 2, 1]]
    assert body["surfaces"][0]["euler"] == 0


def test_spherical_four_bar_is_a_curve(client):
    """One degree of freedom: traced (closed form of the 3D hinged rotor chain), no surface."""
    lk = client.get("/v1/presets/spherical-four-bar").json()
    r = client.post("/v1/analysis/configuration-space", json={"linkage": lk})
    assert r.status_code == 200, r.text[:500]
    body = r.json()
    assert body["search"]["complete"] and body["search"]["reason"] is None
    assert body["search"]["argument"] in ("derived", "proved")
    assert not body["surfaces"] and body["components"]


@pytest.mark.parametrize(("query", "field"), [
    ("pentagon?L0=5", "L0"), ("five-bar?L1=-1", "L1"), ("spherical-four-bar?L2=2.5", "L2"),
    ("sphere-slider?c=0.5", "c"), ("spherical-five-bar?R=0.5", "R"),
    ("spherical-five-bar?L4=2", "L4"), ("spatial-quadrilateral?l4=3", "l4")])
def test_mechanism_parameters_that_give_no_assembly_are_named(client, query, field):
    r = client.get(f"/v1/presets/{query}")
    assert r.status_code == 422 and r.headers["content-type"].startswith("application/problem")
    assert r.json()["errors"][0]["loc"] == ["query", field]


#: (query, g, L1..L4 on the unit sphere): the defaults (genus 3), a second generic set (genus 4)
#: and the defaults on a sphere of radius 2.
SPHERICAL_FIVE_BARS = [
    ("spherical-five-bar", (1.2, 0.6, 1.0, 0.9, 0.7)),
    ("spherical-five-bar?g=1.0&L1=0.8&L2=0.9&L3=1.1&L4=0.6&side=-1", (1.0, 0.8, 0.9, 1.1, 0.6)),
    # every length doubled with the radius: the same space, scaled
    ("spherical-five-bar?R=2&g=2.4&L1=1.2&L2=2&L3=1.8&L4=1.4", (1.2, 0.6, 1.0, 0.9, 0.7)),
]


@pytest.mark.slow
@pytest.mark.parametrize(("query", "lengths"), SPHERICAL_FIVE_BARS)
def test_spherical_five_bar_against_dense_sampling(client, query, lengths):
    """The components' Euler characteristics against the dense sampling of its crank angles
    (tests/engine/space/surfaces/conftest.py: the branched double cover of the region of the
    crank torus where B is real), every surface closed and orientable (a regular level set).
    The engine's argument may be ``derived`` (the five-bar chain's band, its homotopy ended)."""
    body = space_of(client, query, ("derived", "proved"))
    assert body["search"]["dof"] == 2
    surfaces = body["surfaces"]
    assert sorted(s["euler"] for s in surfaces) == spherical_five_bar_reference(*lengths)
    for s in surfaces:
        assert s["closed"] and s["orientable"] and s["morse_agrees"]
        assert s["betti_q"] == s["betti_z2"] == [1, 2 - s["euler"], 1]
        assert s["genus"] == (2 - s["euler"]) // 2


def test_spherical_five_bar_default_is_genus_three():
    """What the preset's description says of its defaults, by the reference alone."""
    assert spherical_five_bar_reference(1.2, 0.6, 1.0, 0.9, 0.7) == [-4]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "lengths"), QUADRILATERALS)
def test_spatial_quadrilateral_against_spatial_polygon_references(client, name, lengths):
    """Two spheres, a sphere or a torus by the lengths: the preset through HTTP against the
    references of tests/service/test_spatial_polygons.py (Klyachko's Poincare polynomial with
    the blow-up, the fibres over the diagonal and dense sampling), each surface in its own
    sampled component, on the bars to residual_atol."""
    exp = references_agree(lengths)
    query = "spatial-quadrilateral?" + "&".join(
        f"l{k + 1}={x}" for k, x in enumerate(lengths))
    body = space_of(client, query)
    surfaces = body["surfaces"]
    assert len(surfaces) == exp["components"], name
    seen: set[int] = set()
    for surf, want in zip(surfaces, exp["each"], strict=True):
        assert surf["closed"] and surf["orientable"] and surf["morse_agrees"]
        assert (surf["euler"], surf["genus"]) == (want["euler"], want["genus"])
        assert surf["betti_q"] == surf["betti_z2"] == want["betti"]
        assert closed_manifold(np.array(surf["triangles"])) == (True, True)
        pos = {v: np.array(p) for v, p in surf["positions"].items()}
        check_positions(pos, lengths, body["tolerances"]["residual_atol"])
        labels = reference_labels(pos, lengths, exp["label"])
        assert len(labels) == 1 and not labels & seen
        seen |= labels
    assert seen == set(range(exp["components"]))
