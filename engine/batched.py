"""The constraint map and its Jacobian at many configurations at once (small linkages).

:class:`engine.constraints.Constraints` evaluates one configuration per call; where the engine
checks or corrects many independent points (every seed of an exploration against a new curve)
the per-call overhead dominates for small linkages. Here ``U`` is a stack (K, M) of free
coordinate vectors and everything is one vectorised numpy expression over the stack (no loop
over bars or points). Dense only: meant for ``M`` up to a few dozen.
"""

from __future__ import annotations

import numpy as np

from engine.constraints import Constraints
from engine.tolerances import CORRECT_TIGHT, Tolerances

#: Above this many free coordinates the batched paths are not used: the per-point code's call
#: overhead no longer dominates (measured: no gain at M = 43 or 60, single-threaded BLAS).
BATCH_MAX_FREE = 32


class BatchedConstraints:
    """``l^2`` and ``J`` of ``cons`` at a stack of configurations."""

    def __init__(self, cons: Constraints) -> None:
        lk = cons.linkage
        self.cons = cons
        self.free = ~np.asarray(lk.fixed, dtype=bool)
        self.base = np.asarray(lk.positions, dtype=float)
        ends = lk.ends[cons.bars]
        self.i, self.j = ends[:, 0], ends[:, 1]
        self.lengths = lk.lengths[cons.bars]
        pattern = cons.pattern
        self.rows, self.cols = pattern.rows, pattern.cols
        self.sign, self.axes = pattern.sign, pattern.axes

    def bar_vectors(self, us: np.ndarray) -> np.ndarray:
        """``p_i - p_j`` (K, Ea, d)."""
        pos = np.broadcast_to(self.base, (len(us), *self.base.shape)).copy()
        pos[:, self.free] = us
        return pos[:, self.i] - pos[:, self.j]

    def squared_lengths(self, us: np.ndarray) -> np.ndarray:
        """``l^2`` (K, Ea)."""
        vec = self.bar_vectors(us)
        return np.einsum("kij,kij->ki", vec, vec)

    def jacobians(self, us: np.ndarray) -> np.ndarray:
        """``J`` (K, Ea, M)."""
        vec = self.bar_vectors(us)
        out = np.zeros((len(us), self.cons.n_constraints, self.cons.n_free))
        out[:, self.rows, self.cols] = 2.0 * self.sign * vec[:, self.rows, self.axes]
        return out

    def correct(
        self, vs: np.ndarray, ts: np.ndarray, tol: Tolerances, max_iter: int = 12
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`engine.trace.correct` (without a given factor) at every row of ``vs`` with
        the hyperplane normals ``ts``: the same iteration and stopping rules, vectorised.

        Returns the corrected points (K, M; converged to ``CORRECT_TIGHT * residual_atol``
        where rounding allows) and whether each met ``residual_atol``.
        """
        k, m = vs.shape
        mats = np.concatenate([ts[:, None, :], self.jacobians(vs)], axis=1)  # (K, M, M)
        w = vs.copy()
        ok = np.zeros(k, dtype=bool)
        live = np.ones(k, dtype=bool)
        # A singular [t; J] fails at once, as the scalar version's LU does.
        det = np.linalg.det(mats)
        live &= np.isfinite(det) & (det != 0.0)
        prev = np.full(k, np.inf)
        for _ in range(max_iter):
            if not live.any():
                break
            idx = np.flatnonzero(live)
            sq = self.squared_lengths(w[idx])
            g = sq - self.lengths**2
            res = np.max(np.abs(np.sqrt(sq) - self.lengths), axis=1, initial=0.0)
            done = res <= CORRECT_TIGHT * tol.residual_atol
            ok[idx[done]] = True
            live[idx[done]] = False
            norm = np.linalg.norm(g, axis=1)
            # not contracting: the point stands within residual_atol (rounding), else fails
            stalled = ~done & (norm > 0.7 * prev[idx])
            ok[idx[stalled]] = res[stalled] <= tol.residual_atol
            live[idx[stalled]] = False
            step = ~done & ~stalled
            idx, g = idx[step], g[step]
            prev[idx] = norm[step]
            if len(idx):
                rhs = np.concatenate([np.zeros((len(idx), 1)), -g], axis=1)
                w[idx] = w[idx] + np.linalg.solve(mats[idx], rhs[:, :, None])[:, :, 0]
        if live.any():  # out of iterations: judge the last iterate
            idx = np.flatnonzero(live)
            res = np.max(np.abs(np.sqrt(self.squared_lengths(w[idx])) - self.lengths), axis=1,
                         initial=0.0)
            ok[idx] = res <= tol.residual_atol
        return w, ok
