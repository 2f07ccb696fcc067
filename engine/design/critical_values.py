"""Slices of the critical value set in two lengths, and the regions they separate.

With two bar lengths ``p = (L_x, L_y)`` free, the critical configurations solve::

    G(u, sigma, p) = [ (l^2(u) - L(p)^2) / s ;  J(u)^T sigma / s ;  |sigma|^2 - 1 ] = 0

``E + M + 1`` equations in ``M + E + 2`` unknowns: a one-dimensional solution set whose
projection on ``p`` is the slice (paper, Sec. III B). It is traced by pseudo-arclength
continuation (tangent from one factorisation of ``[DG; tau_prev]``, hyperplane Newton corrector)
until it leaves the box or closes. Seeds: at a grid of sample lengths, every critical
configuration the exploration reaches (critical points, and the nearest critical
configurations of the near misses), projected onto ``G = 0`` from the sample lengths. The
boundaries where the configuration space becomes empty are critical values too (a component
shrinks to a rigid point) and are found the same way.

Regions: the box is rasterised at ``resolution``; cells crossed by a curve separate the rest,
which is split into 4-connected regions; each region is sampled at the cell farthest from every
curve and explored there: its number of components (0 where empty) and a ``signature``
(component count and the sorted rotor windings) tell topologies apart.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares

from engine.design.dyad_margin import critical_planes
from engine.local.critical import refine_critical
from engine.model.batched import BATCH_MAX_FREE, BatchedConstraints
from engine.model.budget import NEVER, REASON_TIME, Deadline, granted
from engine.model.constraints import Constraints
from engine.model.errors import InvalidRequest
from engine.model.hessian import DenseStressHessian, dense_stress_hessian
from engine.model.linkage import Linkage, changeable_bar
from engine.model.report import SearchReport
from engine.model.tolerances import CELL_EDGE_TOL, MIN_CRITICAL_LENGTH_ATOL, NORM_FLOOR, Tolerances
from engine.space.configuration_space import (
    SpaceOptions,
    explore,
    find_critical_points,
    rotor_angles,
    winding,
)

#: Where in its grid cell each seed length sits, per axis: irrational and different on the two
#: axes, so that the seed grid avoids the symmetric lengths (``L_x = L_y``, ...) on which
#: critical values of symmetric linkages lie (a seed at critical lengths is the slowest and least
#: robust exploration there is; its neighbours seed the same curves from regular lengths).
GRID_OFFSET = np.array([0.5 + (np.sqrt(2.0) - 1.0) / 10.0, 0.5 - (np.sqrt(5.0) - 2.0) / 10.0])

#: Point budget of one curve in a seed exploration.
SEED_MAX_POINTS = 2000

#: Methods of :func:`critical_value_slice`: ``"auto"`` draws the curves of one-dyad planar
#: chains (the four-bar family) from their closed-form critical lines and traces the rest;
#: ``"traced"`` always seeds and traces (the tests cross-check the two).
SLICE_METHODS = ("auto", "traced")


@dataclass(frozen=True)
class Axis:
    """A free length: bar index and its range."""

    bar: int
    lo: float
    hi: float


@dataclass(frozen=True)
class Region:
    point: tuple[float, float]
    components: int | None  # None: not explored before the deadline
    signature: str
    cells: int


@dataclass(frozen=True)
class Slice:
    curves: list[np.ndarray]  # each (n, 2)
    regions: list[Region]
    search: SearchReport


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


def _onto_solutions(sys: _System, x0: np.ndarray, max_iter: int = 30) -> np.ndarray:
    """A solution of ``G = 0`` near ``x0``: Gauss-Newton with minimum-norm steps (``G`` has two
    more unknowns than equations, so its solutions near a regular point form a curve and the
    iteration converges quadratically onto it); where that does not converge, least squares
    (trust region) from ``x0`` as before. Either way the caller checks ``|G| <= 1e-9``."""
    x = x0.copy()
    for _ in range(max_iter):
        g = sys.g(x)
        if not np.all(np.isfinite(g)):
            break
        if np.max(np.abs(g)) <= 1e-13:
            return x
        x = x - np.linalg.lstsq(sys.dg(x), g, rcond=None)[0]
    if np.all(np.isfinite(g := sys.g(x))) and np.max(np.abs(g)) <= 1e-12:
        return x
    sol = least_squares(sys.g, x0, jac=sys.dg, method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        max_nfev=200)
    return np.asarray(sol.x)


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


def _onto_solutions_batch(sys: _System, x0s: np.ndarray, max_iter: int = 30) -> np.ndarray:
    """:func:`_onto_solutions` from every row of ``x0s`` at once (small linkages): the same
    Gauss-Newton iteration with minimum-norm steps, the rows that converge leaving it, and the
    least-squares fallback of :func:`_onto_solutions` for every row that does not converge
    (the tests compare the two)."""
    if sys.m > BATCH_MAX_FREE or len(x0s) < 2:
        return np.array([_onto_solutions(sys, x0, max_iter) for x0 in x0s]).reshape(x0s.shape)
    batched = _BatchedSystem(sys)
    xs = np.array(x0s, dtype=float)
    live = np.ones(len(xs), dtype=bool)
    done = np.zeros(len(xs), dtype=bool)
    for _ in range(max_iter):
        idx = np.flatnonzero(live)
        if not len(idx):
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
            xs[k] = least_squares(sys.g, x0s[k], jac=sys.dg, method="trf", xtol=1e-15,
                                  ftol=1e-15, gtol=1e-15, max_nfev=200).x
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
        if passes % 16 == 0 and deadline.expired():
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


def _validate(linkage: Linkage, axes: list[tuple[str, float, float]]) -> tuple[Axis, Axis]:
    if len(axes) != 2:
        raise InvalidRequest("give exactly two axes", loc=("axes",))
    out = []
    for k, (bar, lo, hi) in enumerate(axes):
        j = changeable_bar(linkage, bar, ("axes", k, "bar"))
        if not (0 < lo < hi and np.isfinite(hi)):
            raise InvalidRequest("need 0 < min < max", loc=("axes", k))
        out.append(Axis(j, float(lo), float(hi)))
    if out[0].bar == out[1].bar:
        raise InvalidRequest("the two axes name the same bar", loc=("axes", 1, "bar"))
    return out[0], out[1]


def _signature(linkage: Linkage, lengths: np.ndarray, options: SpaceOptions,
               tol: Tolerances, deadline: Deadline = NEVER) -> tuple[int, str]:
    at = linkage.with_lengths(lengths)
    # the components only: no near misses (where the closed form or the chain rules certify
    # that there is no critical point, the critical-point search is then skipped)
    res = explore(at, tol, options, start_on_space=False, near_misses=False, deadline=deadline)
    patterns = set()
    for comp in res.components:
        angles = rotor_angles(at, comp.points)
        patterns.add(",".join(f"{b}:{abs(w) if (w := winding(a, comp.closed)) is not None else '?'}"
                              for b, a in angles.items()))
    count = len(res.components)
    complete = res.search.complete
    shown = f"{count}" if complete else f">={count} (search budget reached)"
    return count, f"components={shown}; turns={'|'.join(sorted(patterns))}"


def critical_value_slice(
    linkage: Linkage,
    axes: list[tuple[str, float, float]],
    resolution: int = 48,
    seeds_per_axis: int = 5,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    max_curve_points: int = 4000,
    deadline: Deadline | None = None,
    *,
    method: str = "auto",
) -> Slice:
    """Curves of the critical value set in the plane of two lengths, and its regions.

    Once ``deadline`` has passed the seeding and tracing stop, and regions not yet explored
    have ``components = None``; ``search["complete"]`` is then False with ``reason "time"``.

    ``method="auto"`` takes the curves of a one-dyad planar chain (the four-bar family) from
    its closed-form critical lines (:func:`engine.design.dyad_margin.critical_planes`), sampled at
    the
    tracing step; ``"traced"`` (and every other linkage) seeds and traces them.
    ``search["method"]`` says which (``"closed form"`` or ``"traced"``).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> s = critical_value_slice(build_preset("four-bar", {"L2": 1.2}),
    ...                          [("L2", 0.5, 1.5), ("L3", 0.5, 1.5)], resolution=16)
    >>> len(s.regions) >= 2
    True
    """
    if method not in SLICE_METHODS:
        raise InvalidRequest(f"unknown method {method!r}: one of {', '.join(SLICE_METHODS)}",
                             loc=("method",))
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions(angles=24, random_starts=4)
    dl = deadline or NEVER
    ax = _validate(linkage, axes)
    box = np.array([[ax[0].lo, ax[0].hi], [ax[1].lo, ax[1].hi]])
    span = box[:, 1] - box[:, 0]
    h_max = float(min(span)) / resolution
    lines = _closed_form_curves(linkage, ax, box, h_max, tol) if method == "auto" else None
    if lines is not None:
        raw, seeds, timed_out = lines, 0, False
        grid: list[np.ndarray] = []
    else:
        tracing = _CurveTracing(linkage, ax, box, h_max, tol, opt, max_curve_points, dl)
        grid = [box[:, 0] + span * (np.array([i, j]) + GRID_OFFSET) / seeds_per_axis
                for i in range(seeds_per_axis) for j in range(seeds_per_axis)]
        # One column of seed lengths at a time: the explorations first, then all their starts
        # onto G = 0 in one batch (a pure function of each start), then taken in seed order
        # (the same curves as seed by seed; a deadline still leaves the earlier columns' curves).
        for col in range(0, len(grid), seeds_per_axis):
            starts = []
            for k in range(col, min(col + seeds_per_axis, len(grid))):
                if dl.expired():
                    tracing.timed_out = True
                    break
                dl.report(0.6 * k / len(grid), "critical values: tracing the curves")
                starts.append(tracing.starts_at(grid[k]))
            tracing.take(starts)
            if tracing.timed_out and dl.expired():
                break
        raw = [_clip(c[:, -2:], box) for c in tracing.curves]
        seeds, timed_out = tracing.seeds_tried, tracing.timed_out
    curves = _merge_coincident([c for c in raw if len(c) >= 2], 1e-7 * float(max(span)))
    regions = _regions(linkage, ax, box, curves, resolution, opt, tol, dl)
    timed_out = timed_out or any(r.components is None for r in regions)
    search = SearchReport({
        "method": "closed form" if lines is not None else "traced",
        "seed_lengths": len(grid),
        "seed_configurations": seeds,
        "curves": len(curves),
        "step": h_max,
        "resolution": resolution,
        "regions_explored": sum(r.components is not None for r in regions),
    }, timed_out=timed_out, time_budget_s=granted(dl))
    return Slice(curves, regions, search)


def _closed_form_curves(
    linkage: Linkage, ax: tuple[Axis, Axis], box: np.ndarray, step: float, tol: Tolerances,
) -> list[np.ndarray] | None:
    """The slice's curves of a one-dyad planar chain: every critical hyperplane
    ``n . (r, ra, rb) = D`` of :func:`engine.design.dyad_margin.critical_planes` met with the plane
    of
    the two axes (the other length as given) is a line; its piece inside the box (lengths at
    least the shortest critical bar) sampled at most ``step`` apart. None when the linkage is
    not such a chain or an axis is none of its three bars."""
    found = critical_planes(linkage)
    if found is None:
        return None
    _, pl = found
    cols = [np.flatnonzero(pl.bars == a.bar) for a in ax]
    if any(len(c) != 1 for c in cols):
        return None
    i, j = int(cols[0][0]), int(cols[1][0])
    k = 3 - i - j  # the third bar keeps its length
    other = float(linkage.lengths[pl.bars[k]])
    shortest = MIN_CRITICAL_LENGTH_ATOL * tol.residual_atol
    lo = np.maximum(box[:, 0], shortest)
    curves = []
    for normal in pl.normals:  # at most 8 planes
        if normal[k] != 0 and other < shortest:
            continue  # the third bar would be degenerate: no critical configuration there
        n = normal[[i, j]]
        # the line n . p = c, as p0 + t d with |d| = 1, cut to the box (slab by slab)
        c = pl.dist - normal[k] * other
        p0 = n * c / float(n @ n)
        d = np.array([-n[1], n[0]]) / float(np.hypot(*n))
        t_lo, t_hi = -np.inf, np.inf
        for m in range(2):  # the two axes of the box
            if d[m] == 0.0:
                if not lo[m] <= p0[m] <= box[m, 1]:
                    t_lo, t_hi = np.inf, -np.inf
                continue
            ta, tb = sorted(((lo[m] - p0[m]) / d[m], (box[m, 1] - p0[m]) / d[m]))
            t_lo, t_hi = max(t_lo, ta), min(t_hi, tb)
        if not t_hi > t_lo:
            continue
        t = np.linspace(t_lo, t_hi, int(np.ceil((t_hi - t_lo) / step)) + 1)
        curves.append(np.clip(p0[None, :] + t[:, None] * d[None, :], lo, box[:, 1]))
    return curves


class _CurveTracing:
    """The curves of a slice traced so far (in ``(u, sigma, p)`` space), and how they are
    seeded: from the critical points and near misses of a seed's lengths, each moved onto the
    solution set ``G = 0`` and followed both ways unless a curve already traced has it."""

    def __init__(self, linkage: Linkage, ax: tuple[Axis, Axis], box: np.ndarray, h_max: float,
                 tol: Tolerances, opt: SpaceOptions, max_curve_points: int,
                 deadline: Deadline) -> None:
        self.linkage, self.ax, self.box, self.h_max = linkage, ax, box, h_max
        self.tol, self.max_curve_points, self.deadline = tol, max_curve_points, deadline
        self.sys = _System(linkage, ax)
        self.span = float(max(box[:, 1] - box[:, 0]))
        self.curves: list[np.ndarray] = []
        self.seeds_tried = self.seeds_used = 0
        self.timed_out = False
        # A seed exploration need not be complete (it only has to reach critical configurations
        # near its lengths), so its curves get a point budget: one that fails to close (as near
        # a branch point at critical lengths) must not cost a full trace budget.
        self.seed_opt = replace(
            opt, max_components=min(opt.max_components, 8), near_misses_closed_form=True,
            trace=replace(opt.trace, max_points=min(opt.trace.max_points, SEED_MAX_POINTS)),
        )

    def known(self, x: np.ndarray) -> bool:
        """The seed's lengths lie on a curve already traced (other assemblies of the same
        critical sheet project onto the same curve of the slice)."""
        p = x[-2:][None, :]
        return any(_polyline_distance(p, c[:, -2:])[0] <= 1e-7 * self.span for c in self.curves)

    def starts_at(self, p0: np.ndarray) -> np.ndarray:
        """The starts (K, M + E + 2) of the seed lengths ``p0``: every critical point (refined,
        with its stress) and near miss that the exploration at ``p0`` reaches, at ``p0``."""
        lengths = self.linkage.lengths.copy()
        lengths[self.ax[0].bar], lengths[self.ax[1].bar] = p0
        at = self.linkage.with_lengths(lengths)
        # Only the critical configurations are needed here: no segments, no components.
        res = find_critical_points(at, self.tol, self.seed_opt, start_on_space=False,
                                   deadline=self.deadline)
        cons = Constraints(at)
        starts: list[np.ndarray] = []
        found: list[tuple[np.ndarray, np.ndarray | None]] = (
            [(cp.u, None) for cp in res.critical_points]
            + [(m.critical_u, m.critical_sigma) for m in res.near_misses]
        )
        for u0, s0 in found:
            if s0 is None:  # (a near miss's configuration is refined already, with its stress)
                ref = refine_critical(cons, u0, self.tol)
                u0, s0 = ref.u, ref.sigma
            starts.append(np.concatenate([u0, s0, p0]))
        return np.array(starts, dtype=float).reshape(-1, self.sys.n)

    def take(self, starts: list[np.ndarray]) -> None:
        """Every new curve through the starts of some seed lengths (:meth:`starts_at`, one
        array per seed, in seed order): all of them moved onto ``G = 0`` at once, then each
        followed unless a curve traced before it (from this or an earlier seed) has it."""
        if not starts or not sum(len(s) for s in starts):
            return
        xs = _onto_solutions_batch(self.sys, np.concatenate(starts))
        for x in xs:
            self.seeds_tried += 1
            if np.max(np.abs(self.sys.g(x))) > 1e-9 or self.known(x):
                continue
            if np.any(x[-2:] < self.box[:, 0] - self.h_max) or \
                    np.any(x[-2:] > self.box[:, 1] + self.h_max):
                continue
            self.seeds_used += 1
            self.follow(x)

    def follow(self, x: np.ndarray) -> None:
        """The curve through ``x``, both ways (closed: once round)."""
        t = _tangent(self.sys, x, np.random.default_rng(self.seeds_used).normal(size=self.sys.n))
        if t is None:
            return
        args = (self.box, self.h_max, self.max_curve_points, self.deadline)
        fwd, stop_f = _continue(self.sys, x, t, *args)
        if stop_f == "closed":
            self.curves.append(np.array(fwd + [fwd[0]]))
            return
        back, stop_b = _continue(self.sys, x, -t, *args)
        self.curves.append(np.array(back[::-1] + fwd[1:]))
        self.timed_out = self.timed_out or REASON_TIME in (stop_f, stop_b)


def _polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of each point (n, 2) to the polyline ``line`` (m, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), NORM_FLOOR)
    rel = points[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("kij,ij->ki", rel, ab) / denom, 0.0, 1.0)
    foot = a[None, :, :] + s[:, :, None] * ab[None, :, :]
    return np.min(np.linalg.norm(points[:, None, :] - foot, axis=2), axis=1)


def _merge_coincident(curves: list[np.ndarray], atol: float) -> list[np.ndarray]:
    """Drop a curve lying on another one: two sheets of the critical value set can project onto
    the same line of the slice (a self-intersection of the set); the slice draws it once."""
    kept: list[np.ndarray] = []
    for c in sorted(curves, key=len, reverse=True):
        if not any(np.all(_polyline_distance(c, k) <= atol) for k in kept):
            kept.append(c)
    return kept


def _clip(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """The part of a polyline inside the box, cut exactly where it crosses the boundary (the
    crossing point is interpolated on the segment that crosses; the traced curve ends one
    step outside the box)."""
    lo, hi = box[:, 0], box[:, 1]

    def inside(q: np.ndarray) -> bool:
        return bool(np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12))

    def crossing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        # largest s in [0, 1] keeping a + s (b - a) in the box (a inside)
        s = 1.0
        d = b - a
        for k in range(2):
            if d[k] > 0:
                s = min(s, (hi[k] - a[k]) / d[k])
            elif d[k] < 0:
                s = min(s, (lo[k] - a[k]) / d[k])
        return a + max(s, 0.0) * d

    out: list[np.ndarray] = []
    for k, q in enumerate(points):
        if inside(q):
            if k > 0 and not inside(points[k - 1]) and not out:
                out.append(crossing(q, points[k - 1]))
            out.append(q)
        elif out and inside(points[k - 1]):
            out.append(crossing(points[k - 1], q))
            break
    return np.array(out).reshape(-1, 2)


def _blocked_cells(curves: list[np.ndarray], box: np.ndarray, n: int) -> np.ndarray:
    """The (n, n) raster cells the curves cross: every segment sampled at a quarter of a cell
    (``steps + 1`` points ``a + s (b - a)``, ``s = 0, 1/steps, .., 1``), all segments at once;
    a sample on a cell's edge (within ``CELL_EDGE_TOL`` cells) blocks the cells on both sides."""
    blocked = np.zeros((n, n), dtype=bool)
    if not curves:
        return blocked
    span = box[:, 1] - box[:, 0]
    a = np.concatenate([c[:-1] for c in curves])  # (S, 2) segment starts
    b = np.concatenate([c[1:] for c in curves])
    steps = (np.ceil(4 * np.max(np.abs(b - a) / span, axis=1) * n)).astype(int) + 1  # (S,)
    seg = np.repeat(np.arange(len(a)), steps + 1)
    first = np.concatenate([[0], np.cumsum(steps + 1)[:-1]])
    s = (np.arange(len(seg)) - first[seg]) / steps[seg]  # (N,) in [0, 1] per segment
    q = (a[seg] + s[:, None] * (b[seg] - a[seg]) - box[:, 0]) / span * n
    # a sample within CELL_EDGE_TOL of a cell's edge blocks the cells on both sides (at a
    # corner all four): no cell depends on how the sample was rounded
    lo = np.clip(np.floor(q - CELL_EDGE_TOL).astype(int), 0, n - 1)
    hi = np.clip(np.floor(q + CELL_EDGE_TOL).astype(int), 0, n - 1)
    for i in (lo[:, 0], hi[:, 0]):
        for j in (lo[:, 1], hi[:, 1]):
            blocked[i, j] = True
    return blocked


def _regions(
    linkage: Linkage,
    ax: tuple[Axis, Axis],
    box: np.ndarray,
    curves: list[np.ndarray],
    resolution: int,
    opt: SpaceOptions,
    tol: Tolerances,
    deadline: Deadline = NEVER,
) -> list[Region]:
    n = resolution
    span = box[:, 1] - box[:, 0]
    blocked = _blocked_cells(curves, box, n)
    labels, count = ndimage.label(~blocked)
    dist = ndimage.distance_transform_edt(~blocked)
    out = []
    for k in range(1, count + 1):
        cells = labels == k
        idx = np.unravel_index(int(np.argmax(np.where(cells, dist, -1))), cells.shape)
        point = box[:, 0] + span * (np.array(idx) + 0.5) / n
        lengths = linkage.lengths.copy()
        lengths[ax[0].bar], lengths[ax[1].bar] = point
        where = (float(point[0]), float(point[1]))
        if deadline.expired():
            out.append(Region(where, None, "not explored (time)", int(cells.sum())))
            continue
        deadline.report(0.6 + 0.4 * k / count, "critical values: exploring the regions")
        comps, sig = _signature(linkage, lengths, opt, tol, deadline)
        out.append(Region(where, comps, sig, int(cells.sum())))
    return out
