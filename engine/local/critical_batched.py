"""The critical-point refinement of :func:`engine.local.critical.refine_critical` from many starts
at
once (small linkages).

:func:`engine.local.critical.refine_critical` runs MINPACK's Levenberg-Marquardt from one start; on
a
four-bar its augmented system is 8 x 7 and the cost is the per-evaluation overhead of Python and
``least_squares`` (about 10 ms a start, most of an exploration). Here every start is one row of
a stack and each iteration is a handful of vectorised numpy expressions over the stack
(``F`` and ``dF/dx`` from the batched bar vectors, one stacked ``solve`` of the damped normal
equations), each start with its own damping and stopping rules.

The iteration is Levenberg-Marquardt (Nielsen's damping update, MINPACK's column scaling), as
:meth:`engine.local.critical.SparseAugmentedSystem.solve`. A start whose cost stops falling fast (a
*near miss*: lengths that are not critical, so the least-squares minimum has ``F != 0``) goes
on with the full Hessian of ``|F|^2`` (``A^T A + sum_i f_i Hess f_i``; ``F`` is quadratic, so
the second term is cheap and exact): Gauss-Newton converges only linearly to a minimum with a
residual (MINPACK stops after its 100 evaluations some ``1e-5`` short of the minimum on a
four-bar), Newton quadratically. The answers are the same critical points, and the same near
misses to within the distance MINPACK's stop leaves (the tests compare the two on random and
catalogue linkages).
"""

from __future__ import annotations

import weakref

import numpy as np

from engine.local.critical import REFINE_MAX_NFEV, Refined
from engine.model.batched import BATCH_MAX_FREE
from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.hessian import DenseStressHessian
from engine.model.tolerances import NORM_FLOOR, Tolerances

#: Largest linkage (free coordinates) refined in a batch; larger ones refine one start at a
#: time (:func:`engine.local.critical.refine_critical`, sparse from its own threshold on).
REFINE_BATCH_MAX_FREE = BATCH_MAX_FREE

#: A start switches from Gauss-Newton to Newton steps once an accepted step lowers its cost by
#: less than this fraction (linear convergence to a minimum with a residual).
NEWTON_SWITCH = 1e-3

#: Relative reductions (actual and predicted) below which a start has converged (MINPACK's
#: ``ftol`` as :func:`engine.local.critical.refine_critical` uses it, with room for the rounding of
#: a sum of squares).
FTOL = 1e-14

#: A step shorter than this, relative to the scaled ``x``, ends a start (MINPACK's ``xtol``).
XTOL = 1e-15

#: The deadline is checked every this many iterations.
DEADLINE_EVERY = 8

#: A linkage whose median bar length is outside ``[1 / UNIT_RANGE, UNIT_RANGE]`` is refined in
#: units of a power of two near that length (an exact rescaling). The cost weighs the length
#: rows (in length units) against the dimensionless stress rows: at lengths of 1e12 the
#: rounding of the length rows (about 1e-4) hides the stress rows, and a start stopped with
#: ``sigma_min / sigma_max`` about 1e-8, on the edge of ``rank_rtol`` (the equilateral
#: four-bar drawn at 1e12 lost a branch point to "regular").
UNIT_RANGE = 2.0**10


