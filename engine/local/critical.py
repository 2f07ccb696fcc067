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
import scipy.sparse as sp
from scipy.optimize import least_squares
from scipy.sparse.linalg import splu

from engine.local.second_order import SecondOrderResult, second_order
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.hessian import dense_stress_hessian, stress_hessian_map
from engine.model.linkage import Linkage
from engine.model.tolerances import NORM_FLOOR, Tolerances


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


#: From this many unknowns ``M + E`` on, :func:`refine_critical` runs the sparse
#: Levenberg-Marquardt of :class:`SparseAugmentedSystem` (MINPACK's dense QR below it).
SPARSE_REFINE_MIN_UNKNOWNS = 160

#: Residual evaluations of one refinement (either method).
REFINE_MAX_NFEV = 100

#: Methods of :func:`refine_critical`: ``"auto"`` chooses by size.
REFINE_METHODS = ("auto", "minpack", "sparse")


class SparseAugmentedSystem:
    """``dF/dx`` of :class:`AugmentedSystem` as a sparse matrix, and a Levenberg-Marquardt
    iteration on it (:meth:`solve`) for large linkages.

    Every block but the last row (``2 sigma``, dense over the stresses) is sparse with a fixed
    pattern: ``J / 2L`` (4 entries per planar bar), ``H_sigma / s`` and ``J^T / s``. The pattern
    is merged into CSR order once; each Jacobian is one weighted ``bincount`` into it. A step
    solves ``(A0^T A0 + lam D^2 + a a^T) dx = -A^T F`` (``A0`` the sparse rows, ``a`` the dense
    last row) by one sparse LU of ``A0^T A0 + lam D^2`` and the Sherman-Morrison correction for
    ``a a^T``; ``D`` are the largest column norms seen (MINPACK's scaling)."""

    def __init__(self, cons: Constraints) -> None:
        system = _SYSTEMS.get(cons)
        if system is None:
            system = _SYSTEMS[cons] = AugmentedSystem(cons)
        hess = stress_hessian_map(cons)
        self.system, self.hess = system, hess
        m, e = system.m, system.e
        self.m, self.e = m, e
        r, c = system.rows, system.cols
        rows = np.concatenate([r, e + hess._flat // m, e + c])
        cols = np.concatenate([c, hess._flat % m, m + r])
        key = rows * (m + e) + cols
        uniq, self._slot = np.unique(key, return_inverse=True)
        self._nnz = len(uniq)
        self._indices = (uniq % (m + e)).astype(np.int32)
        self._indptr = np.searchsorted(uniq // (m + e), np.arange(e + m + 1)).astype(np.int32)
        self._inv_2l = 1.0 / (2.0 * system.lengths[r])

    def sparse_rows(self, x: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
        """``A0`` (E + M, M + E) sparse and the dense last row ``a`` (M + E,) of ``dF/dx``."""
        sysm, m, e = self.system, self.m, self.e
        u, s = x[:m], x[m:]
        _, jac = sysm._at(u)
        jv = jac[sysm.rows, sysm.cols]
        vals = np.concatenate([jv * self._inv_2l, self.hess._sign * s[self.hess._bar] / sysm.scale,
                               jv / sysm.scale])
        data = np.bincount(self._slot, weights=vals, minlength=self._nnz)
        a0 = sp.csr_matrix((data, self._indices, self._indptr), shape=(e + m, m + e))
        last = np.zeros(m + e)
        last[m:] = 2.0 * s
        return a0, last

    def solve(self, x0: np.ndarray, max_nfev: int = REFINE_MAX_NFEV,
              xtol: float = 1e-15, ftol: float = 1e-15) -> np.ndarray:
        """Levenberg-Marquardt from ``x0`` (Nielsen's damping update); stops when a step or
        the predicted and actual reductions fall below ``xtol`` / ``ftol`` (relative), or after
        ``max_nfev`` residual evaluations, as MINPACK's ``lmder``. Returns the last accepted
        ``x``."""
        residual = self.system.residual
        x = np.array(x0, dtype=float)
        f = residual(x)
        cost = float(f @ f)
        nfev = 1
        a0, last = self.sparse_rows(x)
        diag = np.maximum(np.sqrt(np.asarray(a0.multiply(a0).sum(axis=0)).ravel() + last**2),
                          NORM_FLOOR)
        normal0 = (a0.T @ a0).tocsc()
        lam, nu = 1e-3 * float(np.max(diag**2)), 2.0
        while nfev < max_nfev and cost > 0.0:
            grad = a0.T @ f[:-1] + last * f[-1]
            try:
                lu = splu((normal0 + sp.diags(lam * diag**2, format="csc")).tocsc())
            except RuntimeError:  # exactly singular: damp harder
                lam, nu = lam * nu, 2.0 * nu
                continue
            y, z = lu.solve(-grad), lu.solve(last)
            step = y - (last @ y) / (1.0 + last @ z) * z
            if not np.all(np.isfinite(step)):
                break
            x_new = x + step
            f_new = residual(x_new)
            nfev += 1
            cost_new = float(f_new @ f_new)
            lin = a0 @ step + f[:-1]
            pred = cost - float(lin @ lin + (f[-1] + last @ step) ** 2)
            actual = cost - cost_new
            rho = actual / pred if pred > 0 else -1.0
            small = float(np.linalg.norm(diag * step)) <= xtol * float(np.linalg.norm(diag * x))
            if rho > 1e-4 and np.isfinite(cost_new):
                x, f, cost = x_new, f_new, cost_new
                a0, last = self.sparse_rows(x)
                diag = np.maximum(diag, np.sqrt(
                    np.asarray(a0.multiply(a0).sum(axis=0)).ravel() + last**2))
                normal0 = (a0.T @ a0).tocsc()
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                if small or (abs(actual) <= ftol * cost and pred <= ftol * cost):
                    break
            else:
                lam, nu = lam * nu, 2.0 * nu
                if small:
                    break
        return x


_SPARSE_SYSTEMS: weakref.WeakKeyDictionary[Constraints, SparseAugmentedSystem] = (
    weakref.WeakKeyDictionary()
)


def refine_critical(
    cons: Constraints, u0: np.ndarray, tol: Tolerances, sigma0: np.ndarray | None = None,
    *, method: str = "auto",
) -> Refined:
    """Solve the augmented system in least squares (Levenberg-Marquardt) from ``u0``.

    ``method="auto"`` runs MINPACK's ``lmder`` (dense QR) below
    :data:`SPARSE_REFINE_MIN_UNKNOWNS` unknowns and the sparse iteration of
    :class:`SparseAugmentedSystem` from there on (the tests check the two against each
    other); ``"minpack"`` or ``"sparse"`` force one."""
    if method not in REFINE_METHODS:
        raise InvalidRequest(f"unknown method {method!r}: one of {', '.join(REFINE_METHODS)}",
                             loc=("method",))
    m = cons.n_free
    system = _SYSTEMS.get(cons)
    if system is None:
        system = _SYSTEMS[cons] = AugmentedSystem(cons)
    jac0 = cons.jacobian(u0, sparse=False)
    s0 = _smallest_left_singular(jac0) if sigma0 is None else sigma0 / np.linalg.norm(sigma0)
    x0 = np.concatenate([u0, s0])
    if method == "sparse" or (method == "auto"
                              and m + cons.n_constraints >= SPARSE_REFINE_MIN_UNKNOWNS):
        sparse = _SPARSE_SYSTEMS.get(cons)
        if sparse is None:
            sparse = _SPARSE_SYSTEMS[cons] = SparseAugmentedSystem(cons)
        x = sparse.solve(x0)
    else:
        x = least_squares(
            system.residual, x0, jac=system.jacobian, method="lm",
            xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=REFINE_MAX_NFEV,
        ).x
    u, s = x[:m], x[m:]
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
