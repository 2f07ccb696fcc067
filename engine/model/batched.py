"""The constraint map and its Jacobian at many configurations at once (small linkages).

:class:`engine.model.constraints.Constraints` evaluates one configuration per call; where the engine
checks or corrects many independent points (every seed of an exploration against a new curve)
the per-call overhead dominates for small linkages. Here ``U`` is a stack (K, M) of free
coordinate vectors and everything is one vectorised numpy expression over the stack (no loop
over bars or points). Dense only: meant for ``M`` up to a few dozen.
"""

from __future__ import annotations

import numpy as np

from engine.model.constraints import Constraints
from engine.model.tolerances import CORRECT_TIGHT, Tolerances

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
        pos = np.empty((len(us), *self.base.shape))
        pos[:] = self.base
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
        """:func:`engine.space.trace.correct` (without a given factor) at every row of ``vs`` with
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


#: The steps of a backtracking line search: ``t = 1, 1/2, 1/4, ...`` while ``t > 1e-10`` (as
#: :func:`engine.model.constraints._line_search` halves it; powers of two, so exactly its values).
BACKTRACK = 0.5 ** np.arange(34)
assert BACKTRACK[-1] > 1e-10 >= 0.5 * BACKTRACK[-1]

#: Relative margin between two sums of the same nonnegative squares taken in different orders
#: (``g @ g`` and ``einsum``): far above their rounding (``2 Ea eps``).
SUM_ORDER_MARGIN = 1e-12


def line_searches(
    cons: Constraints, batch: BatchedConstraints, u: np.ndarray, steps: list[np.ndarray],
    cost: float,
) -> list[tuple[np.ndarray, np.ndarray, float] | None]:
    """:func:`engine.model.constraints._line_search` from ``u`` along each of ``steps``, every trial
    point of every step evaluated in one batch: the same answers. The trial points, ``l^2``
    and residuals are the same numbers; a trial's cost is accepted as there, by ``g @ g``
    (whose rounding differs from the batch's sum), taken in order for the trials whose batch
    sum is not clearly above ``cost``."""
    if not steps:
        return []
    trials = u[None, None, :] + BACKTRACK[None, :, None] * np.array(steps)[:, None, :]
    flat = trials.reshape(-1, len(u))
    g_flat = batch.squared_lengths(flat) - cons.targets
    rough = np.einsum("ka,ka->k", g_flat, g_flat).reshape(len(steps), len(BACKTRACK))
    g_all = g_flat.reshape(len(steps), len(BACKTRACK), -1)
    out: list[tuple[np.ndarray, np.ndarray, float] | None] = []
    for n in range(len(steps)):
        found = None
        for k in np.flatnonzero(~(rough[n] >= cost * (1.0 + SUM_ORDER_MARGIN))):
            g_trial = g_all[n, k].copy()  # (``@`` of a view of a larger array can round
            cost_trial = float(g_trial @ g_trial)  # otherwise than of its own array)
            if cost_trial < cost:
                found = (trials[n, k].copy(), g_trial, cost_trial)
                break
        out.append(found)
    return out


def backtrack(
    batch: BatchedConstraints, u: np.ndarray, step: np.ndarray, cost: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Backtracking from every row of ``u`` (K, M) along its ``step``: the first ``t`` of
    :data:`BACKTRACK` at which ``|l^2 - L^2|^2`` falls below ``cost`` (K,): the points, their
    ``l^2 - L^2`` and costs (NaN, NaN, inf where no ``t`` does).

    Every trial point of every row is evaluated in one batch; the halvings are then replayed
    on those numbers, giving what one batch per ``t`` of the rows still looking gives (the
    tests compare the two bit for bit). The same trial points and ``l^2``; the sums of
    squares as there: ``l^2 - L^2`` of a batch of one row is contiguous and of several rows
    not, and einsum's sum rounds differently on the two, so both are taken and each ``t``
    uses the one its count of rows still looking would have had."""
    targets = batch.lengths**2
    k, m = u.shape
    new_u = np.full_like(u, np.nan)
    new_g = np.full((k, len(targets)), np.nan)
    new_cost = np.full(k, np.inf)
    if not k:
        return new_u, new_g, new_cost
    trials = u[:, None, :] + BACKTRACK[None, :, None] * step[:, None, :]  # (K, T, M)
    flat = batch.squared_lengths(trials.reshape(-1, m)) - targets  # (K T, E), several rows
    sums = {False: np.einsum("ka,ka->k", flat, flat).reshape(k, -1)}
    one = np.ascontiguousarray(flat)  # a batch of one row: contiguous
    sums[True] = np.einsum("ka,ka->k", one, one).reshape(k, -1)
    g_trials = flat.reshape(k, len(BACKTRACK), -1)
    rows = np.arange(k)
    for n in range(len(BACKTRACK)):
        c = sums[len(rows) == 1][rows, n]
        hit = c < cost[rows]
        if hit.any():
            r = rows[hit]
            new_u[r], new_g[r], new_cost[r] = trials[r, n], g_trials[r, n], c[hit]
            rows = rows[~hit]
            if not len(rows):
                break
    return new_u, new_g, new_cost


def project_many(
    cons: Constraints, us: np.ndarray, tol: Tolerances, max_iter: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`engine.model.constraints.project` from every row of ``us`` (K, M) at once: the same
    Gauss-Newton iteration with minimum-norm steps (truncated SVD at ``STEP_RCOND``, as its
    ``lstsq``), the same backtracking line search (one halving schedule for every row), the
    same stopping rules; an iteration in which a row needs the escapes of poor progress runs
    them with the scalar helpers for that row. Returns the projected coordinates and whether
    each met ``residual_atol`` (the tests compare with :func:`project` one start at a time)."""
    from engine.model.constraints import _escape, _unstick
    from engine.model.steps import STEP_RCOND

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
        new_u, new_g, new_cost = backtrack(batch, u[idx], step, cost[idx])
        found = np.isfinite(new_cost)
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
                tries = line_searches(cons, batch, u[r], [right[n].T @ np.where(
                    sing[n] > rc * sing[n, 0], proj / np.where(sing[n] > 0, sing[n], 1.0), 0.0)
                    for rc in (1e-4, 1e-2)], float(cost[r]))
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
