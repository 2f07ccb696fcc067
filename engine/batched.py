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


def project_many(
    cons: Constraints, us: np.ndarray, tol: Tolerances, max_iter: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`engine.constraints.project` from every row of ``us`` (K, M) at once: the same
    Gauss-Newton iteration with minimum-norm steps (truncated SVD at ``STEP_RCOND``, as its
    ``lstsq``), the same backtracking line search (one halving schedule for every row), the
    same stopping rules; an iteration in which a row needs the escapes of poor progress runs
    them with the scalar helpers for that row. Returns the projected coordinates and whether
    each met ``residual_atol`` (the tests compare with :func:`project` one start at a time)."""
    from engine.constraints import STEP_RCOND, _escape, _line_search, _unstick

    batch = BatchedConstraints(cons)
    targets = batch.lengths**2
    u = np.array(us, dtype=float).reshape(-1, cons.n_free)
    k = len(u)

    def max_res(v: np.ndarray) -> np.ndarray:
        sq = batch.squared_lengths(v)
        return np.max(np.abs(np.sqrt(sq) - batch.lengths), axis=1, initial=0.0)

    live = max_res(u) > tol.residual_atol
    for r in np.flatnonzero(live):
        u[r] = _unstick(cons, u[r])
    g = batch.squared_lengths(u) - targets
    cost = np.einsum("ka,ka->k", g, g)
    escapes = np.zeros(k, dtype=int)
    slow = np.zeros(k, dtype=int)
    for _ in range(max_iter):
        idx = np.flatnonzero(live)
        if not len(idx):
            break
        jac = batch.jacobians(u[idx])
        left, sing, right = np.linalg.svd(jac, full_matrices=False)
        keep = sing > STEP_RCOND * sing[:, :1]
        coef = np.einsum("kae,ka->ke", left, -g[idx])
        coef = np.where(keep, coef / np.where(keep, sing, 1.0), 0.0)
        step = np.einsum("ke,kem->km", coef, right)
        # backtracking: the first t = 1, 1/2, ... (> 1e-10) that lowers the cost
        new_u = np.full_like(u[idx], np.nan)
        new_g = np.full_like(g[idx], np.nan)
        new_cost = np.full(len(idx), np.inf)
        pending = np.ones(len(idx), dtype=bool)
        t = 1.0
        while t > 1e-10 and pending.any():
            rows = np.flatnonzero(pending)
            trial = u[idx[rows]] + t * step[rows]
            g_trial = batch.squared_lengths(trial) - targets
            c_trial = np.einsum("ka,ka->k", g_trial, g_trial)
            hit = c_trial < cost[idx[rows]]
            new_u[rows[hit]], new_g[rows[hit]] = trial[hit], g_trial[hit]
            new_cost[rows[hit]] = c_trial[hit]
            pending[rows[hit]] = False
            t *= 0.5
        found = ~pending
        good = found & (new_cost <= 0.5 * cost[idx])  # no escape needed: move, vectorised
        r = idx[good]
        u[r], g[r] = new_u[good], new_g[good]
        slow[r] = np.where(new_cost[good] > 0.99 * cost[r], slow[r] + 1, 0)
        cost[r] = new_cost[good]
        for n in np.flatnonzero(~good):
            r = idx[n]
            best = (new_u[n], new_g[n], float(new_cost[n])) if found[n] else None
            if (best is None or best[2] > 0.5 * cost[r]) and escapes[r] < 8:
                escapes[r] += 1
                # the truncated steps from this row's SVD (lstsq's at rcond = rc)
                proj = left[n].T @ -g[r]
                tries = [_line_search(cons, u[r], right[n].T @ np.where(
                    sing[n] > rc * sing[n, 0], proj / np.where(sing[n] > 0, sing[n], 1.0), 0.0),
                    cost[r]) for rc in (1e-4, 1e-2)]
                tries += [best, _escape(cons, u[r], g[r], cost[r])]
                done = [x for x in tries if x is not None]
                best = min(done, key=lambda x: x[2]) if done else None
            if best is None:  # the line search failed: the residual stopped decreasing
                live[r] = False
                continue
            u[r], g[r] = best[0], best[1]
            slow[r] = slow[r] + 1 if best[2] > 0.99 * cost[r] else 0
            cost[r] = best[2]
        idx = idx[live[idx]]
        if len(idx):
            live[idx[max_res(u[idx]) <= tol.residual_atol]] = False
            live[idx[slow[idx] >= 8]] = False
    return u, max_res(u) <= tol.residual_atol
