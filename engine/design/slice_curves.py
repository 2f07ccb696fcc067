"""The equations of a slice's curves, and their continuation (for :mod:`.critical_values`).

With two bar lengths ``p = (L_x, L_y)`` free, the critical configurations solve::

    G(u, sigma, p) = [ (l^2(u) - L(p)^2) / s ;  J(u)^T sigma / s ;  |sigma|^2 - 1 ] = 0

``E + M + 1`` equations in ``M + E + 2`` unknowns: a one-dimensional solution set whose
projection on ``p`` is the slice (paper, Sec. III B). :class:`_System` is ``G`` and its Jacobian
(:class:`_BatchedSystem` at a stack of points), :func:`_onto_solutions` moves a start onto
``G = 0`` and :func:`_continue` follows the curve by pseudo-arclength continuation (tangent from
one factorisation of ``[DG; tau_prev]``, hyperplane Newton corrector).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from engine.model.batched import BATCH_MAX_FREE, BatchedConstraints
from engine.model.budget import NEVER, REASON_TIME, Deadline
from engine.model.constraints import Constraints
from engine.model.hessian import DenseStressHessian, dense_stress_hessian
from engine.model.linkage import Linkage
from engine.model.tolerances import NORM_FLOOR


@dataclass(frozen=True)
class Axis:
    """A free length: bar index and its range."""

    bar: int
    lo: float
    hi: float


class _System:
    """``G`` and its Jacobian for the two free lengths."""

    def __init__(self, linkage: Linkage, axes: tuple[Axis, Axis]) -> None:
        self.linkage = linkage
        self.cons = Constraints(linkage)
        act = [int(b) for b in self.cons.bars]
        self.rows = [act.index(a.bar) for a in axes]
        self.m, self.e = self.cons.n_free, self.cons.n_constraints
        self.base = linkage.lengths[self.cons.bars].copy()
        self.s = 2.0 * float(np.median(self.base))
        self.n = self.m + self.e + 2
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def lengths(self, p: np.ndarray) -> np.ndarray:
        out = self.base.copy()
        out[self.rows] = p
        return out

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return x[: self.m], x[self.m : self.m + self.e], x[self.m + self.e :]

    def _jacobian(self, u: np.ndarray) -> np.ndarray:
        """``J(u)``, reused while ``u`` is the last one asked for (``g`` and ``dg`` are asked
        at the same point by every Newton step and by least squares)."""
        last = self._last
        if last is not None and np.array_equal(last[0], u):
            return last[1]
        jac = self.cons.jacobian(u, sparse=False)
        self._last = (u.copy(), jac)
        return jac

    def g(self, x: np.ndarray) -> np.ndarray:
        u, sig, p = self.split(x)
        jac = self._jacobian(u)
        return np.concatenate([
            (self.cons.squared_lengths(u) - self.lengths(p) ** 2) / self.s,
            jac.T @ sig / self.s,
            [sig @ sig - 1.0],
        ])

    def dg(self, x: np.ndarray) -> np.ndarray:
        u, sig, p = self.split(x)
        jac = self._jacobian(u)
        out = np.zeros((self.e + self.m + 1, self.n))
        out[: self.e, : self.m] = jac / self.s
        for k, r in enumerate(self.rows):
            out[r, self.m + self.e + k] = -2.0 * p[k] / self.s
        hess = dense_stress_hessian(self.cons, sig)
        out[self.e : self.e + self.m, : self.m] = hess / self.s
        out[self.e : self.e + self.m, self.m : self.m + self.e] = jac.T / self.s
        out[-1, self.m : self.m + self.e] = 2.0 * sig
        return out


def _tangent(sys: _System, x: np.ndarray, prev: np.ndarray) -> np.ndarray | None:
    mat = np.vstack([sys.dg(x), prev])
    rhs = np.zeros(sys.n)
    rhs[-1] = 1.0
    try:
        y = np.linalg.solve(mat, rhs)
    except np.linalg.LinAlgError:
        return None
    norm = float(np.linalg.norm(y))
    return y / norm if np.isfinite(norm) and norm > 0 else None


def _correct(sys: _System, v: np.ndarray, t: np.ndarray) -> np.ndarray | None:
    x = v.copy()
    for _ in range(12):
        g = sys.g(x)
        if np.max(np.abs(g)) <= 1e-12:
            return x
        mat = np.vstack([sys.dg(x), t])
        try:
            dx = np.linalg.solve(mat, np.concatenate([-g, [0.0]]))
        except np.linalg.LinAlgError:
            return None
        x = x + dx
    return x if np.max(np.abs(sys.g(x))) <= 1e-10 else None


class _OutOfTime(Exception):
    """The deadline passed inside the least squares of :func:`_least_squares_onto`."""


def _least_squares_onto(sys: _System, x0: np.ndarray, deadline: Deadline) -> np.ndarray:
    """The least-squares (trust region) fallback of :func:`_onto_solutions` from ``x0``, the
    deadline looked at on every evaluation (each one a dense SVD of ``dG``: about 30 ms at 100
    rotors, 200 of them without it); ``x0`` itself once it has passed (the caller's check of
    ``|G|`` then leaves the start out)."""
    if deadline.expired():
        return x0

    def g_in_time(x: np.ndarray) -> np.ndarray:
        if deadline.expired():
            raise _OutOfTime
        return sys.g(x)

    try:
        sol = least_squares(g_in_time, x0, jac=sys.dg, method="trf", xtol=1e-15, ftol=1e-15,
                            gtol=1e-15, max_nfev=200)
    except _OutOfTime:
        return x0
    return np.asarray(sol.x)


def _onto_solutions(sys: _System, x0: np.ndarray, max_iter: int = 30,
                    deadline: Deadline = NEVER) -> np.ndarray:
    """A solution of ``G = 0`` near ``x0``: Gauss-Newton with minimum-norm steps (``G`` has two
    more unknowns than equations, so its solutions near a regular point form a curve and the
    iteration converges quadratically onto it); where that does not converge, least squares
    (trust region) from ``x0`` as before. Either way the caller checks ``|G| <= 1e-9`` (once
    ``deadline`` has passed, the iteration stops where it is: the check leaves it out)."""
    x = x0.copy()
    for _ in range(max_iter):
        g = sys.g(x)
        if not np.all(np.isfinite(g)):
            break
        if np.max(np.abs(g)) <= 1e-13:
            return x
        if deadline.expired():
            return x
        x = x - np.linalg.lstsq(sys.dg(x), g, rcond=None)[0]
    if np.all(np.isfinite(g := sys.g(x))) and np.max(np.abs(g)) <= 1e-12:
        return x
    return _least_squares_onto(sys, x0, deadline)


class _BatchedSystem:
    """``G`` and ``dG`` of :class:`_System` at a stack of points (K, M + E + 2) (small
    linkages: :data:`engine.model.batched.BATCH_MAX_FREE`)."""

    def __init__(self, sys: _System) -> None:
        self.sys = sys
        self.batch = BatchedConstraints(sys.cons)
        m, e = sys.m, sys.e
        hess = DenseStressHessian(sys.cons)
        self.hess_map = np.zeros((e, m * m))
        np.add.at(self.hess_map, (hess._bar, hess._flat), hess._sign)

    def g(self, xs: np.ndarray) -> np.ndarray:
        sys = self.sys
        m, e = sys.m, sys.e
        u, sig, p = xs[:, :m], xs[:, m:m + e], xs[:, m + e:]
        lengths = np.broadcast_to(sys.base, (len(xs), e)).copy()
        lengths[:, sys.rows] = p
        jac = self.batch.jacobians(u)
        out = np.empty((len(xs), e + m + 1))
        out[:, :e] = (self.batch.squared_lengths(u) - lengths**2) / sys.s
        out[:, e:e + m] = np.einsum("ka,kam->km", sig, jac) / sys.s
        out[:, -1] = np.einsum("ka,ka->k", sig, sig) - 1.0
        return out

    def dg(self, xs: np.ndarray) -> np.ndarray:
        sys = self.sys
        m, e, k = sys.m, sys.e, len(xs)
        u, sig, p = xs[:, :m], xs[:, m:m + e], xs[:, m + e:]
        jac = self.batch.jacobians(u)
        out = np.zeros((k, e + m + 1, sys.n))
        out[:, :e, :m] = jac / sys.s
        for c, r in enumerate(sys.rows):
            out[:, r, m + e + c] = -2.0 * p[:, c] / sys.s
        out[:, e:e + m, :m] = (sig @ self.hess_map).reshape(k, m, m) / sys.s
        out[:, e:e + m, m:m + e] = np.transpose(jac, (0, 2, 1)) / sys.s
        out[:, -1, m:m + e] = 2.0 * sig
        return out


def _min_norm_steps(mats: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``lstsq(mats[k], rhs[k])`` for every ``k`` (wide matrices, (K, p, n), p < n): from the
    QR factorisation of ``mats[k]^T = Q R`` (``x = Q R^-T rhs``, as accurate as the SVD of
    ``lstsq`` where ``mats[k]`` has full rank), by ``lstsq`` for the rows where ``R`` is
    singular to working precision."""
    q, r = np.linalg.qr(np.transpose(mats, (0, 2, 1)))
    diag = np.abs(np.diagonal(r, axis1=1, axis2=2))
    regular = np.min(diag, axis=1) > 1e-13 * np.maximum(np.max(diag, axis=1), NORM_FLOOR)
    out = np.empty((len(mats), mats.shape[2]))
    if regular.any():
        try:
            y = np.linalg.solve(np.transpose(r[regular], (0, 2, 1)), rhs[regular][:, :, None])
            out[regular] = np.matmul(q[regular], y)[:, :, 0]
        except np.linalg.LinAlgError:  # (not expected: R's diagonal was checked) by lstsq
            regular[:] = False
    for k in np.flatnonzero(~regular):
        out[k] = np.linalg.lstsq(mats[k], rhs[k], rcond=None)[0]
    return out


