"""The linear-product start against independent counts and solutions: the multihomogeneous
Bezout number expanded here as a polynomial, the start's roots checked by substitution, the
height's critical points on a crank-rocker four-bar against dense sampling of its two circuits
(both starts find the same ones), and the three-rotor's twelve branch points (the paper's)
found again by a bihomogeneous kernel system tracked from a linear product."""

from __future__ import annotations

from collections import Counter
from math import comb

import numpy as np
import pytest

from engine.catalogue.presets import build_preset
from engine.model.constraints import Constraints
from engine.model.errors import NumericalFailure
from engine.space.configuration_space import explore
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.linear_product import LinearProduct, Structure, bezout
from engine.space.surfaces.morse import LagrangeSystem
from engine.space.witnesses import bar_quadrics


def expanded_coefficient(sizes: list[int], degrees: np.ndarray) -> int:
    """The coefficient of ``prod_g z_g^{n_g}`` in ``prod_e sum_g d_{e,g} z_g``, by expanding the
    product monomial by monomial (exponent tuples -> coefficients)."""
    poly: Counter = Counter({tuple(0 for _ in sizes): 1})
    for row in degrees:
        nxt: Counter = Counter()
        for mono, coef in poly.items():
            for g, d in enumerate(row):
                if d:
                    key = tuple(x + (k == g) for k, x in enumerate(mono))
                    nxt[key] += coef * int(d)
        poly = nxt
    return poly[tuple(sizes)]


def random_structure(rng: np.random.Generator) -> tuple[Structure, np.ndarray]:
    sizes = [int(s) for s in rng.integers(1, 4, size=int(rng.integers(2, 4)))]
    n = sum(sizes)
    cuts = np.cumsum([0] + sizes)
    groups = tuple(np.arange(1 + cuts[g], 1 + cuts[g + 1]) for g in range(len(sizes)))
    degrees = rng.integers(0, 3, size=(n, len(sizes)))
    degrees[degrees.sum(axis=1) == 0, 0] = 1
    total = degrees.sum(axis=1) + rng.integers(0, 2, size=n)  # some padded with x_0
    return Structure(groups, degrees), total


@pytest.mark.parametrize("seed", range(8))
def test_start_roots_number_the_bezout_number_and_solve_the_start(seed):
    rng = np.random.default_rng(seed)
    st, total = random_structure(rng)
    ref = expanded_coefficient([len(g) for g in st.groups], st.degrees)
    assert bezout(st) == ref
    lp = LinearProduct(st, total, rng)
    sol = lp.solutions()
    assert len(sol) == ref
    if not ref:
        return
    g, jac = lp(sol)
    assert np.abs(g).max() <= 1e-9 * max(1.0, float(np.abs(sol).max()) ** int(total.max()))
    # nonsingular in the affine chart x_0 = 1 and pairwise distinct
    assert all(np.linalg.matrix_rank(j[:, 1:]) == st.n for j in jac)
    d = np.linalg.norm(sol[:, None] - sol[None], axis=2) + np.eye(len(sol))
    assert d.min() > 1e-8


def test_the_jacobian_is_the_derivative():
    rng = np.random.default_rng(3)
    st = Structure((np.array([1, 2, 3]), np.array([4, 5])),
                   np.array([[2, 0], [1, 1], [0, 1], [3, 0], [1, 0]]))
    total = np.array([2, 2, 2, 3, 2])
    lp = LinearProduct(st, total, rng)
    x = rng.normal(size=(4, 6)) + 1j * rng.normal(size=(4, 6))
    _, jac = lp(x)
    h = 1e-6
    fd = np.stack([(lp(x + h * e)[0] - lp(x - h * e)[0]) / (2 * h) for e in np.eye(6)], axis=2)
    assert np.abs(fd - jac).max() <= 1e-7 * max(1.0, float(np.abs(jac).max()))
    # homogeneous of the total degrees: G(s X) = s^d G(X)
    s = 0.7 - 0.2j
    np.testing.assert_allclose(lp(s * x)[0], s ** total * lp(x)[0], rtol=1e-10)


def test_a_factor_count_beyond_the_total_degree_is_refused():
    st = Structure((np.array([1]),), np.array([[3]]))
    with pytest.raises(NumericalFailure, match="exceeds its equation"):
        LinearProduct(st, np.array([2]), np.random.default_rng(0))


