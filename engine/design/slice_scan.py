"""Every critical value on a scanline of a slice, by homotopy (for :mod:`.critical_values`).

On a scanline one axis is held at a value ``v`` and the other length ``L_y`` is free. A
configuration ``u`` is critical at lengths ``(v, L_y)`` exactly when ``L_y = l_y(u)`` and the
full Jacobian ``J(u)`` (all ``E`` bars, bar ``y`` included) has rank below ``E``, i.e. its
tangent form ``t(u)`` (the ``M = E + 1`` maximal minors) vanishes. Without bar ``y`` the
linkage has two degrees of freedom; on that space the critical configurations are the
isolated solutions of the square system::

    f_a(u) = l_a^2(u) - L_a^2 = 0  (a != y),    det [J(u); c_1] = 0,    det [J(u); c_2] = 0

for random directions ``c_1, c_2`` (``det [J; c] = c . t``): ``E - 1`` quadrics and two
determinants of degree ``E`` in ``M`` unknowns. Every critical configuration solves it (``t = 0``);
at a non-degenerate critical point of ``l_y`` on the two-dimensional space (a branch point is
a saddle, a rigid point where a component is born or dies is an extremum) it is a simple
solution, since ``(c_1 . t, c_2 . t)`` is then a generic projection of a map that vanishes
transversally. The other solutions (``t != 0`` orthogonal to ``c_1`` and ``c_2``) are dropped by
the rank of ``J``. All isolated solutions are found by the total-degree homotopy of
:mod:`engine.space.homotopy` (``2^(E-1) E^2`` paths: 36 for the four-bar, 400 for the
three-rotor), so the critical values on the scanline are complete when every path ended and
the two-degree-of-freedom space is bounded.

A curve of the slice that crosses the scanline meets one of these configurations; the slice
seeds its tracing from all of them (:class:`ScanDirection`: one homotopy per axis, then a
parameter homotopy to each edge of the box, and a sweep between them that reports where a
curve turns or enters the box).

>>> from engine.catalogue.presets import build_preset
>>> lk = build_preset("four-bar", {"L2": 1.2})
>>> scan = ScanDirection(lk, free_bar=2, held_bar=1, fixed=0, mid=1.2, free_hi=4.0)
>>> line = scan.at_value(1.2)
>>> line.success, sorted({round(float(v), 6) for v in line.starts[:, -1] if v > 1e-6})
(True, [0.8, 1.2, 3.2])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.space.homotopy import H_MAX, REGULAR, SINGULAR, track
from engine.space.parameter_homotopy import Parameter, follow
from engine.space.witnesses import FAR_REACH, REAL_TOL, SINGULAR_IMAG_TOL, _reach

#: ``sigma_min / sigma_max`` of ``J`` below which a real regular solution is a critical
#: configuration (a solution with ``t != 0`` has a full-rank ``J``).
CRITICAL_RTOL = 1e-6
#: The same for singular ends (within about ``sqrt(T_END)`` of their solution).
SINGULAR_RTOL = 1e-3
#: A sweep's path is bent off the real lengths by this (relative to its span of squared
#: lengths), and a solution on it within ``SWEEP_REAL_TOL`` (relative) of the reals is real:
#: off a meeting point of two real solutions by ``d``, a real one is about ``b / sqrt(d)`` off.
SWEEP_BUMP = 1e-5
SWEEP_REAL_TOL = 1e-3


@dataclass(frozen=True)
class Scanline:
    """The critical configurations on one scanline.

    Attributes
    ----------
    fixed : int
        The axis held (0 or 1); the other is free.
    value : float
        The held axis's length.
    starts : (K, M + E + 2) float
        ``(u, sigma, p)`` at each critical configuration found (``p`` in the slice's axis order,
        the free length ``l_y(u)``), for :func:`engine.design.slice_curves._onto_solutions`.
    paths : int
        Paths of the homotopy (0: not run).
    success : bool
        Every path ended, none jumped, the deadline kept, the space bounded: ``starts`` holds
        every critical configuration of the scanline.
    message : str
    """

    fixed: int
    value: float
    starts: np.ndarray
    paths: int
    success: bool
    message: str


def scan_paths(linkage: Linkage) -> int:
    """The paths of one scanline's homotopy, ``2^(E-1) E^2`` (``E`` bars with a free end)."""
    e = Constraints(linkage).n_constraints
    return int(2 ** (e - 1) * e * e)