def _onto_solutions_batch(sys: _System, x0s: np.ndarray, max_iter: int = 30,
                          deadline: Deadline = NEVER) -> np.ndarray:
    """:func:`_onto_solutions` from every row of ``x0s`` at once (small linkages): the same
    Gauss-Newton iteration with minimum-norm steps, the rows that converge leaving it, and the
    least-squares fallback of :func:`_onto_solutions` for every row that does not converge
    (the tests compare the two). ``deadline`` is looked at between iterations and rows (large
    linkages: one dense ``lstsq`` or SVD each); the rows not reached keep their starts."""
    if sys.m > BATCH_MAX_FREE or len(x0s) < 2:
        return np.array([x0 if deadline.expired() else _onto_solutions(sys, x0, max_iter, deadline)
                         for x0 in x0s]).reshape(x0s.shape)
    batched = _BatchedSystem(sys)
    xs = np.array(x0s, dtype=float)
    live = np.ones(len(xs), dtype=bool)
    done = np.zeros(len(xs), dtype=bool)
    for _ in range(max_iter):
        idx = np.flatnonzero(live)
        if not len(idx) or deadline.expired():
            break
        g = batched.g(xs[idx])
        finite = np.all(np.isfinite(g), axis=1)
        conv = finite & (np.max(np.abs(g), axis=1) <= 1e-13)
        done[idx[conv]] = True
        live[idx[conv | ~finite]] = False
        step = finite & ~conv
        idx, g = idx[step], g[step]
        if len(idx):
            xs[idx] = xs[idx] - _min_norm_steps(batched.dg(xs[idx]), g)
    rest = np.flatnonzero(~done)
    if len(rest):
        g = batched.g(xs[rest])
        fine = np.all(np.isfinite(g), axis=1) & (np.max(np.abs(g), axis=1) <= 1e-12)
        for k in rest[~fine]:
            xs[k] = _least_squares_onto(sys, x0s[k], deadline)
    return xs


