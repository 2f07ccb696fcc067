"""Five-bar chains seeded by their crank angles: spherical five-bars (4,608 paths of the Lagrange
homotopy, past its bound) against dense grids of the crank angles with ``B`` where three spheres
meet, a cone found by the argument and checked by the rank of ``J``, the recognition of the
chain, and the seeds themselves."""

from __future__ import annotations

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.budget import NEVER
from engine.space.surfaces.explore import explore_surfaces
from engine.space.surfaces.five_bar import chain_seeds, five_bar_chain, lift
from engine.space.surfaces.geometry import Surface
from tests.engine.space.surfaces.conftest import (
    _middle,
    _on_circle,
    _sphere_pins,
    cone_lengths,
    five_bar,
    pentagon,
    slider_torus,
    spherical_five_bar,
    spherical_five_bar_reference,
)

#: (g, L1, L2, L3, L4): genus 3, two tori, the whole torus of crank angles (two tori: the two
#: sides of the plane O A C never meet), genus 5, genus 2.
CASES = [(1.2, 0.6, 1.0, 0.9, 0.7), (1.2, 0.6, 0.5, 1.5, 1.4), (0.5, 0.6, 1.6, 1.5, 1.4),
         (1.2, 1.2, 1.0, 1.5, 1.4), (1.2, 0.6, 1.0, 0.4, 1.4)]


def jacobian(linkage, u: np.ndarray) -> np.ndarray:
    """``J`` (E, M) from the bar vectors, written here: row ``ab`` has ``2 (p_a - p_b)`` at
    ``a``'s free coordinates and the negative at ``b``'s."""
    pos = linkage.positions_of(u)
    free = np.full(linkage.fixed.shape, -1)
    free[~linkage.fixed] = np.arange(linkage.n_free)
    jac = np.zeros((linkage.n_bars, linkage.n_free))
    for k, (a, b) in enumerate(linkage.ends):
        for v, sign in ((a, 1.0), (b, -1.0)):
            cols = free[v] >= 0
            jac[k, free[v][cols]] += sign * 2 * (pos[a] - pos[b])[cols]
    return jac


@pytest.mark.parametrize("lengths", CASES[:1] + [pytest.param(c, marks=pytest.mark.slow)
                                                  for c in CASES[1:]])
def test_spherical_five_bar_against_the_crank_angle_grid(lengths):
    lk = spherical_five_bar(*lengths)
    res = explore_surfaces(lk)
    s = res.search
    assert s.complete and s["argument"] == "derived", s.as_dict()
    assert "4608 paths exceed" in s["homotopy"]
    assert "24 paths" in str(s.argument_detail)
    assert sorted(c.homology.euler for c in res.components) == \
        spherical_five_bar_reference(*lengths)
    for c in res.components:
        chi = c.homology.euler
        assert c.closed and c.homology.orientable and c.morse_agrees and c.morse_sum == chi
        assert c.homology.betti_q == (1, 2 - chi, 1) == c.homology.betti_z2
        assert not any(c.defects.values()) and c.inverted == 0
    assert not res.critical_points
    # every critical point of the height: c in the row space of J (rank [J; c] = E), on a mesh
    for u in res.height_critical.points:
        jac = jacobian(lk, u)
        sv = np.linalg.svd(np.vstack([jac, res.height]), compute_uv=False)
        assert sv[-1] <= 1e-8 * sv[0] and np.linalg.svd(jac, compute_uv=False)[-1] > 1e-3
    assert (res.height_component >= 0).all()


