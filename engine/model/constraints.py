"""Constraint map ``f(u) = l^2``, its Jacobian and stress-contracted Hessian, and projection.

Only *active* bars (those with at least one free coordinate at an end) are constraints; a bar
between two pins is a constant and is left out (its self-stress component is reported as 0).

Shapes: ``u`` (M,) free coordinates, ``J`` (Ea, M) with ``Ea`` the number of active bars,
``H_sigma`` (M, M).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from engine.model.budget import NEVER, Deadline
from engine.model.errors import NoNearbySolution
from engine.model.hessian import dense_stress_hessian
from engine.model.linkage import Linkage
from engine.model.lu import parity
from engine.model.steps import min_norm_step
from engine.model.tolerances import NORM_FLOOR, Tolerances

#: Above this many free coordinates, matrices are built and factorised as ``scipy.sparse``.
DENSE_MAX_FREE = 600


@dataclass(frozen=True)
class JacobianPattern:
    """COO pattern of ``J`` (one entry per free coordinate of each end of each bar): ``rows``
    (the bar), ``cols`` (the free coordinate), ``sign`` (+1 for the first end, -1 for the
    second) and ``axes`` (the coordinate axis). ``J[rows, cols] = 2 sign (p_i - p_j)[rows,
    axes]``: the one description of the structure that the dense, sparse and batched
    Jacobians and the augmented system all use."""

    rows: np.ndarray
    cols: np.ndarray
    sign: np.ndarray
    axes: np.ndarray

    @classmethod
    def of(cls, linkage: Linkage, first: np.ndarray, second: np.ndarray) -> JacobianPattern:
        """The pattern for bars with ends ``first``, ``second`` (vertex indices, in row
        order) of ``linkage``."""
        d = linkage.dimension
        fi = linkage.free_index
        rows = np.repeat(np.arange(len(first)), d)
        axes = np.tile(np.arange(d), len(first))
        ci, cj = fi[first].ravel(), fi[second].ravel()  # (Ea*d,), -1 where fixed
        ki, kj = ci >= 0, cj >= 0
        return cls(
            rows=np.concatenate([rows[ki], rows[kj]]),
            cols=np.concatenate([ci[ki], cj[kj]]),
            sign=np.concatenate([np.ones(int(ki.sum())), -np.ones(int(kj.sum()))]),
            axes=np.concatenate([axes[ki], axes[kj]]),
        )


class Constraints:
    """The constraint system of a linkage: sparsity pattern computed once, values on demand.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> c = Constraints(build_preset("four-bar"))
    >>> c.jacobian(c.linkage.coordinates()).shape
    (3, 4)
    """

    def __init__(self, linkage: Linkage) -> None:
        self.linkage = linkage
        self.bars = np.flatnonzero(linkage.active)  # (Ea,) indices into all bars
        ends = linkage.ends[self.bars]
        self._i, self._j = ends[:, 0], ends[:, 1]
        self.n_constraints = len(self.bars)
        self.n_free = linkage.n_free
        self.targets = linkage.lengths[self.bars] ** 2  # (Ea,) L^2
        # Bar vectors as differences of entries of ``[u, fixed coordinates]``: two gathers per
        # evaluation (the tracer evaluates them several times per point).
        d = linkage.dimension
        fixed = np.asarray(linkage.fixed).ravel()
        self._fixed_values = np.array(linkage.positions, dtype=float).ravel()[fixed]
        slot = np.empty(fixed.size, dtype=np.intp)
        slot[~fixed] = np.arange(int((~fixed).sum()))
        slot[fixed] = int((~fixed).sum()) + np.arange(int(fixed.sum()))
        axes = np.arange(d)
        self._gather_i = slot[self._i[:, None] * d + axes]  # (Ea, d)
        self._gather_j = slot[self._j[:, None] * d + axes]
        self._band_cache: tuple[int, tuple[int, int, np.ndarray, int, np.ndarray, int]] | None = \
            None

    @property
    def use_sparse(self) -> bool:
        """True when the linkage is large enough for sparse matrices."""
        return self.n_free > DENSE_MAX_FREE

    @cached_property
    def pattern(self) -> JacobianPattern:
        """The sparsity pattern of ``J`` (computed once: the values change, the structure
        never)."""
        return JacobianPattern.of(self.linkage, self._i, self._j)

    @cached_property
    def _csr(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """CSR structure of J, computed once: the order taking pattern values to CSR order,
        the column indices and the row pointers (the values change, the structure never)."""
        r, c = self.pattern.rows, self.pattern.cols
        order = np.lexsort((c, r))
        indptr = np.searchsorted(r[order], np.arange(self.n_constraints + 1))
        return order, c[order].astype(np.int32), indptr.astype(np.int32)

    @cached_property
    def _csc_below(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """CSC structure of ``[0; J]`` (J one row down, an empty first row): the order taking
        pattern values to CSC order, the row indices and the column pointers."""
        r, c = self.pattern.rows, self.pattern.cols
        order = np.lexsort((r, c))
        indptr = np.searchsorted(c[order], np.arange(self.n_free + 1))
        return order, (r[order] + 1).astype(np.int32), indptr.astype(np.int32)

    def unit_bordered_jacobian(self, u: np.ndarray, k: int) -> sp.csc_matrix:
        """``[e_k; J(u)]`` (Ea + 1, M) as CSC: ``J`` with one extra entry, so its LU has the
        fill of ``J`` alone (a dense border row would fill the factors)."""
        order, rows, indptr = self._csc_below
        at = int(indptr[k])
        data = np.insert(self.jacobian_values(u)[order], at, 1.0)
        indices = np.insert(rows, at, 0)
        ptr = indptr.copy()
        ptr[k + 1:] += 1
        mat = sp.csc_matrix((data, indices, ptr), shape=(self.n_constraints + 1, self.n_free))
        mat.has_canonical_format = True  # row 0 comes first in column k: still sorted
        return mat

    @cached_property
    def _band_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """A fixed reordering that makes ``J`` (and ``[e_k; J]``) a band matrix when the linkage
        allows it (chains): columns by reverse Cuthill-McKee on the coupling graph of the
        coordinates, rows by the mean position of their columns. Returns the position of each
        column, the band row of each pattern entry's bar (before inserting the unit row) and
        its band column, the sorted row keys, and the sign of the two permutations."""
        r, c = self.pattern.rows, self.pattern.cols
        m, ea = self.n_free, self.n_constraints
        inc = sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(ea, m))
        order = reverse_cuthill_mckee((inc.T @ inc).tocsr(), symmetric_mode=True)
        col_pos = np.empty(m, dtype=np.intp)
        col_pos[order] = np.arange(m)
        key = np.bincount(r, weights=col_pos[c], minlength=ea) / np.bincount(r, minlength=ea)
        rows = np.argsort(key, kind="stable")
        rank = np.empty(ea, dtype=np.intp)
        rank[rows] = np.arange(ea)
        return col_pos, rank[r], col_pos[c], key[rows], parity(col_pos) * parity(rank)

    def _unit_band_layout(self, k: int) -> tuple[int, int, np.ndarray, int, np.ndarray, int]:
        """Band layout of ``[e_k; J]``: ``kl``, ``ku``, the flat index into ``ab`` of each
        pattern entry, that of the unit entry, the band row of each original row, and the sign
        of the reordering. The last one is kept: ``k`` (the largest entry of the tangent)
        changes rarely from one traced point to the next."""
        if self._band_cache is not None and self._band_cache[0] == k:
            return self._band_cache[1]
        col_pos, entry_rank, entry_col, keys, sign = self._band_layout
        ck = int(col_pos[k])
        ins = int(np.searchsorted(keys, ck, side="right"))  # the unit row's band row
        diff = entry_rank + (entry_rank >= ins) - entry_col
        kl = max(int(diff.max()), ins - ck, 0)
        ku = max(int(-diff.min()), ck - ins, 0)
        m = self.n_free
        flat = (kl + ku + diff) * m + entry_col
        unit = (kl + ku + ins - ck) * m + ck
        row_rank = self._band_row_rank
        row_pos = np.concatenate([[ins], row_rank + (row_rank >= ins)])
        # moving the unit row from the top to band row ``ins`` is a cycle of length ins + 1
        layout = (kl, ku, flat, unit, row_pos, sign * (-1 if ins % 2 else 1))
        self._band_cache = (k, layout)
        return layout

    def unit_bordered_band(
        self, u: np.ndarray, k: int, max_work: int
    ) -> tuple[np.ndarray, int, int, np.ndarray, np.ndarray, int] | None:
        """``[e_k; J(u)]`` (square) reordered to band storage for LAPACK ``gbtrf``: ``ab``,
        ``kl``, ``ku``, the band row of each original row and band column of each column, and
        the sign of the reordering; None when ``kl (kl + ku)`` (the work per column) exceeds
        ``max_work``: then the band form is no cheaper than a general sparse LU."""
        kl, ku, flat, unit, row_pos, sign = self._unit_band_layout(k)
        if kl * (kl + ku) > max_work:
            return None
        ab = np.zeros((2 * kl + ku + 1, self.n_free))
        ab.flat[flat] = self.jacobian_values(u)
        ab.flat[unit] = 1.0
        return ab, kl, ku, row_pos, self._band_layout[0], sign

    @cached_property
    def _band_row_rank(self) -> np.ndarray:
        """The band row of each bar (before inserting the unit row), (Ea,)."""
        out = np.empty(self.n_constraints, dtype=np.intp)
        out[self.pattern.rows] = self._band_layout[1]
        return out

    @cached_property
    def _bordered_csc(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """CSC structure of ``[row; J]`` (a dense first row over all M columns): the order
        taking ``concatenate([row, J values in pattern order])`` to CSC order, the row indices
        and the column pointers."""
        r, c = self.pattern.rows, self.pattern.cols
        rows = np.concatenate([np.zeros(self.n_free, dtype=np.int64), r + 1])
        cols = np.concatenate([np.arange(self.n_free), c])
        order = np.lexsort((rows, cols))
        indptr = np.searchsorted(cols[order], np.arange(self.n_free + 1))
        return order, rows[order].astype(np.int32), indptr.astype(np.int32)

    def bar_vectors(self, u: np.ndarray) -> np.ndarray:
        """``p_i - p_j`` for each active bar, (Ea, d)."""
        ext = np.concatenate([u, self._fixed_values])
        return ext[self._gather_i] - ext[self._gather_j]

    def squared_lengths(self, u: np.ndarray) -> np.ndarray:
        """``f(u) = l^2``, (Ea,)."""
        diff = self.bar_vectors(u)
        return np.einsum("ij,ij->i", diff, diff)

    def residual(self, u: np.ndarray) -> np.ndarray:
        """``l(u) - L`` for each active bar, (Ea,)."""
        return np.sqrt(self.squared_lengths(u)) - self.linkage.lengths[self.bars]

    def jacobian(self, u: np.ndarray, sparse: bool | None = None) -> np.ndarray | sp.csr_matrix:
        """Analytic Jacobian ``J = d(l^2)/du``, (Ea, M): ``2 (p_i - p_j)`` on the coordinates of
        end ``i`` and its negative on those of end ``j`` (fixed coordinates dropped)."""
        sparse = self.use_sparse if sparse is None else sparse
        r, c = self.pattern.rows, self.pattern.cols
        vals = self.jacobian_values(u)
        shape = (self.n_constraints, self.n_free)
        if sparse:
            order, indices, indptr = self._csr
            return sp.csr_matrix((vals[order], indices.copy(), indptr.copy()), shape=shape)
        jac = np.zeros(shape)
        jac[r, c] = vals  # each (bar, coordinate) pair occurs once: a bar's ends differ
        return jac

    def jacobian_values(self, u: np.ndarray) -> np.ndarray:
        """The nonzero values of ``J(u)`` in the order of the (fixed) sparsity pattern."""
        r, s, ax = self.pattern.rows, self.pattern.sign, self.pattern.axes
        return 2.0 * s * self.bar_vectors(u)[r, ax]

    def bordered_jacobian(
        self, u: np.ndarray, row: np.ndarray, sparse: bool | None = None
    ) -> np.ndarray | sp.csc_matrix:
        """``[row; J(u)]``, (Ea + 1, M): sparse as CSC (ready for LU) from the structure
        computed once, so that only the values are refreshed."""
        sparse = self.use_sparse if sparse is None else sparse
        if not sparse:
            return np.vstack([row, self.jacobian(u, sparse=False)])
        order, indices, indptr = self._bordered_csc
        data = np.concatenate([np.asarray(row, dtype=float), self.jacobian_values(u)])[order]
        mat = sp.csc_matrix(
            (data, indices.copy(), indptr.copy()), shape=(self.n_constraints + 1, self.n_free)
        )
        mat.has_canonical_format = True  # sorted, no duplicates: by construction
        return mat

    def stress_hessian(
        self, sigma: np.ndarray, sparse: bool | None = None
    ) -> np.ndarray | sp.csr_matrix:
        """``H_sigma = sum_a sigma_a Hess(l_a^2)``, (M, M), for a stress ``sigma`` (Ea,).

        ``Hess(l_a^2) = 2 (e_i - e_j)(e_i - e_j)^T (x) I_d``, restricted to free coordinates; it
        does not depend on ``u``.
        """
        sparse = self.use_sparse if sparse is None else sparse
        d = self.linkage.dimension
        fi = self.linkage.free_index
        w = np.repeat(2.0 * np.asarray(sigma, dtype=float), d)  # (Ea*d,)
        ci = fi[self._i].ravel()
        cj = fi[self._j].ravel()
        blocks = ((ci, ci, w), (cj, cj, w), (ci, cj, -w), (cj, ci, -w))
        rows, cols, vals = [], [], []
        for a, b, v in blocks:
            keep = (a >= 0) & (b >= 0)
            rows.append(a[keep])
            cols.append(b[keep])
            vals.append(v[keep])
        hess = sp.coo_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.n_free, self.n_free),
        ).tocsr()  # duplicates are summed
        return hess if sparse else hess.toarray()

    def max_residual(self, u: np.ndarray) -> float:
        """``max_a |l_a(u) - L_a|`` (0 without constraints)."""
        res = self.residual(u)
        return float(np.max(np.abs(res))) if res.size else 0.0


@dataclass(frozen=True)
class ProjectionResult:
    """Outcome of :func:`project`.

    ``positions`` (V, d) is the projected configuration, ``residual`` the largest bar-length
    error there, ``distance`` the 2-norm of the displacement of the free coordinates.
    """

    success: bool
    message: str
    positions: np.ndarray
    residual: float
    input_residual: float
    distance: float
    iterations: int


def _unstick(cons: Constraints, u: np.ndarray) -> np.ndarray:
    """Nudge the free ends of bars whose ends coincide but whose target length is positive.

    There ``J``'s row is exactly zero, so no Gauss-Newton step can move the ends apart; a tiny
    seeded perturbation (``1e-6`` of the target length) breaks the symmetry reproducibly.
    """
    stuck = np.flatnonzero((cons.squared_lengths(u) == 0) & (cons.targets > 0))
    if stuck.size == 0:
        return u
    rng = np.random.default_rng(0)
    fi = cons.linkage.free_index
    u = u.copy()
    for end in (cons._i[stuck], cons._j[stuck]):
        idx = fi[end].ravel()
        scale = np.repeat(np.sqrt(cons.targets[stuck]), cons.linkage.dimension)
        keep = idx >= 0
        u[idx[keep]] += 1e-6 * scale[keep] * rng.normal(size=int(keep.sum()))
    return u


def _line_search(
    cons: Constraints, u: np.ndarray, step: np.ndarray | None, cost: float
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Backtracking on ``||l^2 - L^2||^2`` along ``step``: the new point, residual, cost
    (None without a step)."""
    if step is None:
        return None
    t = 1.0
    while t > 1e-10:
        trial = u + t * step
        g_trial = cons.squared_lengths(trial) - cons.targets
        cost_trial = float(g_trial @ g_trial)
        if cost_trial < cost:
            return trial, g_trial, cost_trial
        t *= 0.5
    return None


