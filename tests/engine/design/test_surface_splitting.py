"""Cones of a two-degree-of-freedom space and how they resolve, against Farber and Schuetz's
homology of planar pentagon spaces at lengths on both sides of a critical length vector, and the
cones themselves against the collinear pentagons enumerated here."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest

from engine.design.surface_splitting import remesh_split, resolve_cone, split_surface
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import find_cones
from tests.engine.space.surfaces.conftest import pentagon, pentagon_betti

CRITICAL = (2.0, 1.0, 1.0, 1.0, 1.0)


def collinear_pentagons(lengths: tuple[float, ...]) -> np.ndarray:
    """Free coordinates (x_A, y_A, x_B, y_B, x_C, y_C) of every pentagon P0 P1 A B C with
    P0 = 0, P1 = (L0, 0) lying on the x axis: each bar after the ground one points along +-x,
    and the last closes the loop at P0."""
    out = []
    for signs in product((1.0, -1.0), repeat=4):
        x = lengths[0]
        pts = []
        for s, length in zip(signs[:3], lengths[1:4], strict=True):
            x += s * length
            pts.append(x)
        if abs(pts[-1] + signs[3] * lengths[4]) < 1e-12:
            out.append([pts[0], 0.0, pts[1], 0.0, pts[2], 0.0])
    return np.array(out)


def euler(b: tuple[int, int, int]) -> int:
    return b[0] - b[1] + b[2]


def test_every_cone_is_found_by_the_homotopy():
    lk = pentagon(CRITICAL)
    cps, ended = find_cones(lk, Tolerances(), np.random.default_rng(0))
    ref = collinear_pentagons(CRITICAL)
    assert ended and len(ref) == 4 and len(cps) == len(ref)
    got = np.array([cp.u for cp in cps])
    gap = np.linalg.norm(got[:, None] - ref[None], axis=2)
    assert gap.min(axis=1).max() < 1e-8 and gap.min(axis=0).max() < 1e-8
    for cp in cps:
        q = cp.analysis.q_eigenvalues
        assert len(q) == 3 and q.max() > 0 > q.min()


def test_a_cone_resolves_the_other_way_under_the_opposite_change():
    lk = pentagon(CRITICAL)
    cps, _ = find_cones(lk, Tolerances(), np.random.default_rng(1))
    d_l = np.zeros(5)
    d_l[2] = 0.05
    for cp in cps:
        up, down = resolve_cone(lk, cp, d_l), resolve_cone(lk, cp, -d_l)
        assert up.sign == -down.sign != 0
        assert {up.sheets, down.sheets} == {1, 2}
        assert up.euler_change == -down.euler_change


@pytest.mark.parametrize(("bar", "change"), [(1, 0.1), (1, -0.1)])
def test_the_predicted_topology_change_matches_farber_schuetz_and_the_re_meshing(bar, change):
    lk = pentagon(CRITICAL)
    d_l = np.zeros(5)
    d_l[bar] = change
    res = split_surface(lk, d_l)
    plus = pentagon_betti(tuple(np.asarray(CRITICAL) + d_l))
    minus = pentagon_betti(tuple(np.asarray(CRITICAL) - d_l))
    assert len(res.cones) == 4 and all(c.sheets in (1, 2) for c in res.cones)
    # the prediction against the published homology on both sides
    assert res.predicted_euler_difference == euler(plus) - euler(minus)
    # and the re-meshing against it too
    assert res.euler == (euler(plus), euler(minus))
    assert res.betti == (plus, minus)
    # the Betti numbers predicted from the critical space's mesh with its apexes resolved
    assert res.predicted_betti == (plus, minus)
    assert res.verified and res.search["verified"]


def test_an_unproved_splitting_says_why():
    """When the cones' homotopy did not end on every path the answer is incomplete and its
    ``argument_detail`` says so (what it did establish), never an empty reason."""
    lk = pentagon((1.0, 1.0, 1.0, 1.0, 1.0))  # generic: no cone
    res = remesh_split(lk, [], False, np.array([0.0, 1e-3, 0.0, 0.0, 0.0]), Tolerances())
    assert not res.complete and res.search.reason == "searched"
    detail = res.search.argument_detail
    assert detail is not None and "did not end" in detail, detail
    assert res.search.argument is None


@pytest.mark.parametrize(("lengths", "change", "moved"), [
    ((1.0, 1.0, 1.0, 1.0, 1.0), 1e-3, True),  # no cone: L - dL's meshes are L + dL's, moved
    ((2.0, 1.03, 1.0, 1.0, 1.0), 0.06, False),  # a critical value between: marched again
])
def test_a_splitting_without_cones_against_farber_schuetz(lengths, change, moved):
    """Lengths with no cone: the cones' and heights' homotopy (one, along L + w dL) and the
    re-meshings give Farber and Schuetz's homology on both sides; the second side's meshes
    are moved from the first's where no critical value lies between them, and marched again
    where one does (the move would be too long)."""
    lk = pentagon(lengths)
    d_l = np.array([0.0, change, 0.0, 0.0, 0.0])
    res = split_surface(lk, d_l)
    plus = pentagon_betti(tuple(np.asarray(lengths) + d_l))
    minus = pentagon_betti(tuple(np.asarray(lengths) - d_l))
    assert res.cones == [] and res.complete
    assert res.betti == (plus, minus) and res.euler == (euler(plus), euler(minus))
    assert res.search["minus_side_mesh"] == ("moved" if moved else "marched")
    # no cone predicts no change: verified only where the spaces agree
    assert res.predicted_euler_difference == 0
    assert res.verified == (euler(plus) == euler(minus))
    assert res.search.argument == ("proved" if res.verified else None)


@pytest.mark.parametrize("change", [0.05, -0.05, pytest.param(0.02, marks=pytest.mark.slow)])
def test_a_spherical_five_bar_cone_resolves_as_the_crank_angle_grid_says(change):
    """A spherical five-bar with ``L3`` at a cone (``A``, ``B``, ``C`` on one great circle; the
    cone homotopy would need 4,608 paths): the chain's argument derives the cone (24 paths),
    and the Euler characteristics at ``L3 +- dL`` and their predicted difference are those of
    the dense grid of crank angles with ``B`` where three spheres meet (a double cover of the
    band, branched along its edge); the critical space's is the grid's at ``L3`` less one (the
    cone's apex pinches the cover)."""
    from tests.engine.design.test_surface_critical import AT_CONE, cone_lengths
    from tests.engine.space.surfaces.conftest import (
        spherical_five_bar,
        spherical_five_bar_reference,
    )

    lengths, _ = cone_lengths(*AT_CONE)
    lk = spherical_five_bar(*lengths)
    d_l = np.zeros(7)
    d_l[lk.bar_ids.index("L3")] = change
    res = split_surface(lk, d_l)
    chi = [sum(spherical_five_bar_reference(*np.add(lengths, (0, 0, 0, s * change, 0))))
           for s in (1, -1)]
    assert chi[0] != chi[1]  # the cone changes the topology
    (cone,) = res.cones
    assert cone.sheets in (1, 2) and cone.euler_change == 2 * cone.sheets - 3
    assert res.predicted_euler_difference == chi[0] - chi[1]
    assert res.euler == (chi[0], chi[1])
    critical = res.critical_betti
    assert critical is not None
    assert critical[0] - critical[1] + critical[2] == \
        sum(spherical_five_bar_reference(*lengths)) - 1
    assert res.predicted_betti == res.betti
    assert res.verified and res.complete
    s = res.search
    assert s.complete and s.argument == "derived", s.as_dict()
    assert s["method"] == "five-bar chain and re-meshing" and s["cone_search_paths"] == 24
    assert "24 paths" in str(s.argument_detail)