class BatchedAugmentedSystem:
    """``F(x)``, ``dF/dx`` and the second-order term ``sum_i f_i Hess f_i`` of the augmented
    system (:class:`engine.local.critical.AugmentedSystem`) at a stack of points ``x`` (K, M + E).

    ``F`` is quadratic in ``x``, so ``dF/dx`` is affine in ``x`` and the second-order term
    linear in ``F``: both are one matrix product with maps built once (from the direct
    expressions of :meth:`jacobian_direct` and :meth:`second_order_direct` at unit vectors;
    the tests compare the two), as are the bar vectors (affine in ``u``).
    """

    def __init__(self, cons: Constraints) -> None:
        lk = cons.linkage
        self.cons = cons
        self.m, self.e = m, e = cons.n_free, cons.n_constraints
        self.n, self.p = n, p = m + e, e + m + 1
        self.d = d = lk.dimension
        self.free = ~np.asarray(lk.fixed, dtype=bool)
        self.base = np.array(lk.positions, dtype=float)
        ends = lk.ends[cons.bars]
        self.i, self.j = ends[:, 0], ends[:, 1]
        self.lengths = lk.lengths[cons.bars].astype(float)
        self.targets = self.lengths**2
        self.two_l = 2.0 * self.lengths
        self.scale = 2.0 * float(np.median(self.lengths))
        pattern = cons.pattern
        self.rows, self.cols, self.axes = pattern.rows, pattern.cols, pattern.axes
        self.sign2 = 2.0 * pattern.sign
        # H_w = sum_a w_a Hess(l_a^2) as one product w @ P, P (E, M*M)
        hess = DenseStressHessian(cons)
        self.hess_map = np.zeros((e, m * m))
        np.add.at(self.hess_map, (hess._bar, hess._flat), hess._sign)
        # affine maps: bar vectors of u, J of u, dF/dx of x; linear: the second-order term of F
        eye_m, eye_n, eye_p = np.eye(m), np.eye(n), np.eye(p)
        zero = np.zeros((1, m))
        self.vec0 = self._vectors_direct(zero, self.base).reshape(1, e * d)
        self.vec_map = self._vectors_direct(eye_m, self.base).reshape(m, e * d) - self.vec0
        self.jac0 = self._jac(self.vec0.reshape(1, e, d)).reshape(1, e * m)
        self.jac_map = self._jac(self.vec_map.reshape(m, e, d) + 0.0).reshape(m, e * m)
        zero_x = np.zeros((1, n))
        self.a0 = self.jacobian_direct(zero_x).reshape(1, p * n)
        self.a_map = self.jacobian_direct(eye_n).reshape(n, p * n) - self.a0
        self.s_map = self.second_order_direct(eye_p).reshape(p, n * n)

    def _vectors_direct(self, u: np.ndarray, base: np.ndarray) -> np.ndarray:
        pos = np.broadcast_to(base, (len(u), *base.shape)).copy()
        pos[:, self.free] = u
        return pos[:, self.i] - pos[:, self.j]

    def _jac(self, vec: np.ndarray) -> np.ndarray:
        """``J`` (K, E, M) of the bar vectors (K, E, d) (linear in them)."""
        out = np.zeros((len(vec), self.e, self.m))
        out[:, self.rows, self.cols] = self.sign2 * vec[:, self.rows, self.axes]
        return out

    def vectors(self, u: np.ndarray) -> np.ndarray:
        """``p_i - p_j`` (K, E, d) at the rows of ``u`` (K, M)."""
        return (u @ self.vec_map + self.vec0).reshape(len(u), self.e, self.d)

    def jacobians(self, u: np.ndarray) -> np.ndarray:
        """``J`` (K, E, M) at the rows of ``u``."""
        return (u @ self.jac_map + self.jac0).reshape(len(u), self.e, self.m)

    def residual(self, x: np.ndarray) -> np.ndarray:
        """``F`` (K, E + M + 1)."""
        m, e = self.m, self.e
        u, s = x[:, :m], x[:, m:]
        vec = (u @ self.vec_map + self.vec0).reshape(len(x), e, self.d)
        f = np.empty((len(x), self.p))
        f[:, :e] = (np.einsum("kij,kij->ki", vec, vec) - self.targets) / self.two_l
        f[:, e:e + m] = np.matmul(s[:, None, :], self.jacobians(u))[:, 0] / self.scale
        f[:, -1] = np.einsum("ka,ka->k", s, s) - 1.0
        return f

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """``dF/dx`` (K, E + M + 1, M + E) (affine in ``x``: one product)."""
        return (x @ self.a_map + self.a0).reshape(len(x), self.p, self.n)

    def second_order(self, f: np.ndarray) -> np.ndarray:
        """``sum_i f_i Hess f_i`` (K, M + E, M + E) for residuals ``f`` (K, E + M + 1)
        (linear in ``f``: one product)."""
        return (f @ self.s_map).reshape(len(f), self.n, self.n)

    def jacobian_direct(self, x: np.ndarray) -> np.ndarray:
        """``dF/dx`` from its blocks: ``[[J / 2L, 0], [H_sigma / s, J^T / s], [0, 2 sigma]]``."""
        m, e = self.m, self.e
        u, s = x[:, :m], x[:, m:]
        jac = self._jac(self._vectors_direct(u, self.base))
        a = np.zeros((len(x), self.p, self.n))
        a[:, :e, :m] = jac / self.two_l[:, None]
        a[:, e:e + m, :m] = (s @ self.hess_map).reshape(len(x), m, m) / self.scale
        a[:, e:e + m, m:] = np.transpose(jac, (0, 2, 1)) / self.scale
        a[:, -1, m:] = 2.0 * s
        return a

    def second_order_direct(self, f: np.ndarray) -> np.ndarray:
        """``sum_i f_i Hess f_i`` from its blocks: ``F`` is quadratic in ``x``, so this is
        exact and depends on ``F`` only. Length rows: ``H_w`` with ``w = f_a / 2L_a``; stress
        rows (bilinear in ``u`` and ``sigma``): the ``u``-``sigma`` block ``J(r)^T / s`` with
        ``r`` their residual taken as a displacement (fixed vertices at zero); the last row:
        ``2 f_last I`` on ``sigma``."""
        m, e = self.m, self.e
        k = len(f)
        out = np.zeros((k, self.n, self.n))
        w = f[:, :e] / self.two_l
        out[:, :m, :m] = (w @ self.hess_map).reshape(k, m, m)
        cross = self._jac(self._vectors_direct(f[:, e:e + m], np.zeros_like(self.base)))
        cross /= self.scale
        out[:, :m, m:] = np.transpose(cross, (0, 2, 1))
        out[:, m:, :m] = cross
        idx = np.arange(m, m + e)
        out[:, idx, idx] += 2.0 * f[:, -1:]
        return out


