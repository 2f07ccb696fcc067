"""A point on every compact component, and every critical point, of a one-degree-of-freedom
linkage: the real solutions of one square polynomial system, all found by homotopy continuation.

The argument (the answers' ``search.argument = "proved"``). Let ``C = {u : f(u) = 0}`` be the
configuration space (``f_a = l_a^2 - L_a^2``, ``M = E + 1`` free coordinates) and ``c`` a
generic direction. On a compact component ``K`` of ``C`` the height ``c . u`` has a maximum.
Where ``K`` is smooth there, ``c`` is normal to ``K``: ``c`` lies in the row space of ``J``, so
``det [J(u); c] = 0``; where ``K`` is not smooth, ``J`` loses rank (a critical point) and the
determinant vanishes as well. So every compact component holds a real solution of::

    f(u) = 0,    det [J(u); c] = 0        (M equations in M unknowns)

and every critical point of the linkage is one (``det [J; c] = c . t(u)`` with ``t`` the
tangent form of the paper, which vanishes exactly at critical points). The system is square,
of degrees 2 (each bar) and ``E`` (the determinant); its isolated solutions are all found by
the total-degree homotopy of :mod:`engine.space.homotopy`. Critical points are singular
solutions; the extrema at smooth points are regular ones.

The path count is cut down without changing the solution set: two bars from one vertex to two
pinned vertices (a hinge in 3D) differ by a *linear* equation (their quadratic parts cancel), so
the quadrics are replaced by as few as their quadratic parts need (a left null space of the
quadratic parts, computed once) and linear equations; the determinant's degree is then the
number of quadrics ``r``, and the paths number ``2^r r``: 24 for the four-bar, 160 for the
three-rotor and for a 3D chain of three hinged rotors.

The argument needs the configuration space bounded (every connected piece of the bar graph
holds a vertex pinned in every coordinate) and every path ended (none failed, none jumped); the
caller also refines every singular end near the reals and traces from every real regular end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import count_text
from engine.space.homotopy import FAR, REGULAR, SINGULAR, track

#: Largest number of paths tracked (``2^r r``, ``r`` quadrics; 160 for ``r = 5``, 896 for
#: ``r = 7``, 2048 for ``r = 8``): a path costs about 5-10 ms of one core (more under load), so
#: 512 keeps the homotopy near a second; a caller may ask for more (``homotopy_paths_max``).
PATHS_MAX = 512
#: Relative size of the imaginary part below which a regular end is real.
REAL_TOL = 1e-6
#: Relative size of the imaginary part below which a singular end is refined as a possible
#: critical point (a singular end is within about ``sqrt(T_END)`` of its solution).
SINGULAR_IMAG_TOL = 1e-3
#: Paths whose affine point is this many times beyond every reachable configuration near the
#: end of the homotopy are gone towards infinity (``homotopy.T_FAR``).
FAR_REACH = 1e2
#: Singular values of the quadratic parts below this (relative) make a combination linear.
LINEAR_RTOL = 1e-10
#: Floating-point operations per second assumed of the system's set-up (the SVD of the
#: (E, M^2) quadratic parts, about E^2 M^2 of them: ~1 s at M = 200 on the shared test machine,
#: 1.6e9 of them), conservative: set-up that would not fit the time left is not started.
SETUP_FLOPS_PER_S = 1e9


@dataclass(frozen=True)
class Witnesses:
    """Real points the argument needs, and what was done to find them.

    Attributes
    ----------
    seeds : (K, M) float
        Real regular solutions: one or more on every compact component (at smooth points).
    critical_starts : (S, M) float
        Real parts of the singular solutions near the reals and in the bounded region: every
        critical point is within about ``sqrt(T_END)`` (relative) of one.
    paths : int
        Paths tracked (the Bezout number ``2^r r``).
    counts : dict
        ``regular`` and ``singular`` (ends in the region the linkage can reach), ``far`` (at or
        towards infinity, or beyond that region), ``failed`` (or stopped): a partition of the
        paths; ``real``, ``critical_candidates``, ``quadrics``, ``linear``, ``steps``.
    success : bool
        The argument holds: bounded space, every path ended, none jumped, the deadline kept.
    message : str
    """

    seeds: np.ndarray
    critical_starts: np.ndarray
    paths: int
    counts: dict[str, int]
    success: bool
    message: str


def bounded(linkage: Linkage, cons: Constraints) -> bool:
    """Every connected piece of the graph of active bars holds a vertex pinned in every
    coordinate (so every vertex is within a sum of bar lengths of a fixed point)."""
    v = linkage.n_vertices
    ends = linkage.ends[cons.bars]
    graph = coo_matrix((np.ones(len(ends)), (ends[:, 0], ends[:, 1])), shape=(v, v))
    _, label = connected_components(graph, directed=False)
    pinned = np.asarray(linkage.fixed, dtype=bool).all(axis=1)
    moving = np.unique(ends.ravel())
    anchored = np.zeros(label.max() + 1, dtype=bool)
    anchored[label[pinned]] = True
    return bool(anchored[label[moving]].all())


def bar_quadrics(linkage: Linkage, cons: Constraints) -> tuple[np.ndarray, float, np.ndarray]:
    """Each active bar's equation ``l_a^2 - L_a^2 = 0`` as a quadratic form ``X^T Q_a X`` in
    homogeneous, scaled coordinates ``X = (x_0, y)``, ``u = centre + scale * y / x_0``: the
    forms (E, M + 1, M + 1), ``scale`` (the median length) and ``centre`` (M,)."""
    lk = linkage
    d, m = lk.dimension, cons.n_free
    pos = np.asarray(lk.positions, dtype=float)
    scale = float(np.median(lk.lengths[cons.bars]))
    centroid = pos.mean(axis=0)
    scaled = (pos - centroid) / scale
    fi = lk.free_index  # (V, d), -1 where fixed
    centre = np.zeros(m)
    centre[fi[fi >= 0]] = np.broadcast_to(centroid, fi.shape)[fi >= 0]
    # coordinate (i, k) as a linear form in X: free -> e_{1+fi}, fixed -> scaled * e_0
    ends = lk.ends[cons.bars]
    e = len(ends)
    diff = np.zeros((e, d, m + 1))
    for side, sign in ((0, 1.0), (1, -1.0)):
        v = ends[:, side]
        idx = fi[v]  # (e, d)
        free = idx >= 0
        a_idx, k_idx = np.nonzero(free)
        diff[a_idx, k_idx, 1 + idx[free]] += sign
        a_fix, k_fix = np.nonzero(~free)
        diff[a_fix, k_fix, 0] += sign * scaled[v[a_fix], k_fix]
    quad = np.einsum("akm,akn->amn", diff, diff)
    quad[:, 0, 0] -= (lk.lengths[cons.bars] / scale) ** 2
    return quad, scale, centre


class LinkageSystem:
    """``[quadrics; linear; det [J; c]]`` of a linkage in homogeneous, scaled coordinates
    ``X = (x_0, y)`` with ``u = centre + scale * y / x_0``."""

    def __init__(self, linkage: Linkage, cons: Constraints, c: np.ndarray) -> None:
        m = cons.n_free
        quad, self.scale, self.centre = bar_quadrics(linkage, cons)
        e = len(quad)
        # fewest quadrics: combinations whose quadratic parts cancel are linear equations
        parts = quad[:, 1:, 1:].reshape(e, -1)
        # (economic: the same U (E, E) and singular values, without the (M^2, M^2) V that a
        # full SVD allocates: 12.8 GB at M = 200, a 422 memory-limit for a 100-rotor chain)
        u_left, sv, _ = np.linalg.svd(parts, full_matrices=False)
        rank = int((sv > LINEAR_RTOL * max(float(sv[0]) if len(sv) else 0.0, 1.0)).sum())
        null = u_left[:, rank:].T  # (E - r, E): null @ parts = 0
        _, _, piv = sla.qr(parts.T, pivoting=True, mode="economic")
        keep = np.sort(piv[:rank])
        comb = np.einsum("ka,amn->kmn", null, quad)
        self.linear = np.concatenate([comb[:, 0, :1], 2.0 * comb[:, 0, 1:]], axis=1)
        self.quad = quad[keep]
        self.c = np.asarray(c, dtype=float) / np.linalg.norm(c)
        self.r = rank
        self.n = m
        # (r (M + 1), M + 1): the quadrics' rows stacked, for Q_a X of every a in one product;
        # (r M, M + 1): rows 1.. of each Q_a, for the determinant's gradient
        self._quad_rows = self.quad.reshape(-1, m + 1)
        self._quad_cols = self.quad[:, 1:, :].reshape(-1, m + 1)
        self.degrees = np.array([2] * rank + [1] * (e - rank) + [rank], dtype=int)

    @property
    def paths(self) -> int:
        return int(np.prod(self.degrees.astype(float)))

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (N, M) and Jacobians (N, M, M + 1) at ``x`` (N, M + 1)."""
        p, m, r = len(x), self.n, self.r
        grads = 2.0 * (self._quad_rows @ x.T).T.reshape(p, r, m + 1)  # (N, r, M + 1)
        qv = 0.5 * np.einsum("pam,pm->pa", grads, x)
        lv = x @ self.linear.T
        rows = np.empty((p, m, m), dtype=complex)  # [J; c]
        rows[:, :r] = grads[:, :, 1:]
        rows[:, r:m - 1] = self.linear[:, 1:]
        rows[:, m - 1] = self.c
        det, adj = _det_adjugate(rows)
        # d det / dX_k = sum over quadric rows a, columns j: adj[j, a] * 2 Q_a[1 + j, k]
        ddet = 2.0 * adj[:, :, :r].transpose(0, 2, 1).reshape(p, r * m) @ self._quad_cols
        values = np.concatenate([qv, lv, det[:, None]], axis=1)
        jac = np.empty((p, m, m + 1), dtype=complex)
        jac[:, :r] = grads
        jac[:, r:m - 1] = self.linear
        jac[:, m - 1] = ddet
        return values, jac

    def coordinates(self, x: np.ndarray) -> np.ndarray:
        """Free coordinates ``u`` (N, M) of affine points ``y`` (N, M) (scaled, centred)."""
        return self.centre + self.scale * x


