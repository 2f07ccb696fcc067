"""Critical points of a height on a D = 2 surface: the Lagrange system against finite
differences, the sphere's two poles in closed form, and the Morse sum against the genus."""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as P

from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.mesh import march
from engine.space.surfaces.morse import (
    LagrangeSystem,
    assign,
    classify_points,
    height_witnesses,
    pl_critical_vertices,
    ring,
    start_order,
)
from tests.engine.space.surfaces.conftest import pentagon, pentagon_betti, slider_torus, sphere_3d


def test_lagrange_jacobian_against_finite_differences():
    lk = pentagon((1, 1, 1, 1, 1))
    rng = np.random.default_rng(0)
    system = LagrangeSystem(lk, Surface(lk).cons, rng.normal(size=lk.n_free))
    n = lk.n_free + int(lk.active.sum()) + 1
    x = rng.normal(size=(2, n)) + 1j * rng.normal(size=(2, n))
    values, jac = system(x)
    h = 1e-7
    fd = np.stack([(system(x + h * e)[0] - system(x - h * e)[0]) / (2 * h) for e in np.eye(n)],
                  axis=2)
    assert np.abs(fd - jac).max() < 1e-6 * max(1.0, float(np.abs(jac).max()))
    assert values.shape == (2, n - 1) and system.paths == 2 ** (n - 1)


def test_sphere_poles_in_closed_form():
    """A point on a sphere of radius r about the pin: the height c . u has its minimum at
    -r c and its maximum at +r c (c a unit vector)."""
    lk = sphere_3d(1.3)
    s = Surface(lk)
    c = np.array([0.3, -0.5, 0.8])
    c /= np.linalg.norm(c)
    w = height_witnesses(s, c, np.random.default_rng(1))
    assert w.success, w.message
    order = np.argsort(w.critical.index)
    assert w.critical.index[order].tolist() == [0, 2]
    assert np.allclose(w.critical.points[order], [-1.3 * c, 1.3 * c], atol=1e-9)
    # the bihomogeneous Bezout number in (u, lambda): the bar (2, 0), the three Lagrange
    # equations (1, 1): the coefficient of a^3 b in (2a)(a + b)^3 is 2 * 3 (the total degree
    # would be 2^4)
    assert (w.paths, w.start) == (2 * 3, "linear product")


def test_torus_has_four_critical_points_summing_to_zero():
    lk = slider_torus()
    s = Surface(lk)
    c = np.random.default_rng(5).normal(size=lk.n_free)
    w = height_witnesses(s, c, np.random.default_rng(2))
    assert w.success, w.message
    idx = sorted(w.critical.index.tolist())
    assert sum((-1) ** i for i in idx) == 0 and idx[0] == 0 and idx[-1] == 2
    # M = 5, E = 3: the coefficient of a^5 b^3 in (2a)^3 (a + b)^5 (not the total 2^8)
    assert w.counts["paths"] == 2 ** 3 * int(P.polypow([1, 1], 5)[5 - 3]) == 80
    c = w.counts
    assert c["regular"] + c["singular"] + c["far"] + c["failed"] == c["paths"]


def test_pl_critical_vertices_refine_to_the_morse_sum():
    """On a genus-4 pentagon space the refined PL critical vertices of a generic height give
    sum (-1)^index = chi = -6 (Farber and Schuetz give the genus, not the engine)."""
    lengths = (1, 1, 1, 1, 1)
    b = pentagon_betti(lengths)
    chi = b[0] - b[1] + b[2]
    lk = pentagon(lengths)
    s = Surface(lk)
    m = march(s, lk.coordinates(), 0.35, 60_000)
    c = np.random.default_rng(7).normal(size=lk.n_free)
    verts, pl_index = pl_critical_vertices(m.vertices, m.triangles, m.vertices @ c)
    assert int(pl_index.sum()) == chi  # the PL Morse theorem on the mesh itself
    crit = classify_points(s, c, m.vertices[ring(m.triangles, verts)], 0.5 * 0.35)
    assert (crit.index >= 0).all()
    assert sum((-1) ** int(i) for i in crit.index) == chi
    # each is a critical point: c in the row space of J there
    for u, lam in zip(crit.points, crit.multipliers, strict=True):
        assert np.linalg.norm(s.jacobian(u).T @ lam - c / np.linalg.norm(c)) < 1e-8
    assert (assign(crit.points, [m.vertices], 0.7) == 0).all()
    assert (assign(crit.points + 10.0, [m.vertices], 0.7) == -1).all()


def test_paths_beyond_the_bound_decline():
    # the pentagon's fewest paths: 2^4 C(6, 4) = 240 (the linear product; 1024 total degree)
    lk = pentagon((1, 1, 1, 1, 1))
    w = height_witnesses(Surface(lk), np.ones(lk.n_free), np.random.default_rng(0),
                         paths_max=239)
    assert not w.success and "240 paths exceed" in w.message and w.paths == 240


def test_the_total_degree_start_is_the_fallback():
    """The linear product first (where it has fewer paths), each start tried twice; the total
    degree after it only where its paths fit the bound."""
    assert start_order(240, 1024, 4096) == [True, True, False, False]
    assert start_order(240, 1024, 512) == [True, True]
    assert start_order(16, 16, 512) == [False, False]