def _bounded_without(linkage: Linkage, cons: Constraints, row: int | list[int]) -> bool:
    """Every piece of the graph of the active bars but row(s) ``row`` holds a pinned vertex."""
    v = linkage.n_vertices
    ends = np.delete(linkage.ends[cons.bars], row, axis=0)
    graph = coo_matrix((np.ones(len(ends)), (ends[:, 0], ends[:, 1])), shape=(v, v))
    _, label = connected_components(graph, directed=False)
    pinned = np.asarray(linkage.fixed, dtype=bool).all(axis=1)
    anchored = np.zeros(label.max() + 1, dtype=bool)
    anchored[label[pinned]] = True
    moving = np.unique(linkage.ends[cons.bars].ravel())
    return bool(anchored[label[moving]].all())


def _det_adjugate(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Determinants (N,) and adjugates (N, M, M) of a stack: ``det * inv`` where the inverse
    exists, from the SVD for the rows where it does not (``adj = det(V^H) det(U)
    V diag(prod_{j != i} s_j) U^H``), those rows alone."""
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        det = np.linalg.det(a)
        try:
            adj = det[:, None, None] * np.linalg.inv(a)
            bad = ~np.isfinite(adj).all(axis=(1, 2))
        except np.linalg.LinAlgError:
            adj = np.full_like(a, np.nan)
            bad = np.ones(len(a), dtype=bool)
    rows = np.flatnonzero(bad & np.isfinite(a).all(axis=(1, 2)))
    if len(rows):
        u, s, vh = np.linalg.svd(a[rows])
        m = s.shape[1]
        others = np.stack([np.prod(np.delete(s, i, axis=1), axis=1) for i in range(m)], axis=1)
        phase = np.linalg.det(vh) * np.linalg.det(u)
        adj[rows] = phase[:, None, None] * np.matmul(
            np.conj(np.transpose(vh, (0, 2, 1))) * others[:, None, :],
            np.conj(np.transpose(u, (0, 2, 1))))
    return det, adj


class ScanSystem:
    """``[f_a (a != free); det [J; c_1]; det [J; c_2]]`` in homogeneous, scaled coordinates
    ``X = (x_0, y)``, ``u = centre + scale * y / x_0`` (as :class:`engine.space.witnesses.
    LinkageSystem`)."""

    def __init__(self, linkage: Linkage, cons: Constraints, free: int, held: int,
                 c: np.ndarray) -> None:
        lk = linkage
        d, m = lk.dimension, cons.n_free
        pos = np.asarray(lk.positions, dtype=float)
        self.scale = float(np.median(lk.lengths[cons.bars]))
        centroid = pos.mean(axis=0)
        scaled = (pos - centroid) / self.scale
        fi = lk.free_index  # (V, d), -1 where fixed
        self.centre = np.zeros(m)
        self.centre[fi[fi >= 0]] = np.broadcast_to(centroid, fi.shape)[fi >= 0]
        ends = lk.ends[cons.bars]
        e = len(ends)
        diff = np.zeros((e, d, m + 1))  # coordinate differences as linear forms in X
        for side, sign in ((0, 1.0), (1, -1.0)):
            v = ends[:, side]
            idx = fi[v]
            free_c = idx >= 0
            a_idx, k_idx = np.nonzero(free_c)
            diff[a_idx, k_idx, 1 + idx[free_c]] += sign
            a_fix, k_fix = np.nonzero(~free_c)
            diff[a_fix, k_fix, 0] += sign * scaled[v[a_fix], k_fix]
        quad = np.einsum("akm,akn->amn", diff, diff)  # (E, M + 1, M + 1)
        quad[:, 0, 0] -= (lk.lengths[cons.bars] / self.scale) ** 2
        self.quad = quad
        self.keep = np.delete(np.arange(e), free)  # the equations' bars
        self.c = np.asarray(c, dtype=float) / np.linalg.norm(c, axis=1, keepdims=True)  # (2, M)
        self.e, self.n = e, m
        self._rows = quad.reshape(-1, m + 1)  # (E (M + 1), M + 1)
        self._cols = quad[:, 1:, :].reshape(-1, m + 1)  # (E M, M + 1)
        self.degrees = np.array([2] * (e - 1) + [e, e], dtype=int)
        # the held bar's squared length w = L^2 enters its equation as - w x_0^2 / scale^2
        self.held = int(np.flatnonzero(self.keep == held)[0])
        self.w_ref = float(lk.lengths[cons.bars[held]]) ** 2
        self.w: complex | np.ndarray = self.w_ref

    def dw(self, x: np.ndarray) -> np.ndarray:
        """``dF / dw`` (N, M) at ``x`` (N, M + 1)."""
        out = np.zeros((len(x), self.n), dtype=complex)
        out[:, self.held] = -x[:, 0] ** 2 / self.scale**2
        return out

    def __call__(self, x: np.ndarray, w: complex | np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Values (N, M) and Jacobians (N, M, M + 1) at ``x`` (N, M + 1), the held bar's
        squared length ``w`` (scalar or (N,); default ``self.w``)."""
        p, m, e = len(x), self.n, self.e
        grads = 2.0 * (self._rows @ x.T).T.reshape(p, e, m + 1)  # (N, E, M + 1)
        qv = 0.5 * np.einsum("pam,pm->pa", grads[:, self.keep], x)
        values = np.empty((p, m), dtype=complex)
        jac = np.empty((p, m, m + 1), dtype=complex)
        values[:, :e - 1] = qv
        jac[:, :e - 1] = grads[:, self.keep]
        shift = -(np.asarray(self.w if w is None else w) - self.w_ref) / self.scale**2
        values[:, self.held] += shift * x[:, 0] ** 2
        jac[:, self.held, 0] += 2.0 * shift * x[:, 0]
        rows = np.empty((p, m, m), dtype=complex)  # [J; c]
        rows[:, :e] = grads[:, :, 1:]
        for k in range(2):
            rows[:, m - 1] = self.c[k]
            det, adj = _det_adjugate(rows)
            values[:, e - 1 + k] = det
            # d det / dX = sum over rows a, columns j: adj[j, a] * 2 Q_a[1 + j, :]
            jac[:, e - 1 + k] = 2.0 * adj[:, :, :e].transpose(0, 2, 1).reshape(p, e * m) \
                @ self._cols
        return values, jac


class ScanDirection:
    """The scanlines of one direction: bar ``free_bar`` free, bar ``held_bar`` held at each
    value. The system is solved once, by the total-degree homotopy, at a random complex
    squared length ``w_0`` of the held bar (a generic parameter); each scanline then follows
    those solutions to its own ``w_1 = value^2`` along the segment from ``w_0`` (a parameter
    homotopy: for a generic ``w_0`` the segment misses the finitely many parameters where
    solutions meet, so every isolated solution at ``w_1`` is the end of one of these paths;
    Sommese and Wampler 2005, Thm. 7.1.6). A path costs the same either way; the finite
    solutions are about a quarter of the paths (90 of 400 for the three-rotor)."""

    def __init__(self, linkage: Linkage, free_bar: int, held_bar: int, fixed: int,
                 mid: float, free_hi: float, seed: int = 0,
                 deadline: Deadline = NEVER) -> None:
        lengths = np.array(linkage.lengths, dtype=float)
        lengths[held_bar] = mid
        lengths[free_bar] = free_hi  # (a bound for the reach only: the system leaves it out)
        self.at = at = linkage.with_lengths(lengths)
        self.cons = cons = Constraints(at)
        bars = [int(b) for b in cons.bars]
        self.free_bar, self.fixed = free_bar, fixed
        m, e = cons.n_free, cons.n_constraints
        self.starts = np.zeros((0, m + 1), dtype=complex)
        self.paths, self.success = 0, False
        if m - e != 1:
            self.message = "needs M - E = 1"
            return
        if not _bounded_without(at, cons, bars.index(free_bar)):
            self.message = "without the free bar a piece of the linkage holds no pinned vertex"
            return
        rng = np.random.default_rng(seed)
        self.system = ScanSystem(at, cons, bars.index(free_bar), bars.index(held_bar),
                                 rng.normal(size=(2, m)))
        self.reach = _reach(at, cons, self.system.scale)
        self.w0 = complex(mid**2 * (1.0 + 0.5 * np.exp(2j * np.pi * rng.random())))
        self.system.w = self.w0
        # (paths beyond FAR_REACH times every real configuration late in the homotopy are
        # gone to infinity, as in engine.space.witnesses: the three-rotor's 76 regular ends lie
        # within 1.2 times that reach, its singular and far ends beyond 69 times)
        res = track(self.system, self.system.degrees, rng, deadline,
                    far=FAR_REACH * self.reach)
        self.patch = rng.normal(size=m + 1) + 1j * rng.normal(size=m + 1)
        self.patch /= np.linalg.norm(self.patch)
        ends = res.ends[(res.state == REGULAR) & (np.abs(res.ends[:, 0]) > 0)]
        self.starts = ends / (ends @ self.patch)[:, None]
        self.paths, self.success, self.message = res.ends.shape[0], res.success, res.message

    def _ends(self, w: complex, deadline: Deadline) -> tuple[np.ndarray, np.ndarray, str]:
        """Every finite solution at the held squared length ``w`` (from the generic ones)."""
        hom = Parameter(self.system, self.w0, w, self.patch)
        return follow(hom, self.starts, deadline)

    def _critical(self, ends: np.ndarray, loose: np.ndarray, held: np.ndarray,
                  real_tol: float = REAL_TOL) -> tuple[np.ndarray, np.ndarray]:
        """``(u, sigma, p)`` (K, M + E + 2) of the ends (N, M + 1) that are real (``loose``:
        within ``SINGULAR_IMAG_TOL``), in reach and critical (``J`` loses rank), the held
        length of each end ``held`` (N,), and which ends they are (K,)."""
        m, e = self.cons.n_free, self.cons.n_constraints
        x0 = ends[:, 0]
        y = ends[:, 1:] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
        size = np.linalg.norm(y, axis=1)
        near = np.isfinite(size) & (size <= self.reach) & (np.abs(x0) > 0)
        imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
        real = near & (imag <= np.where(loose, SINGULAR_IMAG_TOL, real_tol))
        sys_ = self.system
        starts, which = [], []
        for k in np.flatnonzero(real):
            u = sys_.centre + sys_.scale * y[k].real
            jac = self.cons.jacobian(u, sparse=False)  # (E, M)
            left, sv, _ = np.linalg.svd(jac)
            if sv[-1] > (SINGULAR_RTOL if loose[k] else CRITICAL_RTOL) * max(sv[0], 1e-300):
                continue  # t != 0: not critical
            ends_xy = self.at.positions_of(u)[self.at.ends[self.free_bar]]
            p = np.empty(2)
            p[self.fixed] = held[k]
            p[1 - self.fixed] = float(np.linalg.norm(ends_xy[0] - ends_xy[1]))
            starts.append(np.concatenate([u, left[:, -1], p]))
            which.append(k)
        return np.array(starts, dtype=float).reshape(-1, m + e + 2), np.array(which, dtype=int)

    def at_value(self, value: float, deadline: Deadline = NEVER) -> Scanline:
        """Every critical configuration with the held bar at ``value``."""
        m, e = self.cons.n_free, self.cons.n_constraints
        if not self.success:
            return Scanline(self.fixed, value, np.zeros((0, m + e + 2)), self.paths, False,
                            f"the generic system: {self.message}")
        ends, state, message = self._ends(value**2, deadline)
        done = np.isin(state, (REGULAR, SINGULAR))
        out, _ = self._critical(ends[done], (state == SINGULAR)[done],
                                np.full(int(done.sum()), value))
        return Scanline(self.fixed, value, out, self.paths, not message,
                        message or "every path ended")

    def sweep(self, lo: float, hi: float, free_lo: float, free_hi: float, step: float,
              deadline: Deadline = NEVER) -> Scanline:
        """The critical configurations where a curve of the slice turns between the held
        lengths ``lo`` and ``hi``, or enters the free range ``[free_lo, free_hi]``: every
        solution at ``lo`` followed along the real lengths to ``hi`` (bent off them by
        ``SWEEP_BUMP``) in steps of at most ``step`` of the held length, and the point of each
        step where a solution turns critical, real and in range, or the last before it stops
        being so (a curve born, or entering the box, between two steps is caught; one born and
        gone within one step is not); with every critical configuration at ``lo`` and at
        ``hi`` (the edges: :meth:`at_value` there)."""
        m, e = self.cons.n_free, self.cons.n_constraints
        empty = np.zeros((0, m + e + 2))
        if not self.success:
            return Scanline(self.fixed, lo, empty, self.paths, False,
                            f"the generic system: {self.message}")
        ends, state, message = self._ends(lo**2, deadline)
        if message:
            return Scanline(self.fixed, lo, empty, self.paths, False, f"at {lo:.6g}: {message}")
        done = np.isin(state, (REGULAR, SINGULAR))
        found = [self._critical(ends[done], (state == SINGULAR)[done],
                                np.full(int(done.sum()), lo))[0]]
        # the sweep starts just off the edge, where no two solutions meet (at the edge itself
        # some may: a singular end cannot be followed on)
        span = abs(hi**2 - lo**2)
        start = lo**2 + 1j * SWEEP_BUMP * span
        x, state, message = self._ends(start, deadline)
        stuck = (state == SINGULAR) & self._rank_deficient(x)
        if message or stuck.any():
            return Scanline(self.fixed, lo, np.concatenate(found), self.paths, False,
                            f"just off {lo:.6g}: " + (message or "a singular critical solution"))
        # (a singular end where J has full rank is no critical configuration, t != 0: the
        # critical ones are simple solutions and are followed on their own paths)
        x = x[state == REGULAR]
        hom = Parameter(self.system, start, hi**2, self.patch, SWEEP_BUMP * span)
        status = self._status(x, np.full(len(x), lo), free_lo, free_hi)
        last = x.copy()
        times = np.ones(len(x))  # each path's t at its last step

        def watch(paths: np.ndarray, points: np.ndarray, t: np.ndarray) -> None:
            held = np.sqrt(np.maximum(hom.w(t).real, 0.0))
            now = self._status(points, held, free_lo, free_hi)
            born = now & ~status[paths]
            gone = ~now & status[paths]
            if born.any():
                found.append(self._critical(points[born], np.ones(born.sum(), dtype=bool),
                                            held[born], SWEEP_REAL_TOL)[0])
            if gone.any():
                before = np.sqrt(np.maximum(hom.w(times[paths[gone]]).real, 0.0))
                found.append(self._critical(last[paths[gone]], np.ones(gone.sum(), dtype=bool),
                                            before, SWEEP_REAL_TOL)[0])
            status[paths] = now
            last[paths] = points
            times[paths] = t

        h = step / max(abs(hi - lo), 1e-300) * 2.0 * min(lo, hi) / (lo + hi)
        ends, state, swept = follow(hom, x, deadline, h_max=min(H_MAX, h), watch=watch)
        done = np.isin(state, (REGULAR, SINGULAR))  # (the path ends on the reals, at hi)
        found.append(self._critical(ends[done], (state == SINGULAR)[done],
                                    np.full(int(done.sum()), hi))[0])
        message = "; ".join(m for m in (message, swept) if m)
        return Scanline(self.fixed, lo, np.concatenate(found), self.paths, not message,
                        message or "every path ended")

    def _rank_deficient(self, points: np.ndarray) -> np.ndarray:
        """Which points (N, M + 1), complex, have ``J`` (E, M) of rank below ``E`` (within
        ``SINGULAR_RTOL``): the critical ones."""
        sys_ = self.system
        grads = 2.0 * (sys_._rows @ points.T).T.reshape(len(points), sys_.e, sys_.n + 1)
        sv = np.linalg.svd(grads[:, :, 1:] / points[:, :1, None], compute_uv=False)
        return np.asarray(sv[:, -1] <= SINGULAR_RTOL * sv[:, 0])

    def _status(self, points: np.ndarray, held: np.ndarray, free_lo: float,
                free_hi: float) -> np.ndarray:
        """Which points (N, M + 1) are real (within ``SWEEP_REAL_TOL``), in reach, critical and
        with the free length in ``[free_lo, free_hi]``."""
        out = np.zeros(len(points), dtype=bool)
        crit, which = self._critical(points, np.ones(len(points), dtype=bool), held,
                                     SWEEP_REAL_TOL)
        free = crit[:, -2 + (1 - self.fixed)]
        out[which] = (free >= free_lo) & (free <= free_hi)
        return out


@dataclass(frozen=True)
class Scan:
    """The sweeps of a slice: which were solved completely, and the starts they give."""

    lines: list[Scanline]
    planned: int
    paths: int
    message: str
    step: float  # the sweep's longest step in the held length
    @property
    def complete(self) -> bool:
        """Every planned sweep ran, each with every critical configuration it looks for."""
        return bool(self.lines) and len(self.lines) == self.planned and \
            all(s.success for s in self.lines)

    def summary(self) -> str:
        """What the sweeps prove, in a sentence."""
        if not self.paths:
            return f"no scanline solved ({self.message})"
        done = sum(s.success for s in self.lines)
        return (f"{done} of {self.planned} sweeps (an axis's two edges of the box and the "
                f"lengths between) solved completely (a {self.paths}-path homotopy, its finite "
                "solutions followed)" + ("" if done == self.planned else f": {self.message}"))
