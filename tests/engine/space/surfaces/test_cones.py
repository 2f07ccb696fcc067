"""Meshing through the cones of critical pentagon spaces: the topology against Farber and
Schuetz's homology on both sides of the critical lengths, the apexes against the collinear
pentagons enumerated here, and the mesh near each apex against the quadratic cone of the
lengths' second-order expansion, computed here from the bars."""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest
from scipy.linalg import null_space

from engine.design.surface_splitting import resolve_cone
from engine.model.tolerances import Tolerances
from engine.space.surfaces.cones import (
    cone_fans,
    cone_morse_term,
    cone_width,
    find_cones,
    is_cone,
    resolve_apexes,
)
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.homology import manifold_defects, surface_homology
from tests.engine.design.test_surface_splitting import collinear_pentagons
from tests.engine.space.surfaces.conftest import pentagon, pentagon_betti

#: Directions of length change, tried in turn until one is generic for the lengths at hand
#: (:func:`generic_direction`): the spaces at L +- v are then generic and every cone resolves
#: one way on one side and the other way on the other, so that the critical space's Euler
#: characteristic is the mean of theirs (each cone changes it by -1 or +1). The first is off
#: every wall through (2, 1, 1, 1, 1), but not through (1, 2, 1, 1, 1): there
#: L1 + L4 = L0 + L2 + L3 and 0.013 + 0.005 = 0 + 0.007 + 0.011, so L +- V stays critical
#: and the closed form (for generic lengths) says nothing about it.
DIRECTIONS = [np.array([0.0, 0.013, 0.007, 0.011, 0.005]),
              np.array([0.0, 0.0131, 0.0067, 0.0113, 0.0049]),
              np.array([0.0029, -0.0071, 0.0123, 0.0047, -0.0101])]


def generic_direction(lengths: tuple[float, ...], skip: int = 0) -> np.ndarray:
    """The first of ``DIRECTIONS`` (after ``skip``) along which ``lengths`` leaves every wall
    ``sum eps_i L_i = 0`` (eps = +-1: a collinear polygon, where the closed form does not
    apply) that it lies on, and crosses no other: L +- v is generic on both sides."""
    lv = np.array(lengths, dtype=float)
    signs = np.array(list(product((1.0, -1.0), repeat=len(lv))))
    on = np.abs(signs @ lv) < 1e-9
    for v in DIRECTIONS[skip:]:
        if (np.abs(signs[on] @ v) > 1e-4).all() and (
                np.abs(signs[~on] @ v) < 0.5 * np.abs(signs[~on] @ lv)).all():
            return v
    raise AssertionError(f"no generic direction for {lengths}")


def chi_reference(lengths: tuple[float, ...], skip: int = 0) -> int:
    v = generic_direction(lengths, skip)
    chis = [sum((-1) ** i * b for i, b in enumerate(pentagon_betti(tuple(np.array(lengths)
                                                                        + s * v))))
            for s in (1, -1)]
    assert (chis[0] + chis[1]) % 2 == 0
    return (chis[0] + chis[1]) // 2


