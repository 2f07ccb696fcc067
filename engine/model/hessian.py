"""The stress-contracted Hessian ``H_sigma = sum_a sigma_a Hess(l_a^2)`` as a dense matrix.

Below :mod:`engine.model.constraints` (whose corrector's curvature step uses it) and
:mod:`engine.local.critical` (the augmented system's Jacobian): it needs only the bars and the
free coordinates, so it takes any object that has them.
"""

from __future__ import annotations

import weakref
from typing import Protocol

import numpy as np

from engine.model.linkage import Linkage


class HasBars(Protocol):
    """What the Hessian's index map reads (a :class:`engine.model.constraints.Constraints`)."""

    linkage: Linkage
    bars: np.ndarray  # (Ea,) indices of the active bars
    n_constraints: int
    n_free: int


class DenseStressHessian:
    """``H_sigma`` (M, M) as a dense matrix without sparse assembly.

    ``Hess(l_a^2) = 2 (e_i - e_j)(e_i - e_j)^T (x) I_d`` restricted to free coordinates: the
    ``(row, column)`` positions of every bar's four blocks are fixed, so they are computed once
    and each call is one weighted ``bincount`` (duplicates summed) into a dense array: no COO
    assembly and conversion (the hot spot of the augmented-system Jacobian in profiles), and
    ``O(E d^2 + M^2)`` for any size. :meth:`engine.model.constraints.Constraints.stress_hessian`
    stays the reference (tests compare the two).
    """

    def __init__(self, cons: HasBars) -> None:
        lk = cons.linkage
        d, m = lk.dimension, cons.n_free
        fi = lk.free_index
        ends = lk.ends[cons.bars]
        ci, cj = fi[ends[:, 0]].ravel(), fi[ends[:, 1]].ravel()  # (Ea*d,), -1 where fixed
        bar = np.repeat(np.arange(cons.n_constraints), d)
        flat, sign, which = [], [], []
        for a, b, sg in ((ci, ci, 1.0), (cj, cj, 1.0), (ci, cj, -1.0), (cj, ci, -1.0)):
            keep = (a >= 0) & (b >= 0)
            flat.append(a[keep] * m + b[keep])
            sign.append(np.full(int(keep.sum()), 2.0 * sg))
            which.append(bar[keep])
        self._flat = np.concatenate(flat)
        self._sign = np.concatenate(sign)
        self._bar = np.concatenate(which)
        self._m = m

    def __call__(self, sigma: np.ndarray) -> np.ndarray:
        w = self._sign * np.asarray(sigma, dtype=float)[self._bar]
        return np.bincount(self._flat, weights=w, minlength=self._m**2).reshape(self._m, self._m)


_HESSIANS: weakref.WeakKeyDictionary[HasBars, DenseStressHessian] = (
    weakref.WeakKeyDictionary()
)


def stress_hessian_map(cons: HasBars) -> DenseStressHessian:
    """The map ``sigma -> H_sigma`` of ``cons``, built once per ``cons`` (cached weakly)."""
    hess = _HESSIANS.get(cons)
    if hess is None:
        hess = _HESSIANS[cons] = DenseStressHessian(cons)
    return hess


def dense_stress_hessian(cons: HasBars, sigma: np.ndarray) -> np.ndarray:
    """``H_sigma`` of ``cons`` as a dense (M, M) array (the map is built once per ``cons``)."""
    return stress_hessian_map(cons)(sigma)