def _continue(
    sys: _System, x0: np.ndarray, t0: np.ndarray, box: np.ndarray, h_max: float, budget: int,
    deadline: Deadline = NEVER,
) -> tuple[list[np.ndarray], str]:
    """Follow ``G = 0`` from ``x0`` along ``t0`` until ``p`` leaves the box, the curve
    closes, or ``deadline`` passes (``"time"``)."""
    pts = [x0]
    x, t, h = x0, t0, 0.25 * h_max
    travelled = 0.0
    p0 = x0[-2:]
    passes = 0
    while len(pts) < budget:
        passes += 1
        if passes % 16 == 1 and deadline.expired():  # (the first pass too)
            return pts, REASON_TIME
        if h < 1e-9 * h_max:
            return pts, "step underflow"
        v = x + h * t
        w = _correct(sys, v, t)
        if w is None or np.linalg.norm(w - v) > 0.5 * h:
            h *= 0.5
            continue
        nt = _tangent(sys, w, t)
        if nt is None or nt @ t < 0.9:
            h *= 0.5
            continue
        pts.append(w)
        travelled += float(np.linalg.norm(w[-2:] - x[-2:]))
        p = w[-2:]
        if np.any(p < box[:, 0]) or np.any(p > box[:, 1]):
            return pts, "left the box"
        if travelled > 4 * h_max and np.linalg.norm(p - p0) < 0.5 * h_max and \
                np.linalg.norm(w - x0) < 2 * h_max:
            return pts, "closed"
        x, t = w, nt
        h = min(h_max, 1.5 * h)
    return pts, "budget"