def second_order(lengths: tuple[float, ...], u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The zero modes Z (6, 3) and Q = Z^T H_sigma Z (3, 3) of the pentagon P0 P1 A B C (P0,
    P1 pinned at (0, 0), (L0, 0); u = (A, B, C)) at a collinear configuration, from the squared
    lengths ``|A - P1|^2, |B - A|^2, |C - B|^2, |C - P0|^2`` written out here."""
    a, b, c = u[0:2], u[2:4], u[4:6]
    p1 = np.array([lengths[0], 0.0])
    jac = np.zeros((4, 6))
    jac[0, 0:2] = 2 * (a - p1)
    jac[1, 0:2], jac[1, 2:4] = 2 * (a - b), 2 * (b - a)
    jac[2, 2:4], jac[2, 4:6] = 2 * (b - c), 2 * (c - b)
    jac[3, 4:6] = 2 * c
    sigma = null_space(jac.T)
    assert sigma.shape[1] == 1
    s = sigma[:, 0]
    eye = np.eye(2)
    hess = np.zeros((6, 6))
    hess[0:2, 0:2] += 2 * s[0] * eye
    for k, (i, j) in enumerate(((0, 2), (2, 4)), start=1):
        hess[i:i + 2, i:i + 2] += 2 * s[k] * eye
        hess[j:j + 2, j:j + 2] += 2 * s[k] * eye
        hess[i:i + 2, j:j + 2] -= 2 * s[k] * eye
        hess[j:j + 2, i:i + 2] -= 2 * s[k] * eye
    hess[4:6, 4:6] += 2 * s[3] * eye
    z = null_space(jac)
    return z, z.T @ hess @ z


def link_pieces(tri: np.ndarray, apex: int) -> list[set[int]]:
    """The apex's link as its connected pieces (sets of vertices)."""
    star = tri[(tri == apex).any(axis=1)]
    edges = [tuple(int(v) for v in t if v != apex) for t in star]
    pieces: list[set[int]] = []
    for e in edges:
        touching = [p for p in pieces if p & set(e)]
        merged = set(e).union(*touching)
        pieces = [p for p in pieces if not p & set(e)] + [merged]
    return pieces


CRITICAL = [((2, 1, 1, 1, 1), 0.15), ((2, 1, 1, 1, 1), 0.25), ((2, 1, 1, 1, 1), 0.35),
            ((1.5, 1, 1, 1, 1.5), 0.25), ((3, 1, 1.5, 1.5, 1), 0.25),
            ((1, 1.5, 1.5, 1, 1), 0.25),
            # nearly flat and narrow cones: |lam| 0.11 and 0.12 against 2.3 to 3.6
            ((1, 2, 1, 1, 1), 0.25), ((1, 1, 1, 1, 2), 0.25)]


def test_the_reference_agrees_along_other_directions():
    """The mean of the two sides' Euler characteristics does not depend on the generic
    direction; and the first direction is not generic at (1, 2, 1, 1, 1), whose reference
    along it would be -1."""
    for lengths, _ in CRITICAL:
        assert chi_reference(lengths) == chi_reference(lengths, skip=2)
    lengths = (1, 2, 1, 1, 1)
    assert generic_direction(lengths) is not DIRECTIONS[0]
    assert chi_reference(lengths) == -2


@pytest.mark.slow
@pytest.mark.parametrize(("lengths", "step"), CRITICAL)
def test_critical_spaces_are_meshed_through_their_cones(lengths, step):
    res = explore_surfaces(pentagon(lengths), options=SurfaceOptions(step_rel=step))
    s = res.search
    assert s.complete and s["argument"] == "proved", s.as_dict()
    (comp,) = res.components
    chi = chi_reference(lengths)
    assert comp.homology.euler == chi and comp.morse_sum == chi and comp.morse_agrees
    # connected, and its normalisation (the nappes parted) one closed orientable surface
    assert comp.homology.betti_q == (1, 2 - chi, 1) == comp.homology.betti_z2
    ref = collinear_pentagons(lengths)
    assert len(comp.apexes) == len(ref) == len(res.critical_points) == s["cones"]
    assert comp.defects == {"open_edges": 0, "branched_edges": 0,
                            "pinched_vertices": len(ref), "repeated_triangles": 0}
    x, tri = comp.vertices, comp.triangles
    for apex in comp.apexes:
        u = x[apex]
        assert np.abs(ref - u).sum(axis=1).min() < 1e-8
        z, q = second_order(lengths, u)
        lam, vec = np.linalg.eigh(q)
        assert lam.min() < 0 < lam.max()  # indefinite: a cone
        cp = next(cp for cp in res.critical_points if np.linalg.norm(cp.u - u) < 1e-8)
        # the engine's Q is this one up to the self-stress's sign and scale
        eng = np.sort(np.asarray(cp.analysis.q_eigenvalues))
        mine = lam if np.sign(eng).sum() == np.sign(lam).sum() else np.sort(-lam)
        assert np.allclose(eng / np.abs(eng).max(), mine / np.abs(mine).max(), atol=1e-6)
        lone = int(np.flatnonzero(np.sign(lam) != np.sign(np.sum(np.sign(lam))))[0])
        pieces = link_pieces(tri, apex)
        assert len(pieces) == 2
        sides = []
        for piece in pieces:
            gamma = (x[sorted(piece)] - u) @ z @ vec  # (k, 3) in Q's eigenbasis
            side = np.sign(gamma[:, lone])
            assert abs(side.sum()) == len(side)  # one nappe each
            sides.append(side[0])
        assert sides[0] == -sides[1]
        # near the apex (within twice its ring, at least 0.3) no triangle joins the nappes:
        # each sees one sign of the lone coordinate (at least 0.2 r from zero on these cones)
        r_all = np.linalg.norm(x - u, axis=1)
        side_all = np.sign((x - u) @ z @ vec[:, lone])
        ring_r = float(r_all[np.unique(tri[(tri == apex).any(axis=1)])].max())
        close = tri[(r_all[tri] < max(0.3, 2.0 * ring_r)).all(axis=1)
                    & (tri != apex).all(axis=1)]
        assert len(close) and (np.abs(side_all[close].sum(axis=1)) == 3).all()
        # every mesh vertex near the apex on the cone gamma^T Q gamma = 0, to third order
        delta = x - u
        r = np.linalg.norm(delta, axis=1)
        near = (r > 0) & (r < 0.6)
        gamma = delta[near] @ z
        form = np.einsum("ki,ij,kj->k", gamma, q, gamma) / np.abs(lam).max()
        assert np.all(np.abs(form) <= 4.0 * r[near] ** 3)


@pytest.mark.parametrize("lengths", [(2, 1, 1, 1, 1), (1, 2, 1, 1, 1)])
def test_fans_lie_on_the_lengths_around_the_apex(lengths):
    """Each ring on the lengths, one per nappe (the lone coordinate of Q's eigenbasis, from
    the bars here, of one sign on each ring and opposite on the two), its points the graded
    step apart; the slope of that step at most half the least gap between the quadratic
    cone's nappes (their nearest lines ``2 atan(sqrt(|lam_min| / |lam_k|))`` apart) and half
    the breadth of a nappe (``2 atan(sqrt(|lam_k| / |lam_max|))``)."""
    lk = pentagon(lengths)
    surface = Surface(lk)
    cones, ended = find_cones(lk, Tolerances(), np.random.default_rng(0))
    assert ended and len(cones) == 4 and all(is_cone(cp) for cp in cones)
    for cp in cones:
        fan = cone_fans(surface, cp, 0.25)
        assert fan is not None and len(fan.rings) == 2 and np.array_equal(fan.apex, cp.u)
        z, q = second_order(lengths, cp.u)
        lam, vec = np.linalg.eigh(q)
        lone = int(np.flatnonzero(np.sign(lam) != np.sign(np.sum(np.sign(lam))))[0])
        pair = np.abs(np.delete(lam, lone))
        gap = np.sin(np.arctan(np.sqrt(pair.min() / abs(lam[lone]))))
        breadth = np.sin(np.arctan(np.sqrt(abs(lam[lone]) / pair.max())))
        assert 0 < fan.slope <= min(gap, breadth) * (1 + 1e-3)
        sides = []
        for ring in fan.rings:
            assert len(ring) >= 5
            assert max(surface.cons.max_residual(p) for p in ring) <= 1e-9
            d = np.linalg.norm(ring - cp.u, axis=1)
            assert np.all((d > 0.05) & (d < 0.8))
            side = np.sign((ring - cp.u) @ z @ vec[:, lone])
            assert abs(side.sum()) == len(side)
            sides.append(side[0])
            spacing = np.linalg.norm(ring - np.roll(ring, 1, axis=0), axis=1)
            assert spacing.max() <= 1.5 * min(0.25, fan.slope * d.mean())
        assert sides[0] == -sides[1]


#: Critical lengths (2 - s, 1 + s, 1, 1, 1) (L0 + L1 = L2 + L3 + L4: the pentagon folded
#: flat at (3, 2, 1)): one cone, narrower as s grows, towards (1, 2, 1, 1, 1) and its four.
FAMILY = [0.25, 0.5, 0.75, 0.9]


@pytest.mark.slow
def test_narrowing_cones_are_proved_right_or_left_incomplete():
    """Along the family the cone's width falls (the smallest |lam| against the largest, from
    the bars here, falls too); each answer is either complete with Farber and Schuetz's
    topology and the collinear pentagons as apexes, or incomplete: never a wrong proved
    one. The three widest are proved; at s = 0.9 the space is close to the critical necks
    of (1, 2, 1, 1, 1) far from the cone, where the step is too coarse for the tangent-angle
    check, and the answer says so (unresolved)."""
    widths, ratios, proved = [], [], []
    for s in FAMILY:
        lengths = (2 - s, 1 + s, 1, 1, 1)
        res = explore_surfaces(pentagon(lengths))
        ref = collinear_pentagons(lengths)
        (cp,) = [cp for cp in res.critical_points if is_cone(cp)]
        assert len(ref) == 1 and np.abs(ref[0] - cp.u).max() < 1e-8
        lam = np.abs(np.linalg.eigvalsh(second_order(lengths, cp.u)[1]))
        widths.append(cone_width(cp))
        ratios.append(lam.min() / lam.max())
        if not res.search.complete:
            assert res.search.reason in ("unresolved", "degenerate", "budget")
            continue
        chi = chi_reference(lengths)
        (comp,) = res.components
        assert comp.homology.euler == chi and comp.homology.betti_q == (1, 2 - chi, 1)
        assert len(comp.apexes) == 1 and comp.morse_agrees
        proved.append(s)
    assert widths == sorted(widths, reverse=True) and ratios == sorted(ratios, reverse=True)
    assert proved == [0.25, 0.5, 0.75]


def test_the_apex_term_of_the_morse_count():
    """Along the cone's axis the level through the apex misses both nappes (term 1); across
    it, it cuts both (term -1)."""
    lk = pentagon((2, 1, 1, 1, 1))
    cones, _ = find_cones(lk, Tolerances(), np.random.default_rng(0))
    cp = cones[0]
    lam, z = np.asarray(cp.analysis.q_eigenvalues), np.asarray(cp.analysis.zero_modes)
    lone = int(np.flatnonzero(np.sign(lam) != np.sign(np.sum(np.sign(lam))))[0])
    other = (lone + 1) % 3
    assert cone_morse_term(cp, z[lone]) == 1
    assert cone_morse_term(cp, z[other]) == -1


@pytest.mark.slow
def test_resolving_the_apexes_gives_the_perturbed_homology():
    """The critical space's mesh with each apex split (two sheets) or tubed (one sheet) as its
    cone resolves under dL has Farber and Schuetz's homology at L + dL, for changes that
    resolve the cones alike and differently."""
    lengths = (2.0, 1.0, 1.0, 1.0, 1.0)
    lk = pentagon(lengths)
    res = explore_surfaces(lk)
    (comp,) = res.components
    cps = [next(cp for cp in res.critical_points if np.linalg.norm(cp.u - comp.vertices[a])
                < 1e-8) for a in comp.apexes]
    seen = set()
    for d_l in ([0, 0, 0.08, 0, 0], [0, 0, -0.08, 0, 0], [0, 0.05, 0.05, 0.05, 0.05],
                [0, -0.05, -0.05, -0.05, -0.05], [0, -0.02, 0.05, 0.03, -0.04],
                [0, 0, 0, 0.07, 0], [0, 0, 0, 0, 0.07]):
        d_l = np.array(d_l)
        sheets = np.array([resolve_cone(lk, cp, d_l).sheets for cp in cps])
        assert set(sheets.tolist()) <= {1, 2}
        seen.add(tuple(sheets))
        _, tri = resolve_apexes(comp.vertices, comp.triangles, comp.apexes, sheets)
        h = surface_homology(tri)
        assert h.betti_q == pentagon_betti(tuple(np.array(lengths) + d_l)) == h.betti_z2
        assert h.orientable and not any(manifold_defects(tri).values())
    assert len(seen) >= 6