def test_a_cone_is_found_by_the_argument():
    """``L3`` chosen (here, by optimisation) so that ``A``, ``B``, ``C`` lie on one great circle
    where ``A`` and ``C`` are farthest apart: the band's edge ``s = s_hi`` shrinks to that
    point, a cone (``J`` of rank ``E - 1``, ``sigma J = 0``, ``Q`` indefinite); the space is
    the double cover branched over ``dR`` and the point: ``chi = 2 chi(R) - 1``."""
    g, l1, l2, l4 = 1.2, 0.6, 1.0, 0.7
    (_, _, _, l3, _), s_max = cone_lengths(g, l1, l2, l4)
    lk = spherical_five_bar(g, l1, l2, l3, l4)
    res = explore_surfaces(lk)
    s = res.search
    assert s.complete and s["argument"] == "derived", s.as_dict()
    (cp,) = res.critical_points
    jac = jacobian(lk, cp.u)
    left, sv, _ = np.linalg.svd(jac)
    assert sv[-1] <= 1e-7 * sv[0] < sv[-2]  # rank E - 1
    sigma = left[:, -1]  # the left null vector: sigma J = 0
    assert np.abs(sigma @ jac).max() <= 1e-7 * np.abs(jac).max()
    pos = lk.positions_of(cp.u)
    a, b, c = pos[3], pos[4], pos[5]
    assert abs(np.linalg.det(np.stack([a, b, c]))) < 1e-6  # on one great circle
    assert np.isclose(np.sum((a - c) ** 2), s_max, atol=1e-8)
    q = cp.analysis.q_eigenvalues
    assert q is not None and q.max() > 0 > q.min()
    (comp,) = res.components
    assert len(comp.apexes) == 1 and comp.morse_agrees
    assert comp.homology.euler == spherical_five_bar_reference(g, l1, l2, l3, l4)[0] - 1


def test_the_band_against_three_spheres():
    """Where ``B`` is real on a grid of crank angles (three spheres meet, computed here) is
    exactly where ``s_lo <= |A - C|^2 <= s_hi``, away from the edge."""
    lengths = CASES[0]
    lk = spherical_five_bar(*lengths)
    ch = five_bar_chain(lk, Surface(lk).cons)
    assert ch is not None and ch.s_range is not None
    g1, g2 = _sphere_pins(lengths[0])
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    a = np.broadcast_to(_on_circle(g1, lengths[1], t)[:, None], (90, 90, 3))
    c = np.broadcast_to(_on_circle(g2, lengths[4], t)[None, :], (90, 90, 3))
    t2 = _middle(a, c, lengths[2], lengths[3])[1]
    s = np.sum((a - c) ** 2, axis=-1)
    lo, hi = ch.s_range
    clear = np.minimum(np.abs(s - lo), np.abs(s - hi)) > 1e-6
    assert np.array_equal((t2 >= 0)[clear], ((s >= lo) & (s <= hi))[clear])
    assert (t2 >= 0).any() and (t2 < 0).any()


def test_seeds_lie_on_the_lengths_and_both_sides():
    lk = spherical_five_bar(*CASES[0])
    surface = Surface(lk)
    ch = five_bar_chain(lk, surface.cons)
    assert ch is not None
    got = chain_seeds(surface, ch, np.random.default_rng(3), NEVER)
    assert got.success and got.paths == 24 and len(got.critical) == 0
    assert max(surface.cons.max_residual(u) for u in got.seeds) <= 1e-9
    # both sides of the plane O A C: B's z about the plane changes sign among the seeds
    pos = np.array([lk.positions_of(u) for u in got.seeds])
    side = np.einsum("nk,nk->n", pos[:, 4], np.cross(pos[:, 3], pos[:, 5]))
    assert (side > 1e-6).any() and (side < -1e-6).any()
    # a point of the crank torus outside the band has no lift
    far = np.array([[[1.0, 0.0], [1.0, 0.0]]])
    values = ch.s(far[:, 0], far[:, 1])
    inside = ch.s_range is not None and ch.s_range[0] <= values[0] <= ch.s_range[1]
    assert len(lift(ch, lk, far)) == (2 if inside else 0)


def test_recognition():
    chains = [spherical_five_bar(*CASES[0]), build_preset("five-bar"),
              five_bar(2, 1, 1.4, 1.6, 1), pentagon((1, 1, 1.2, 1, 1))]
    for lk in chains:
        assert five_bar_chain(lk, Surface(lk).cons) is not None
    # a slider; B's third bar to G1 (off C's axis: |B - G1| does not make |C - G1| constant);
    # equal couplers where the cranks' circles meet (over A = C, B on a circle), planar and
    # spherical
    others = [slider_torus(), spherical_five_bar(*CASES[0], pin_b="G1"),
              pentagon((1, 1, 1, 1, 1)), spherical_five_bar(1.2, 0.6, 1.0, 1.0, 0.7)]
    for lk in others:
        assert five_bar_chain(lk, Surface(lk).cons) is None
    res = explore_surfaces(others[1])
    assert res.search.reason == "searched" and res.search["five_bar_chain"] is None
