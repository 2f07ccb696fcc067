"""Surfaces of D = 2 linkages end to end: five-bars against a dense grid of their crank
angles, a 3D sphere and a sliding torus (proved by the homotopy), the budget, the deadline
and the refusal of other degrees of freedom."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.budget import Deadline
from engine.model.errors import InvalidLinkage
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces
from tests.engine.space.surfaces.conftest import (
    five_bar,
    five_bar_reference,
    pentagon,
    pentagon_betti,
    slider_torus,
    sphere_3d,
)


@pytest.mark.parametrize("lengths", [(2, 1, 1.4, 1.6, 1), (3, 1.5, 1.2, 1.5, 1.1)])
def test_five_bar_against_the_crank_angle_grid(lengths):
    chi, comps = five_bar_reference(*lengths)
    res = explore_surfaces(five_bar(*lengths), options=SurfaceOptions(step_rel=0.4))
    assert len(res.components) == comps
    assert sum(c.homology.euler for c in res.components) == chi
    for c in res.components:
        assert c.closed and c.homology.orientable and c.morse_agrees
        assert not any(c.defects.values()) and c.inverted == 0
    assert not res.critical_points


@pytest.mark.parametrize(("build", "betti"), [(sphere_3d, (1, 0, 1)),
                                              (slider_torus, (1, 2, 1))])
def test_3d_surfaces_are_proved(build, betti):
    res = explore_surfaces(build())
    assert [c.homology.betti_q for c in res.components] == [betti]
    assert [c.homology.betti_z2 for c in res.components] == [betti]
    s = res.search
    assert s.complete and s["argument"] == "proved", s.as_dict()
    assert (res.height_component == 0).all()
    assert res.components[0].morse_sum == 2 - 2 * (betti[1] // 2)


def test_pentagon_without_the_homotopy_is_searched():
    # below the linear product's 2^4 C(6, 4) = 240 paths the homotopy is not run; the
    # equilateral pentagon is a five-bar chain whose couplers are equal (l2 = l3: over A = C the
    # middle vertex runs on a circle), which engine.space.surfaces.five_bar leaves alone
    res = explore_surfaces(pentagon((1, 1, 1, 1, 1)),
                           options=SurfaceOptions(step_rel=0.35, homotopy_paths_max=239))
    (comp,) = res.components
    assert comp.homology.genus == 4 and comp.morse_agrees
    assert res.search.reason == "searched" and res.search["five_bar_chain"] is None
    assert "240 paths exceed" in res.search["homotopy"]
    assert res.search["homotopy_start"] is None


def test_pentagon_without_the_homotopy_is_derived():
    """Couplers 1.2 and 1: the five-bar chain's crank angles seed it (24 paths); Farber and
    Schuetz give its Betti numbers."""
    lengths = (1, 1, 1.2, 1, 1)
    res = explore_surfaces(pentagon(lengths),
                           options=SurfaceOptions(step_rel=0.35, homotopy_paths_max=239))
    (comp,) = res.components
    assert comp.homology.betti_q == pentagon_betti(lengths) and comp.morse_agrees
    assert res.search.complete and res.search["argument"] == "derived"
    assert "240 paths exceed" in res.search["homotopy"]


def test_without_the_homotopy_nor_a_chain_is_searched():
    # the sliding torus is no five-bar chain: below its 2^3 C(5, 3) = 80 paths, searched
    res = explore_surfaces(slider_torus(), options=SurfaceOptions(homotopy_paths_max=79))
    (comp,) = res.components
    assert comp.homology.betti_q == (1, 2, 1) and comp.morse_agrees
    assert res.search.reason == "searched" and res.search["five_bar_chain"] is None
    assert "80 paths exceed" in res.search["homotopy"]


def test_pentagon_is_proved_by_the_linear_product():
    """Within the default 512 paths: the linear product's 240 (the total degree's 1024 would
    not fit); Farber and Schuetz give the genus, the Morse sum agrees."""
    lengths = (1, 1, 1, 1, 1)
    res = explore_surfaces(pentagon(lengths), options=SurfaceOptions(step_rel=0.35))
    (comp,) = res.components
    b = pentagon_betti(lengths)
    assert comp.homology.betti_q == b and comp.morse_agrees
    s = res.search
    assert s.complete and s["argument"] == "proved", s.as_dict()
    assert (s["homotopy_start"], s["homotopy_paths"]) == ("linear product", 240)
    assert "linear product" in str(s.argument_detail)


def test_budget_and_deadline():
    lk = pentagon((1, 1, 1, 1, 1))
    res = explore_surfaces(lk, options=SurfaceOptions(max_triangles=300, random_starts=0,
                                                      homotopy_paths_max=0))
    assert res.search.reason == "budget"
    assert not res.components[0].closed
    res = explore_surfaces(lk, deadline=Deadline.after(0.0))
    assert res.search.reason == "time"


def test_other_degrees_of_freedom_and_unbounded_spaces_are_refused():
    with pytest.raises(InvalidLinkage, match="M - E = 2"):
        explore_surfaces(build_preset("four-bar"))
    plane = build_linkage(2, [VertexSpec("P", (0, 0), True), VertexSpec("A", (1, 0))], [])
    with pytest.raises(InvalidLinkage, match="unbounded"):
        explore_surfaces(plane)
    # a bar between two free vertices in 2D (three rigid motions, M - E = 3) is refused for its
    # degrees of freedom; one free vertex on a slider with a bar to a free vertex is unbounded
    slider = build_linkage(2, [VertexSpec("S", (0, 0), (False, True)), VertexSpec("A", (1, 0)),
                               VertexSpec("P", (5, 5), True)],
                           [BarSpec("b", ("S", "A"))])
    with pytest.raises(InvalidLinkage, match="unbounded"):
        explore_surfaces(slider)


def test_two_components_are_both_meshed():
    """A five-bar whose coupler triangle never flips (short cranks): the crank region is the
    whole torus, so the space is two tori (B on either side of A C), both meshed (Farber and
    Schuetz agree: b = (2, 4, 2) for these pentagon lengths)."""
    lengths = (2, 0.5, 1.6, 1.4, 0.45)
    chi, comps = five_bar_reference(*lengths)
    assert (chi, comps) == (0, 2)
    res = explore_surfaces(five_bar(*lengths), options=SurfaceOptions(step_rel=0.4))
    assert len(res.components) == 2
    assert [c.homology.betti_q for c in res.components] == [(1, 2, 1)] * 2
    assert np.all([c.closed and c.morse_agrees for c in res.components])


def test_critical_lengths_locate_the_cones():
    """At lengths (2, 1, 1, 1, 1) the pentagon has critical configurations: a planar polygon
    is critical exactly where all its bars are parallel (the ground bar and one other against
    the remaining three, 2 + 1 = 1 + 1 + 1). They are found, collinear, with Q indefinite on
    their three zero modes (cones); the surface is meshed through them (each an apex of the
    mesh) and the answer is complete (tests/engine/space/surfaces/test_cones.py checks the
    topology and the shape there)."""
    res = explore_surfaces(pentagon((2, 1, 1, 1, 1)))
    assert len(res.critical_points) == 4
    for cp in res.critical_points:
        ys = cp.u[1::2]  # the free coordinates are (x, y) of A, B, C
        assert np.abs(ys).max() < 1e-6  # collinear with the pinned bar on the x axis
        q = cp.analysis.q_eigenvalues
        assert len(q) == 3 and q.max() > 0 > q.min()
    (comp,) = res.components
    assert sorted(comp.critical_points) == [0, 1, 2, 3] and len(comp.apexes) == 4
    assert res.search.complete and res.search["cones"] == 4


def test_a_critical_point_that_is_no_cone_leaves_the_answer_degenerate():
    """At lengths (4, 1, 1, 1, 1) the pentagon can only lie stretched out: its space is one
    point, critical with Q definite (rigid), a component no surface holds: the answer is
    degenerate, not complete."""
    res = explore_surfaces(pentagon((4, 1, 1, 1, 1)))
    assert [cp.kind for cp in res.critical_points] == ["rigid"]
    assert not any(len(c.triangles) for c in res.components)
    assert res.search.reason == "degenerate" and not res.search.complete