def _det_adjugate(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Determinants (N,) and adjugates (N, M, M) of a stack; ``adj = det * inv`` where the
    inverse exists, from the SVD where it does not (a singular matrix has a rank-one
    adjugate)."""
    with np.errstate(invalid="ignore", over="ignore"):
        det = np.linalg.det(a)
    try:
        adj = det[:, None, None] * np.linalg.inv(a)
        if np.isfinite(adj).all():
            return det, adj
    except np.linalg.LinAlgError:
        pass
    adj = np.full_like(a, np.nan)
    for k in np.flatnonzero(np.isfinite(a).all(axis=(1, 2))):
        u, s, vh = np.linalg.svd(a[k])
        others = np.array([np.prod(np.delete(s, i)) for i in range(len(s))])
        # adj(A) = adj(Vh) adj(S) adj(U) = det(Vh) Vh^H diag(others) det(U) U^H
        adj[k] = np.linalg.det(vh) * np.linalg.det(u) * (vh.conj().T * others) @ u.conj().T
    return det, adj


def _fewest_quadrics(linkage: Linkage, cons: Constraints) -> int:
    """A lower bound on the quadrics left after the linear reduction, in O(V + E): the
    quadratic parts' diagonal blocks are the unsigned incidence of the bars on the moving
    vertices (a bar to a pinned vertex has one entry), whose rank is at least the moving
    vertices less the pieces of the graph among them."""
    fixed = np.asarray(np.asarray(linkage.fixed, dtype=bool).all(axis=1))
    ends = linkage.ends[cons.bars]
    moving = np.unique(ends[~fixed[ends]])
    if not len(moving):
        return 0
    inner = ends[~fixed[ends].any(axis=1)]
    v = linkage.n_vertices
    graph = coo_matrix((np.ones(len(inner)), (inner[:, 0], inner[:, 1])), shape=(v, v))
    _, label = connected_components(graph, directed=False)
    return int(len(moving) - len(np.unique(label[moving])))


def _reach(linkage: Linkage, cons: Constraints, scale: float) -> float:
    """A bound on ``|y|`` (the scaled, centred free coordinates) over every configuration:
    each moving vertex stays within the farthest pinned coordinate plus the sum of every
    active bar's length of the centroid, and ``y`` stacks the moving vertices."""
    pos = np.asarray(linkage.positions, dtype=float)
    centroid = pos.mean(axis=0)
    fixed = np.asarray(linkage.fixed, dtype=bool)
    pinned = fixed.any(axis=1)
    far = float(np.linalg.norm(pos[pinned] - centroid, axis=1).max()) if pinned.any() else 0.0
    moving = int((~fixed.all(axis=1)).sum())
    return np.sqrt(moving) * (far + float(linkage.lengths[cons.bars].sum())) / scale


def witness_points(linkage: Linkage, cons: Constraints | None = None, seed: int = 0,
                   deadline: Deadline = NEVER, paths_max: int = PATHS_MAX) -> Witnesses:
    """Real solutions of ``f = 0, det [J; c] = 0`` (module docstring) for a random ``c``.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> w = witness_points(build_preset("four-bar", {"L2": 1.2}))
    >>> w.success, w.paths, len(w.critical_starts)
    (True, 24, 0)
    """
    cons = cons or Constraints(linkage)
    empty = np.zeros((0, cons.n_free))
    if cons.n_free - cons.n_constraints != 1:
        return Witnesses(empty, empty, 0, {}, False, "needs M - E = 1")
    if not bounded(linkage, cons):
        return Witnesses(empty, empty, 0, {}, False,
                         "the configuration space may be unbounded (a piece of the bar graph "
                         "holds no pinned vertex): a height need not have a maximum")
    least = _fewest_quadrics(linkage, cons)
    if 2.0**least * least > paths_max:  # before the (E, M + 1, M + 1) quadrics are built
        return Witnesses(empty, empty, 0, {"quadrics_at_least": least}, False,
                         f"at least {least} quadrics: at least {2**least * least} paths exceed "
                         f"the bound of {paths_max}")
    e, m = cons.n_constraints, cons.n_free
    setup_s = float(e) ** 2 * float(m) ** 2 / SETUP_FLOPS_PER_S
    if deadline.expired() or setup_s > deadline.remaining():
        return Witnesses(empty, empty, 0, {"quadrics_at_least": least}, False,
                         f"the deadline: the system's set-up (about {setup_s:.2g} s) does not "
                         f"fit the {deadline.remaining():.2g} s left")
    rng = np.random.default_rng(seed)
    c = rng.normal(size=cons.n_free)
    system = LinkageSystem(linkage, cons, c)
    counts = {"quadrics": system.r, "linear": cons.n_constraints - system.r}
    if deadline.expired():
        return Witnesses(empty, empty, 0, counts, False,
                         "the deadline passed while the system was set up")
    if system.r == 0:
        return Witnesses(empty, empty, 0, counts, False, "no quadric: the space is a line")
    if system.paths > paths_max:
        return Witnesses(empty, empty, system.paths, counts, False,
                         f"{count_text(system.paths)} paths exceed the bound of {paths_max}")
    reach = _reach(linkage, cons, system.scale)
    res = track(system, system.degrees, rng, deadline, far=FAR_REACH * reach)
    x0 = res.ends[:, 0]
    y = res.ends[:, 1:] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    size = np.linalg.norm(y, axis=1)
    near = np.isfinite(size) & (size <= reach) & (np.abs(x0) > 0)
    imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
    regular = (res.state == REGULAR) & near
    singular = (res.state == SINGULAR) & near
    real = regular & (imag <= REAL_TOL)
    candidates = singular & (imag <= SINGULAR_IMAG_TOL)
    ended = np.isin(res.state, (REGULAR, SINGULAR, FAR))
    # a partition of the paths: regular and singular ends in reach, far ones (towards infinity
    # or beyond reach), failed or stopped ones
    counts.update(regular=int(regular.sum()), singular=int(singular.sum()),
                  far=int((ended & ~(regular | singular)).sum()),
                  failed=int((~ended).sum()), real=int(real.sum()),
                  critical_candidates=int(candidates.sum()), steps=res.steps)
    return Witnesses(system.coordinates(y[real].real), system.coordinates(y[candidates].real),
                     system.paths, counts, res.success, res.message)
