"""Critical points: refinement on the augmented system and classification.

A critical point ``u`` with unit self-stress ``sigma`` solves (paper, Sec. II)::

    F(u, sigma) = [ (l^2(u) - L^2) / (2L) ;  J(u)^T sigma / (2 L_med) ;  |sigma|^2 - 1 ] = 0

``E + M + 1`` equations in ``M + E`` unknowns: for lengths that are not critical there is no
solution and the least-squares minimum is a *near miss*; at critical lengths the minimum is an
exact critical point. The rows are scaled so that the first block is a length error.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from engine.constraints import Constraints
from engine.linkage import Linkage
from engine.second_order import SecondOrderResult, second_order
from engine.tolerances import NORM_FLOOR, Tolerances


@dataclass(frozen=True)
class Refined:
    """Least-squares solution of the augmented system from one start.

    ``length_residual`` is ``max |l - L|``; ``stress_residual`` is ``|J^T sigma| / |J|_F``
    (dimensionless); ``critical`` says both are within tolerance.
    """

    u: np.ndarray
    sigma: np.ndarray
    length_residual: float
    stress_residual: float
    critical: bool


class DenseStressHessian:
    """``H_sigma`` (M, M) as a dense matrix without sparse assembly.

    ``Hess(l_a^2) = 2 (e_i - e_j)(e_i - e_j)^T (x) I_d`` restricted to free coordinates: the
    ``(row, column)`` positions of every bar's four blocks are fixed, so they are computed once
    and each call is one weighted ``bincount`` (duplicates summed) into a dense array: no COO
    assembly and conversion (the hot spot of the augmented-system Jacobian in profiles), and
    ``O(E d^2 + M^2)`` for any size. :meth:`engine.constraints.Constraints.stress_hessian`
    stays the reference (tests compare the two).
    """

    def __init__(self, cons: Constraints) -> None:
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


_HESSIANS: weakref.WeakKeyDictionary[Constraints, DenseStressHessian] = (
    weakref.WeakKeyDictionary()
)


def dense_stress_hessian(cons: Constraints, sigma: np.ndarray) -> np.ndarray:
    """``H_sigma`` of ``cons`` as a dense (M, M) array (the map is built once per ``cons``)."""
    hess = _HESSIANS.get(cons)
    if hess is None:
        hess = _HESSIANS[cons] = DenseStressHessian(cons)
    return hess(sigma)


def _smallest_left_singular(jac: np.ndarray) -> np.ndarray:
    u, _, _ = np.linalg.svd(jac, full_matrices=True)
    return u[:, -1]


class AugmentedSystem:
    """``F(u, sigma)`` of the module docstring and its Jacobian, dense, for
    :func:`refine_critical`.

    Evaluated with precomputed index arrays into preallocated blocks (``J`` once per ``u``,
    shared by the residual and the Jacobian at the same point): the Levenberg-Marquardt
    iteration calls these tens of times per start, so their overhead is the refinement's cost.
    """

    def __init__(self, cons: Constraints) -> None:
        lk = cons.linkage
        self.cons = cons
        self.m, self.e = cons.n_free, cons.n_constraints
        self.free = ~np.asarray(lk.fixed, dtype=bool)
        self.base = np.array(lk.positions, dtype=float)
        ends = lk.ends[cons.bars]
        self.i, self.j = ends[:, 0], ends[:, 1]
        self.lengths = lk.lengths[cons.bars]
        self.targets = self.lengths**2
        self.scale = 2.0 * float(np.median(self.lengths))
        pattern = cons.pattern
        self.rows, self.cols, self.axes = pattern.rows, pattern.cols, pattern.axes
        self.sign2 = 2.0 * pattern.sign
        self._u: np.ndarray | None = None
        self._sq = np.zeros(self.e)
        self._jac = np.zeros((self.e, self.m))

    def _at(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``l^2`` and ``J`` at ``u`` (cached for the last ``u``)."""
        if self._u is None or not np.array_equal(u, self._u):
            pos = self.base.copy()
            pos[self.free] = u
            vec = pos[self.i] - pos[self.j]
            self._sq = np.einsum("ij,ij->i", vec, vec)
            jac = np.zeros((self.e, self.m))
            jac[self.rows, self.cols] = self.sign2 * vec[self.rows, self.axes]
            self._jac = jac
            self._u = u.copy()
        return self._sq, self._jac

    def residual(self, x: np.ndarray) -> np.ndarray:
        """``F(x)``, (E + M + 1,)."""
        m, e = self.m, self.e
        u, s = x[:m], x[m:]
        sq, jac = self._at(u)
        out = np.empty(e + m + 1)
        out[:e] = (sq - self.targets) / (2.0 * self.lengths)
        out[e:e + m] = (s @ jac) / self.scale
        out[-1] = s @ s - 1.0
        return out

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """``dF/dx``, (E + M + 1, M + E)."""
        m, e = self.m, self.e
        u, s = x[:m], x[m:]
        _, jac = self._at(u)
        out = np.zeros((e + m + 1, m + e))
        out[:e, :m] = jac / (2.0 * self.lengths)[:, None]
        out[e:e + m, :m] = dense_stress_hessian(self.cons, s) / self.scale
        out[e:e + m, m:] = jac.T / self.scale
        out[-1, m:] = 2.0 * s
        return out


