"""Prestress decisions at and near the tolerance boundary, against exact rational references.

Every reference here is exact (``fractions.Fraction``): a stress certificate is checked by the
pivots of an exact elimination (all positive: positive definite), a dual certificate by exact
inner products. Families of forms whose stability margin ``t*`` is known exactly put the
engine's decision on each side of ``q_rtol`` and at it: above, True; between rounding and
``q_rtol``, None (never a definite False); zero, False.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from engine.local.certificates import decide
from engine.local.prestress import prestress
from engine.local.rigidity import first_order
from engine.local.second_order import second_order
from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances

TOL = Tolerances()


# -- exact references --------------------------------------------------------------------------

def exact(mat) -> list[list[Fraction]]:
    return [[Fraction(float(v)) for v in row] for row in np.asarray(mat)]


def positive_definite(mat: list[list[Fraction]]) -> bool:
    """Exact: every pivot of Gaussian elimination without exchanges is positive."""
    a = [list(r) for r in mat]
    n = len(a)
    for k in range(n):
        if a[k][k] <= 0:
            return False
        for i in range(k + 1, n):
            f = a[i][k] / a[k][k]
            for j in range(k, n):
                a[i][j] -= f * a[k][j]
    return True


def inner(a: list[list[Fraction]], b: list[list[Fraction]]) -> Fraction:
    return sum((x * y for ra, rb in zip(a, b, strict=True) for x, y in zip(ra, rb, strict=True)),
               Fraction(0))


def combination(forms: list[list[list[Fraction]]], omega: list[Fraction]):
    k = len(forms[0])
    return [[sum((w * f[i][j] for w, f in zip(omega, forms, strict=True)), Fraction(0))
             for j in range(k)] for i in range(k)]


def shifted(mat, t: Fraction):
    """``mat - t I``."""
    return [[v - (t if i == j else 0) for j, v in enumerate(row)] for i, row in enumerate(mat)]


# -- a family with a known margin: t* = |delta| -----------------------------------------------

def family(delta: float) -> tuple[np.ndarray, np.ndarray]:
    """``x^2 - y^2``, ``2 x y`` and ``delta (x^2 + y^2 + z^2)`` on three flexes (the SDP path):
    ``lambda_min(w1 Q1 + w2 Q2 + w3 Q3) = w3 delta - |(w1, w2)|``, so ``t* = |delta|``
    (``omega = (0, 0, sign delta)``), and ``X = diag(1, 1, 0) / 2`` bounds it by ``|delta|``."""
    q = np.array([np.diag([1.0, -1.0, 0.0]),
                  [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
                  delta * np.eye(3)])
    return q, np.array([4.0, 4.0, 4.0])  # bounds on |Q_k| (|delta| < 4 here)


def exact_margin(delta: float) -> Fraction:
    """``t*`` of :func:`family`, proved both ways in rationals: a stress whose combination minus
    ``t I`` is positive semidefinite for every ``t < |delta|`` (checked at ``t = |delta|`` minus
    a little, by exact pivots on the block that is not already zero), and the dual bound."""
    q, _ = family(delta)
    forms = [exact(m) for m in q]
    d = Fraction(delta)
    x = [[Fraction(1, 2), 0, 0], [0, Fraction(1, 2), 0], [0, 0, 0]]
    bound = max(abs(inner(f, x)) for f in forms)  # |<Q_k, X>| with tr X = 1, X >= 0
    assert bound == abs(d)
    if d != 0:
        sign = 1 if d > 0 else -1
        comb = combination(forms, [Fraction(0), Fraction(0), Fraction(sign)])
        assert positive_definite(shifted(comb, abs(d) * Fraction(999_999, 1_000_000)))
    return abs(d)


@pytest.mark.parametrize("factor", [20.0, 1.05])
def test_margin_above_q_rtol_is_stable(factor):
    delta = factor * TOL.q_rtol * 4.0
    assert exact_margin(delta) / 4 > Fraction(TOL.q_rtol)
    q, scales = family(delta)
    d = decide(q, scales, TOL)
    assert d.stable is True and d.rigid is True


@pytest.mark.parametrize("factor", [1.0, 0.95, 0.1, 1e-4])
def test_margin_within_q_rtol_is_undecided_not_false(factor):
    """``0 < t* <= q_rtol`` (exactly, by the rational certificates): the answer is None with
    the reason, never False (before, a dual residual below q_rtol was taken as a proof)."""
    delta = factor * TOL.q_rtol * 4.0
    t_star = exact_margin(delta)
    assert 0 < t_star / 4 <= Fraction(TOL.q_rtol)
    q, scales = family(delta)
    d = decide(q, scales, TOL)
    assert d.stable is None and d.rigid is None, d.reason
    assert "borderline" in d.reason and "q_rtol" in d.reason


def test_margin_zero_is_not_stable_with_a_second_order_flex():
    """``delta = 0``: ``t* = 0`` exactly and (0, 0, 1) is an exact common zero."""
    assert exact_margin(0.0) == 0
    q, scales = family(0.0)
    d = decide(q, scales, TOL)
    assert d.stable is False and d.rigid is False, d.reason
    c = exact([d.witness])[0]
    forms = [exact(m) for m in q]
    energies = [sum(c[i] * f[i][j] * c[j] for i in range(3) for j in range(3)) for f in forms]
    assert max(abs(float(e)) for e in energies) <= 1e-14


def test_a_smaller_q_rtol_decides_what_the_default_leaves_open():
    delta = 0.1 * TOL.q_rtol * 4.0
    q, scales = family(delta)
    assert decide(q, scales, TOL).stable is None
    assert decide(q, scales, Tolerances(q_rtol=1e-9)).stable is True


# -- one stress (closed form): Q = diag(1, 1, delta) ------------------------------------------

@pytest.mark.parametrize(
    ("factor", "expected"),
    [(20.0, True), (1.05, True), (1.0, None), (0.5, None), (1e-5, None), (0.0, False),
     (-1e-5, False), (-0.5, False), (-20.0, False)],
)
def test_one_stress_at_and_near_the_boundary(factor, expected):
    """``t* = max(0, lambda_min(Q), lambda_min(-Q))``: ``delta > 0`` is definite with margin
    ``delta`` (exact pivots), ``delta <= 0`` has the exact dual ``diag(|delta|, 0, 1) / (1 +
    |delta|)`` with ``<Q, X> = 0``: not stable, and decided so (a sign resolved beyond
    rounding, or a zero), while ``0 < delta <= q_rtol`` is None."""
    delta = factor * TOL.q_rtol * 4.0
    q = np.diag([1.0, 1.0, delta])[None]
    form = exact(q[0])
    d_exact = Fraction(delta)
    if d_exact > 0:
        assert positive_definite(shifted(form, d_exact * Fraction(999, 1000)))
    else:
        x = [[-d_exact / (1 - d_exact), 0, 0], [0, 0, 0], [0, 0, 1 / (1 - d_exact)]]
        assert inner(form, x) == 0 and x[0][0] + x[2][2] == 1
    d = decide(q, np.array([4.0]), TOL)
    assert d.stable is expected, d.reason
    assert d.rigid is expected
    if expected is None:
        assert "borderline" in d.reason


@pytest.mark.parametrize(("factor", "expected"), [(20.0, True), (0.5, None), (0.0, False)])
def test_one_flex_at_and_near_the_boundary(factor, expected):
    """One flex, two stresses with energies ``(delta, 0)`` on it: ``t* = |delta|``."""
    delta = factor * TOL.q_rtol * 4.0
    d = decide(np.array([[[delta]], [[0.0]]]), np.array([4.0, 4.0]), TOL)
    assert d.stable is expected and d.rigid is expected, d.reason


# -- the framework: 7 collinear vertices in 3D ----------------------------------------

XS = [1, 2, 3, 6, 7, 8, 12]
EDGES = [(2, 3), (0, 6), (0, 4), (1, 2), (0, 5), (1, 5), (1, 4), (2, 4), (3, 5), (1, 6)]
#: a stress of this framework given by its values on the free columns of the exact elimination
#: below (found once, offline; what proves stability is the exact check, not how it was found)
STRESS_FREE_VALUES = [Fraction(-99247, 970975), Fraction(46372, 366605),
                      Fraction(181117, 733210), Fraction(3, 845206)]


def collinear() -> object:
    return build_linkage(
        3, [VertexSpec(f"v{i}", [float(x), 0.0, 0.0]) for i, x in enumerate(XS)],
        [BarSpec(f"e{i}", (f"v{a}", f"v{b}")) for i, (a, b) in enumerate(EDGES)])


def exact_collinear_stress() -> list[Fraction]:
    """The stress with :data:`STRESS_FREE_VALUES`: equilibrium along the line,
    ``sum_j w_ij (x_j - x_i) = 0`` at every vertex, solved exactly (reduced row echelon form)."""
    n, e = len(XS), len(EDGES)
    rows = [[Fraction(0)] * e for _ in range(n)]
    for k, (i, j) in enumerate(EDGES):
        rows[i][k] += XS[j] - XS[i]
        rows[j][k] += XS[i] - XS[j]
    pivots, r = [], 0
    for c in range(e):
        p = next((i for i in range(r, n) if rows[i][c] != 0), None)
        if p is None:
            continue
        rows[r], rows[p] = rows[p], rows[r]
        rows[r] = [v / rows[r][c] for v in rows[r]]
        for i in range(n):
            if i != r and rows[i][c] != 0:
                f = rows[i][c]
                rows[i] = [a - f * b for a, b in zip(rows[i], rows[r], strict=True)]
        pivots.append(c)
        r += 1
    free = [c for c in range(e) if c not in pivots]
    assert len(free) == 4  # four self-stresses
    w = [Fraction(0)] * e
    for c, v in zip(free, STRESS_FREE_VALUES, strict=True):
        w[c] = v
    for i, c in enumerate(pivots):
        w[c] = -sum((rows[i][f] * w[f] for f in free), Fraction(0))
    for i in range(n):  # equilibrium, checked again from the definition
        assert sum((w[k] * (XS[b] - XS[a]) * (1 if a == i else -1)
                    for k, (a, b) in enumerate(EDGES) if i in (a, b)), Fraction(0)) == 0
    return w


def test_collinear_framework_is_prestress_stable_exactly():
    """The flexes are the motions across the line (modulo the trivial ones, whose span on each
    axis is ``{1, x}``); a stress's energy on them is ``y^T Omega y + z^T Omega z`` with
    ``Omega`` its stress matrix, whose kernel holds ``1`` and ``x`` (equilibrium). Writing any
    vector as a member of ``{1, x}`` plus one vanishing at vertices 0 and 1 (``x0 != x1``), the
    energy is positive on every non-trivial flex iff ``Omega`` on vertices 2..6 is positive
    definite: exact pivots prove it."""
    w = exact_collinear_stress()
    n = len(XS)
    omega = [[Fraction(0)] * n for _ in range(n)]
    for k, (i, j) in enumerate(EDGES):
        omega[i][i] += w[k]
        omega[j][j] += w[k]
        omega[i][j] -= w[k]
        omega[j][i] -= w[k]
    assert positive_definite([[omega[i][j] for j in range(2, n)] for i in range(2, n)])


def test_collinear_framework_is_borderline_at_the_default_and_stable_below():
    """The issue's case: at the default q_rtol the answer was a definite False; the exact
    reference above says stable, with a margin below q_rtol: None, with the reason; at
    q_rtol = 1e-9 the engine proves it stable."""
    lk = collinear()
    rig = first_order(lk)
    assert (rig.self_stresses.shape[0], rig.dof) == (4, 10)
    pre = prestress(lk, rig, TOL)
    assert pre.prestress_stable is None and pre.second_order_rigid is None, pre.reason
    assert "borderline" in pre.reason and "q_rtol" in pre.reason
    assert second_order(lk, TOL).prestress.prestress_stable is None
    fine = prestress(lk, rig, Tolerances(q_rtol=1e-9))
    assert fine.prestress_stable is True and fine.second_order_rigid is True
