"""The dense factorisation (LAPACK getrf/getrs called directly) against numpy's determinant and
solve and scipy's lu_factor (issue 15: the tracer's small systems)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from engine.model.lu import Factor


@pytest.mark.parametrize("n", [1, 2, 4, 7, 30])
@pytest.mark.parametrize("seed", range(5))
def test_dense_factor_agrees_with_numpy_and_scipy(n, seed):
    rng = np.random.default_rng(100 * n + seed)
    a = rng.normal(size=(n, n))
    fac = Factor(a)
    sign, logdet = np.linalg.slogdet(a)
    assert fac.ok and fac.sign == int(sign)
    assert fac.logdet == pytest.approx(logdet, rel=1e-12, abs=1e-12)
    b = rng.normal(size=n)
    assert np.allclose(fac.solve(b), np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)
    assert np.allclose(fac.solve(b), sla.lu_solve(sla.lu_factor(a), b), rtol=1e-12, atol=1e-14)
    e1 = np.zeros(n)
    e1[0] = 1.0
    assert np.allclose(fac.solve_first(), np.linalg.solve(a, e1), rtol=1e-10, atol=1e-12)


def test_a_singular_or_non_finite_matrix_is_not_ok():
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    for mat in (singular, np.zeros((3, 3)), np.array([[np.nan, 1.0], [0.0, 1.0]])):
        fac = Factor(mat)
        assert not fac.ok and fac.sign == 0 and fac.logdet == -np.inf


def test_integer_input_is_factorised_as_float():
    fac = Factor(np.array([[2, 1], [1, 3]]))
    assert fac.ok and fac.sign == 1 and fac.logdet == pytest.approx(np.log(5.0))
