"""The total-degree homotopy against systems whose solutions are known independently: closed
forms, a resultant computed here with numpy's polynomial roots, a double root, solutions at
infinity."""

from __future__ import annotations

import numpy as np
import pytest

from engine.space.homotopy import FAR, REGULAR, SINGULAR, T_END, _jumped, track


def quadrics(coef: np.ndarray):
    """``sum_ij coef[e, i, j] X_i X_j`` (homogeneous quadrics in ``X = (x0, x, y)``)."""
    sym = 0.5 * (coef + coef.transpose(0, 2, 1))

    def system(x):
        f = np.einsum("eij,pi,pj->pe", sym, x, x)
        jac = 2.0 * np.einsum("eij,pj->pei", sym, x)
        return f, jac
    return system


def affine(res) -> np.ndarray:
    ends = res.ends[res.state == REGULAR]
    return ends[:, 1:] / ends[:, :1]


def test_a_circle_and_a_hyperbola_meet_in_four_real_points():
    # x^2 + y^2 = 4 x0^2, x y = x0^2: x^2 = 2 +- sqrt(3), y = 1 / x
    coef = np.zeros((2, 3, 3))
    coef[0] = np.diag([-4.0, 1.0, 1.0])
    coef[1, 1, 2], coef[1, 0, 0] = 1.0, -1.0
    res = track(quadrics(coef), [2, 2], np.random.default_rng(1))
    assert res.success and (res.state == REGULAR).all()
    xs = np.sort(affine(res)[:, 0].real)
    ref = np.sort([s * np.sqrt(2 + e * np.sqrt(3)) for s in (1, -1) for e in (1, -1)])
    np.testing.assert_allclose(xs, ref, atol=1e-10)
    assert np.abs(affine(res).imag).max() < 1e-10


def resultant_solutions(c1: np.ndarray, c2: np.ndarray) -> np.ndarray:
    """Every common root of two affine quadrics in (x, y) (coefficient matrices over
    ``(1, x, y)``), by the Sylvester resultant in y: a quartic in x whose coefficients are
    fitted from its values at 9 points, its roots, then y from the two quadrics' gcd."""
    def in_y(c, x):  # a quadric as a polynomial in y: [a2, a1, a0] at this x
        return np.array([c[2, 2], 2 * (c[0, 2] + c[1, 2] * x),
                         c[0, 0] + 2 * c[0, 1] * x + c[1, 1] * x * x])

    def sylvester(x):
        a, b = in_y(c1, x), in_y(c2, x)
        return np.linalg.det(np.array([[*a, 0], [0, *a], [*b, 0], [0, *b]]))

    xs = np.linspace(-2.0, 2.0, 9)
    poly = np.polyfit(xs, [sylvester(x) for x in xs], 4)
    out = []
    for x in np.roots(poly):
        a, b = in_y(c1, x), in_y(c2, x)
        ya, yb = np.roots(a), np.roots(b)
        y = min(ya, key=lambda v: np.abs(yb - v).min())  # the root they share
        out.append((x, y))
    return np.array(out)


@pytest.mark.parametrize("seed", range(6))
def test_two_random_quadrics_against_the_resultant(seed):
    rng = np.random.default_rng(seed)
    coef = rng.normal(size=(2, 3, 3))
    coef = 0.5 * (coef + coef.transpose(0, 2, 1))
    res = track(quadrics(coef), [2, 2], np.random.default_rng(100 + seed))
    assert res.success and (res.state == REGULAR).all()
    ours = affine(res)
    ref = resultant_solutions(coef[0], coef[1])
    assert len(ours) == len(ref) == 4
    for p in ref:  # every reference solution is an end, and the reverse
        assert np.abs(ours - p).max(axis=1).min() <= 1e-6 * max(1.0, np.abs(p).max())
    for p in ours:
        assert np.abs(ref - p).max(axis=1).min() <= 1e-6 * max(1.0, np.abs(p).max())


def test_a_double_root_ends_singular_near_it():
    # (x - x0)^2 = 0, y - x = 0: one solution (1, 1) of multiplicity 2, two paths
    def system(x):
        x0, a, b = x.T
        f = np.stack([(a - x0) ** 2, b - a], axis=1)
        jac = np.zeros((len(x), 2, 3), dtype=complex)
        jac[:, 0] = np.stack([-2 * (a - x0), 2 * (a - x0), 0 * a], axis=1)
        jac[:, 1, 1], jac[:, 1, 2] = -1.0, 1.0
        return f, jac

    res = track(system, [2, 1], np.random.default_rng(3))
    assert res.success and (res.state == SINGULAR).all()
    ends = res.ends[:, 1:] / res.ends[:, :1]
    assert np.abs(ends - 1.0).max() <= 10 * np.sqrt(T_END)


def test_parallel_lines_meet_only_at_infinity():
    # x + y = x0, x + y = 2 x0 (degree-2 copies: x0 (x + y - x0) = 0 has the line x0 = 0 too)
    def system(x):
        x0, a, b = x.T
        f = np.stack([a + b - x0, a + b - 2 * x0], axis=1)
        jac = np.zeros((len(x), 2, 3), dtype=complex)
        jac[:, 0] = [-1.0, 1.0, 1.0]
        jac[:, 1] = [-2.0, 1.0, 1.0]
        return f, jac

    res = track(system, [1, 1], np.random.default_rng(4), far=100.0)
    # a nonsingular solution at infinity: the path ends regular, with x0 = 0
    assert res.success and (res.state == REGULAR).all()
    assert np.abs(res.ends[:, 0]).max() <= 1e-12 * np.abs(res.ends).max()


def test_paths_to_a_non_isolated_set_at_infinity_end_far():
    # x^2 + y^2 = x0^2 and x^2 + y^2 = 4 x0^2: no finite solution; at infinity the whole
    # isotropic pair x^2 + y^2 = 0 solves both (not isolated, so the ends are singular)
    coef = np.zeros((2, 3, 3))
    coef[0] = np.diag([-1.0, 1.0, 1.0])
    coef[1] = np.diag([-4.0, 1.0, 1.0])
    res = track(quadrics(coef), [2, 2], np.random.default_rng(6), far=100.0)
    assert res.success
    assert np.isin(res.state, (FAR, SINGULAR)).all() and (res.state == FAR).any()
    near = res.state == SINGULAR
    assert (np.abs(res.ends[near, 0]) <= 1e-3 * np.abs(res.ends[near]).max(axis=1)).all()


def test_coinciding_regular_ends_are_reported_as_a_jump():
    a = np.array([[1.0, 0.5, 0.25], [1.0, -1.0, 2.0]], dtype=complex)
    assert _jumped(a) == 0
    assert _jumped(np.vstack([a, a[:1] * (1 + 1e-12)])) == 2


def test_the_deadline_stops_the_paths_and_says_so():
    from engine.model.budget import Deadline

    coef = np.random.default_rng(5).normal(size=(2, 3, 3))
    res = track(quadrics(coef), [2, 2], np.random.default_rng(5),
                deadline=Deadline(stop=lambda: True))
    assert not res.success and "deadline" in res.message