_SYSTEMS: weakref.WeakKeyDictionary[Constraints, BatchedAugmentedSystem] = (
    weakref.WeakKeyDictionary()
)


def batched_system(cons: Constraints) -> BatchedAugmentedSystem:
    """The :class:`BatchedAugmentedSystem` of ``cons`` (built once per ``cons``)."""
    system = _SYSTEMS.get(cons)
    if system is None:
        system = _SYSTEMS[cons] = BatchedAugmentedSystem(cons)
    return system


def start_stresses(cons: Constraints, us: np.ndarray) -> np.ndarray:
    """The start stress of :func:`engine.local.critical.refine_critical` at every row of ``us``:
    the left singular vector of ``J`` of the smallest singular value (K, E)."""
    system = batched_system(cons)
    jac = system.jacobians(us)
    left, _, _ = np.linalg.svd(jac, full_matrices=True)
    return left[:, :, -1]


def _solve(mats: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Stacked ``solve``; rows whose matrix is singular get a NaN step (rejected)."""
    try:
        return np.linalg.solve(mats, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        out = np.full(rhs.shape, np.nan)
        for k in range(len(mats)):
            try:
                out[k] = np.linalg.solve(mats[k], rhs[k])
            except np.linalg.LinAlgError:
                pass
        return out


def levenberg_marquardt(
    system: BatchedAugmentedSystem, x0: np.ndarray, max_iter: int = REFINE_MAX_NFEV,
    deadline: Deadline = NEVER,
) -> tuple[np.ndarray, np.ndarray]:
    """Minimise ``|F|^2`` from every row of ``x0`` (K, M + E): Levenberg-Marquardt, Newton
    steps once a start converges linearly (module docstring). Returns the last accepted ``x``
    of every start and which starts finished (converged, or stopped by their step rules or the
    iteration budget) before ``deadline``."""
    x = np.array(x0, dtype=float)
    k, n = x.shape
    f, a = system.residual(x), system.jacobian(x)
    cost = np.einsum("kp,kp->k", f, f)
    diag = np.maximum(np.sqrt(np.einsum("kpn,kpn->kn", a, a)), NORM_FLOOR)
    lam = 1e-3 * np.max(diag**2, axis=1)
    nu = np.full(k, 2.0)
    newton = np.zeros(k, dtype=bool)
    live = np.isfinite(cost) & (cost > 0.0)
    finished = ~live
    eye = np.arange(n)
    for it in range(max_iter):
        if not live.any():
            break
        if it % DEADLINE_EVERY == 0 and deadline.expired():
            return x, finished
        idx = np.flatnonzero(live)
        ai, fi = a[idx], f[idx]
        at = np.transpose(ai, (0, 2, 1))
        damped = at @ ai
        nw = newton[idx]
        curv = system.second_order(fi[nw]) if nw.any() else None
        if curv is not None:
            damped[nw] += curv
        grad = np.matmul(at, fi[:, :, None])[:, :, 0]
        damped[:, eye, eye] += lam[idx, None] * diag[idx] ** 2
        step = _solve(damped, -grad)
        ok = np.all(np.isfinite(step), axis=1)
        step[~ok] = 0.0
        x_new = x[idx] + step
        f_new = system.residual(x_new)
        cost_new = np.einsum("kp,kp->k", f_new, f_new)
        lin = fi + np.matmul(ai, step[:, :, None])[:, :, 0]
        model = np.einsum("kp,kp->k", lin, lin)
        if curv is not None:
            sn = step[nw]
            model[nw] += np.einsum("ki,ki->k", np.matmul(curv, sn[:, :, None])[:, :, 0], sn)
        c0 = cost[idx]
        pred = c0 - model
        actual = c0 - cost_new
        with np.errstate(divide="ignore", invalid="ignore"):
            rho = np.where(pred > 0, actual / pred, -1.0)
        xs = np.linalg.norm(diag[idx] * x[idx], axis=1)
        small = np.linalg.norm(diag[idx] * step, axis=1) <= XTOL * xs
        accept = ok & (rho > 1e-4) & np.isfinite(cost_new)
        converged = (np.abs(actual) <= FTOL * c0) & (pred <= FTOL * c0) & ok
        # accepted: move, new Jacobian, less damping
        acc = idx[accept]
        if len(acc):
            x[acc] = x_new[accept]
            f_acc, a_acc = f_new[accept], system.jacobian(x[acc])
            f[acc], a[acc] = f_acc, a_acc
            newton[acc] |= actual[accept] < NEWTON_SWITCH * c0[accept]
            cost[acc] = cost_new[accept]
            diag[acc] = np.maximum(diag[acc], np.sqrt(np.einsum("kpn,kpn->kn", a_acc, a_acc)))
            r = rho[accept]
            lam[acc] *= np.maximum(1.0 / 3.0, 1.0 - (2.0 * r - 1.0) ** 3)
            nu[acc] = 2.0
        rej = idx[~accept]
        lam[rej] *= nu[rej]
        nu[rej] *= 2.0
        stop = small | converged | ~np.isfinite(lam[idx]) | (lam[idx] > 1e300)
        stop |= accept & (cost_new == 0.0)
        live[idx[stop]] = False
        finished[idx[stop]] = True
    finished |= live  # the iteration budget is a finish, as MINPACK's max_nfev
    return x, finished


def unit_length(cons: Constraints) -> float:
    """The unit of the batched refinement: 1 for median bar lengths within ``UNIT_RANGE`` of
    1, else the power of two nearest to the median (module constant ``UNIT_RANGE``)."""
    median = float(np.median(cons.linkage.lengths[cons.bars]))
    if 1.0 / UNIT_RANGE <= median <= UNIT_RANGE:
        return 1.0
    return float(2.0 ** round(np.log2(median)))


_IN_UNITS: weakref.WeakKeyDictionary[Constraints, Constraints] = weakref.WeakKeyDictionary()


def _in_units(cons: Constraints, unit: float) -> Constraints:
    """``cons`` with every position and length divided by ``unit`` (a power of two: exact)."""
    scaled = _IN_UNITS.get(cons)
    if scaled is None:
        lk = cons.linkage
        scaled = _IN_UNITS[cons] = Constraints(
            lk.with_positions(lk.positions / unit).with_lengths(lk.lengths / unit))
    return scaled


def refine_critical_batch(
    cons: Constraints, us: np.ndarray, tol: Tolerances, sigmas: np.ndarray | None = None,
    deadline: Deadline = NEVER,
) -> list[Refined | None]:
    """:func:`engine.local.critical.refine_critical` from every row of ``us`` (K, M) at once, with
    the start stresses ``sigmas`` (K, E) where given (else the smallest left singular vectors
    of ``J``, as there). ``None`` for a start the deadline stopped before it finished."""
    us = np.asarray(us, dtype=float).reshape(-1, cons.n_free)
    if not len(us):
        return []
    system = batched_system(cons)
    unit = unit_length(cons)
    work = system if unit == 1.0 else batched_system(_in_units(cons, unit))
    if sigmas is None:
        s0 = start_stresses(cons, us)
    else:
        s0 = np.asarray(sigmas, dtype=float)
        s0 = s0 / np.linalg.norm(s0, axis=1, keepdims=True)
    x, finished = levenberg_marquardt(work, np.concatenate([us / unit, s0], axis=1),
                                      deadline=deadline)
    m = cons.n_free
    u, s = x[:, :m] * unit, x[:, m:]
    s = s / np.linalg.norm(s, axis=1, keepdims=True)
    vec = system.vectors(u)
    jac = system.jacobians(u)
    length_res = np.max(np.abs(np.sqrt(np.einsum("kij,kij->ki", vec, vec)) - system.lengths),
                        axis=1, initial=0.0)
    stress = np.linalg.norm(np.einsum("ka,kam->km", s, jac), axis=1)
    stress_res = stress / np.maximum(np.linalg.norm(jac, axis=(1, 2)), NORM_FLOOR)
    ok = (length_res <= tol.residual_atol) & (stress_res <= tol.rank_rtol)
    return [Refined(u[r].copy(), s[r].copy(), float(length_res[r]), float(stress_res[r]),
                    bool(ok[r])) if finished[r] else None for r in range(len(us))]