_SYSTEMS: weakref.WeakKeyDictionary[Constraints, AugmentedSystem] = weakref.WeakKeyDictionary()


def refine_critical(
    cons: Constraints, u0: np.ndarray, tol: Tolerances, sigma0: np.ndarray | None = None
) -> Refined:
    """Solve the augmented system in least squares (Levenberg-Marquardt) from ``u0``."""
    m = cons.n_free
    system = _SYSTEMS.get(cons)
    if system is None:
        system = _SYSTEMS[cons] = AugmentedSystem(cons)
    jac0 = cons.jacobian(u0, sparse=False)
    s0 = _smallest_left_singular(jac0) if sigma0 is None else sigma0 / np.linalg.norm(sigma0)
    res = least_squares(
        system.residual, np.concatenate([u0, s0]), jac=system.jacobian, method="lm",
        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=100,
    )
    u, s = res.x[:m], res.x[m:]
    s = s / np.linalg.norm(s)
    jac = cons.jacobian(u, sparse=False)
    length_res = cons.max_residual(u)
    stress_res = float(np.linalg.norm(jac.T @ s) / max(float(np.linalg.norm(jac)), NORM_FLOOR))
    ok = length_res <= tol.residual_atol and stress_res <= tol.rank_rtol
    return Refined(u, s, length_res, stress_res, ok)


@dataclass(frozen=True)
class CriticalPoint:
    """A critical point with its second-order classification."""

    u: np.ndarray
    analysis: SecondOrderResult
    length_residual: float
    stress_residual: float

    @property
    def kind(self) -> str:
        return self.analysis.kind


@dataclass(frozen=True)
class NearMiss:
    """A closest approach to a critical configuration for lengths that are not critical.

    ``singular_gap`` is ``s_min / s_max`` of ``J`` at ``u`` (on the configuration space),
    ``distance`` the configuration distance from ``u`` to the nearest critical configuration
    (of slightly different lengths), ``length_gap`` the largest length change that would make
    that configuration's lengths exact (``max |l(u_c) - L|``).
    """

    u: np.ndarray
    singular_gap: float
    distance: float
    length_gap: float
    critical_u: np.ndarray
    critical_sigma: np.ndarray | None = None  # the unit self-stress at ``critical_u``


def classify(linkage: Linkage, u: np.ndarray, tol: Tolerances) -> SecondOrderResult:
    """Second-order analysis of ``linkage`` at free coordinates ``u``."""
    return second_order(linkage.with_positions(linkage.positions_of(u)), tol, sparse=False)


def singular_gap(cons: Constraints, u: np.ndarray) -> float:
    """``s_min / s_max`` of ``J(u)``."""
    jac = cons.jacobian(u, sparse=False)
    s = np.linalg.svd(jac, compute_uv=False)
    return float(s[-1] / s[0]) if s.size and s[0] > 0 else 0.0