def crank_rocker_extrema(lk, c: np.ndarray, samples: int = 40000) -> np.ndarray:
    """Every critical point of ``c . u`` on a crank-rocker four-bar (pins P1 = 0, P2 = (a, 0);
    the crank turns fully, so each assembly mode is one closed circuit over the crank angle):
    the samples where the height's difference changes sign, from circle intersections."""
    pos = np.asarray(lk.positions, dtype=float)
    a_len, l2, l3 = (float(x) for x in lk.lengths)  # L1, L2, L3
    p2 = pos[lk.vertex_ids.index("P2")]
    th = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    a = a_len * np.stack([np.cos(th), np.sin(th)], axis=1)
    d = np.linalg.norm(p2 - a, axis=1)
    assert (d < l2 + l3).all() and (d > abs(l2 - l3)).all()  # a crank: B exists everywhere
    along = (d ** 2 + l2 ** 2 - l3 ** 2) / (2 * d)
    off = np.sqrt(l2 ** 2 - along ** 2)
    e = (p2 - a) / d[:, None]
    n = np.stack([-e[:, 1], e[:, 0]], axis=1)
    out = []
    fi = lk.free_index
    for side in (1.0, -1.0):
        b = a + along[:, None] * e + side * off[:, None] * n
        u = np.zeros((samples, lk.n_free))
        for vid, pts in (("A", a), ("B", b)):
            idx = fi[lk.vertex_ids.index(vid)]
            u[:, idx] = pts
        h = u @ c
        dh = np.roll(h, -1) - h
        turn = np.flatnonzero(np.sign(dh) != np.sign(np.roll(dh, 1)))
        out.append(u[turn])
    return np.vstack(out)


@pytest.mark.parametrize("seed", range(3))
def test_four_bar_height_critical_points_both_starts_against_sampling(seed):
    lk = build_preset("four-bar", {"a": 1.0, "L1": 0.4, "L2": 1.2, "L3": 1.0})
    cons = Constraints(lk)
    rng = np.random.default_rng(seed)
    c = rng.normal(size=cons.n_free)
    system = LagrangeSystem(lk, cons, c / np.linalg.norm(c))
    m, e = cons.n_free, cons.n_constraints
    ref = crank_rocker_extrema(lk, system.c)
    # the bihomogeneous count: the coefficient of a^4 b^3 in (2a)^3 (a + b)^4
    assert system.product_paths == expanded_coefficient([m, e], [[2, 0]] * e + [[1, 1]] * m)
    assert (system.product_paths, system.paths) == (32, 128)
    found = {}
    for name, start in (("product", LinearProduct(system.structure, system.degrees, rng)),
                        ("total", None)):
        res = track(system, system.degrees, rng, far=1e4, start=start)
        assert res.success, res.message
        assert res.paths == (32 if start is not None else 128)
        reg = res.state == REGULAR
        y = res.ends[reg, 1:] / res.ends[reg, :1]
        y = y[np.linalg.norm(y, axis=1) < 1e3]
        found[name] = y
        real = y[np.linalg.norm(y.imag, axis=1) < 1e-8, :m].real
        u = system.centre + system.scale * real
        # the real ones are the sampled extrema, one for one
        assert len(u) == len(ref)
        assert np.linalg.norm(u[:, None] - ref[None], axis=2).min(axis=1).max() < 1e-3
    # both starts end at the same finite solutions, complex ones included
    a, b = found["product"], found["total"]
    assert len(a) == len(b)
    gap = np.linalg.norm(a[:, None] - b[None], axis=2)
    assert gap.min(axis=1).max() < 1e-7 and gap.min(axis=0).max() < 1e-7