def _escape(
    cons: Constraints, u: np.ndarray, g: np.ndarray, cost: float
) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A step along a near-null direction ``z`` of ``J`` on which the cost decreases.

    ``f`` is quadratic, so ``f(u + s z) = f(u) + s J z + s^2 q`` with ``q = f(u+z) - f(u) - Jz``
    exactly; for ``J z ~ 0`` the cost ``|g + s^2 q|^2`` is least at ``s^2 = -(g.q)/(q.q)``.
    Candidates are the eigenvectors of ``Z H_g Z^T`` (``H_g = sum_a g_a Hess(l_a^2)``) on the
    near-null space ``Z``, most negative curvature first. Dense linkages only.
    """
    if cons.use_sparse or cons.n_free == 0:
        return None
    jac = cons.jacobian(u, sparse=False)
    _, s, vt = np.linalg.svd(jac, full_matrices=True)
    s_full = np.zeros(cons.n_free)
    s_full[: s.size] = s
    z = vt[s_full <= 1e-3 * max(float(s_full.max()), NORM_FLOOR)]
    if z.shape[0] == 0:
        return None
    # (the dense H_g by one weighted bincount: the same matrix as stress_hessian's assembly,
    # tests/engine/model/test_fast_paths.py)
    curv = z @ dense_stress_hessian(cons, g) @ z.T
    lam, vec = np.linalg.eigh(0.5 * (curv + curv.T))
    best = None
    f0 = cons.squared_lengths(u)
    for k in np.argsort(lam):
        d = vec[:, k] @ z
        q = cons.squared_lengths(u + d) - f0 - jac @ d
        gq, qq = float(g @ q), float(q @ q)
        if gq >= 0 or qq == 0:
            continue
        trial = u + np.sqrt(-gq / qq) * d
        g_trial = cons.squared_lengths(trial) - cons.targets
        cost_trial = float(g_trial @ g_trial)
        if cost_trial < cost and (best is None or cost_trial < best[2]):
            best = (trial, g_trial, cost_trial)
    return best


#: :attr:`ProjectionResult.message` of a projection that ``deadline`` stopped.
STOPPED_BY_DEADLINE = "stopped by the deadline"


def project(
    linkage: Linkage, tolerances: Tolerances | None = None, max_iter: int = 60,
    deadline: Deadline = NEVER,
) -> ProjectionResult:
    """Project the given positions onto the constraint set ``l(u) = L``.

    Gauss-Newton with minimum-norm steps (the step lies in the row space of ``J``, so the
    iteration moves as little as it can: near a regular solution it converges to the nearest
    point of the configuration space up to second order) and a backtracking line search on
    ``||l^2 - L^2||``.

    Returns a result with ``success=False`` when the residual cannot be brought below
    ``residual_atol`` (for example when the lengths admit no configuration nearby), or when
    ``deadline`` passes first (message :data:`STOPPED_BY_DEADLINE`).

    Examples
    --------
    >>> from engine.model.linkage import BarSpec, VertexSpec, build_linkage
    >>> lk = build_linkage(2, [VertexSpec("P", [0, 0], True), VertexSpec("A", [2, 0])],
    ...                    [BarSpec("r", ["P", "A"], 1.0)])
    >>> res = project(lk)
    >>> res.success, res.positions[1].round(9).tolist()
    (True, [1.0, 0.0])
    """
    tol = tolerances or Tolerances()
    cons = Constraints(linkage)
    u0 = linkage.coordinates()
    u = u0.copy()
    start = cons.max_residual(u)
    iterations = 0
    message = "converged"
    if start > tol.residual_atol:
        u = _unstick(cons, u)
        g = cons.squared_lengths(u) - cons.targets
        cost = float(g @ g)
        escapes = slow = 0
        for iterations in range(1, max_iter + 1):  # noqa: B007 (reported after the loop)
            jac = cons.jacobian(u)
            step = None if deadline.expired() else min_norm_step(jac, -g, deadline=deadline)
            if step is None:
                message = STOPPED_BY_DEADLINE
                break
            found = _line_search(cons, u, step, cost)
            if (found is None or found[2] > 0.5 * cost) and escapes < 8:
                # Poor progress: near a critical configuration a near-null direction dominates
                # the step. Try steps that ignore it (fix the rest of the residual first), and
                # leaving along negative curvature of the cost; keep the best.
                escapes += 1
                tries = [_line_search(cons, u, min_norm_step(jac, -g, rc), cost)
                         for rc in (1e-4, 1e-2)] if not cons.use_sparse else []
                tries += [found, _escape(cons, u, g, cost)]
                done = [x for x in tries if x is not None]
                found = min(done, key=lambda x: x[2]) if done else None
            if found is None:
                message = "line search failed: the residual stopped decreasing"
                break
            u, g, cost_new = found
            slow = slow + 1 if cost_new > 0.99 * cost else 0
            cost = cost_new
            if cons.max_residual(u) <= tol.residual_atol:
                break
            if slow >= 8:
                message = "stalled: the residual decreases by less than 1% per iteration"
                break
        else:
            message = f"no convergence in {max_iter} iterations"
    residual = cons.max_residual(u)
    success = residual <= tol.residual_atol
    if not success and message == "converged":
        message = "did not reach residual_atol"
    return ProjectionResult(
        success=success,
        message=message if not success else "converged",
        positions=linkage.positions_of(u),
        residual=residual,
        input_residual=start,
        distance=float(np.linalg.norm(u - u0)),
        iterations=iterations,
    )


def on_constraints(
    linkage: Linkage, tolerances: Tolerances | None = None
) -> tuple[Linkage, ProjectionResult]:
    """The linkage moved onto its configuration space, or :class:`NoNearbySolution`.

    Raises
    ------
    NoNearbySolution
        When :func:`project` does not succeed; the message gives the residual reached.
    """
    tol = tolerances or Tolerances()
    res = project(linkage, tol)
    if not res.success:
        raise NoNearbySolution(
            "the given positions are not near any configuration with the requested lengths: "
            f"{res.message}; the largest bar-length error reached is {res.residual:.3g} "
            f"(residual_atol {tol.residual_atol:.3g}, error at the given positions "
            f"{res.input_residual:.3g})",
            loc=("vertices",),
        )
    moved = linkage if res.distance == 0.0 else linkage.with_positions(res.positions)
    return moved, res