def kernel_system(lk, cons, c: np.ndarray, b: np.ndarray):
    """``f(u) = 0, J(u) v = 0, c . v = 0, b . v = 1`` in ``X = (x_0, y, v)``: its real solutions
    are the points where the curve's tangent is normal to ``c`` -- the height's critical points
    and the branch points. Bihomogeneous in ``(y, v)``: bars ``(2, 0)``, ``J v`` ``(1, 1)``, the
    two normalisations ``(0, 1)``."""
    quad, scale, centre = bar_quadrics(lk, cons)
    e, m = cons.n_constraints, cons.n_free

    def system(x):
        xu, v = x[:, :m + 1], x[:, m + 1:]
        g = np.einsum("amn,pn->pam", quad, xu)
        f = np.concatenate([np.einsum("pam,pm->pa", g, xu),
                            2 * np.einsum("pam,pm->pa", g[:, :, 1:], v),
                            (v @ c)[:, None], (v @ b - x[:, 0])[:, None]], axis=1)
        jac = np.zeros((len(x), 2 * e + 2, 2 * m + 1), dtype=complex)
        jac[:, :e, :m + 1] = 2 * g
        jac[:, e:2 * e, :m + 1] = 2 * np.einsum("amn,pm->pan", quad[:, 1:, :], v)
        jac[:, e:2 * e, m + 1:] = 2 * g[:, :, 1:]
        jac[:, 2 * e, m + 1:] = c
        jac[:, 2 * e + 1, m + 1:] = b
        jac[:, 2 * e + 1, 0] = -1
        return f, jac

    st = Structure((np.arange(1, m + 1), np.arange(m + 1, 2 * m + 1)),
                   np.array([[2, 0]] * e + [[1, 1]] * e + [[0, 1]] * 2))
    return system, st, np.array([2] * (2 * e) + [1, 1]), scale, centre


def rank_gap(lk, u: np.ndarray) -> float:
    """``s_min / s_max`` of the rigidity matrix at free coordinates ``u``, built here from the
    bar vectors."""
    pos = np.array(lk.positions, dtype=float)
    fi = lk.free_index
    pos[fi >= 0] = u[fi[fi >= 0]]
    rows = np.zeros((len(lk.ends), lk.n_free))
    for k, (i, j) in enumerate(lk.ends):
        d = pos[i] - pos[j]
        for vert, sign in ((i, 1.0), (j, -1.0)):
            free = fi[vert] >= 0
            rows[k, fi[vert][free]] += sign * d[free]
    s = np.linalg.svd(rows, compute_uv=False)
    return float(s[-1] / s[0])


def test_three_rotor_twelve_branch_points_from_a_linear_product():
    """The paper's three-rotor has twelve branch points; the kernel system tracked from its
    linear product (2^5 * 5 = 160 paths; total degree 1024) finds each, where the engine's
    witness points (a determinant system, a total-degree start) found them too."""
    lk = build_preset("three-rotor")
    cons = Constraints(lk)
    rng = np.random.default_rng(0)
    c, b = rng.normal(size=cons.n_free), rng.normal(size=cons.n_free)
    system, st, total, scale, centre = kernel_system(lk, cons, c, b)
    e, m = cons.n_constraints, cons.n_free
    assert bezout(st) == expanded_coefficient([m, m], st.degrees) == 2 ** e * e == 160
    res = track(system, total, rng, far=1e3, start=LinearProduct(st, total, rng))
    assert res.success and res.start == "linear product" and res.paths == 160
    y = res.ends[:, 1:m + 1] / res.ends[:, :1]
    ok = np.isin(res.state, (REGULAR, SINGULAR)) & (np.linalg.norm(y, axis=1) < 1e3)
    real = ok & (np.linalg.norm(y.imag, axis=1) < 1e-4)
    pts = centre + scale * y[real].real
    branch = [p for p in pts if rank_gap(lk, p) < 1e-3]
    distinct: list[np.ndarray] = []
    for p in branch:
        if not any(np.linalg.norm(p - q) < 1e-3 for q in distinct):
            distinct.append(p)
    assert len(distinct) == 12
    ref = np.array([cp.u for cp in explore(lk).critical_points])
    assert len(ref) == 12
    gap = np.linalg.norm(np.asarray(distinct)[:, None] - ref[None], axis=2)
    assert gap.min(axis=1).max() < 1e-3 and gap.min(axis=0).max() < 1e-3


def test_the_pentagon_needs_240_paths():
    """2^4 C(6, 4): the coefficient of a^6 b^4 in (2a)^4 (a + b)^6."""
    m, e = 6, 4
    st = Structure((np.arange(1, m + 1), np.arange(m + 1, m + e + 1)),
                   np.array([[2, 0]] * e + [[1, 1]] * m))
    assert bezout(st) == expanded_coefficient([m, e], st.degrees) == 2 ** e * comb(m, e) == 240
