"""Critical points of a generic height ``h(u) = c . u`` on a ``D = 2`` configuration surface:
seeds on every compact component, and the Morse check of a triangulation.

**The system.** At a critical point of ``h`` on the smooth surface ``S = {f = 0}``, ``c`` lies
in the row space of ``J``: ``c = J^T lambda`` (Lagrange). With ``M`` coordinates and ``E``
bars this is the square system::

    f(u) = 0  (E equations of degree 2),   c - J(u)^T lambda = 0  (M, degree 2 in (u, lambda))

in ``M + E`` unknowns. Every compact component ``K`` of ``S`` on which ``J`` has full rank holds
a maximum of ``h``, a real solution; so does every component whose singular points are
cones (at a cone point where ``Q`` on the ``D + 1 = 3`` zero modes is indefinite, a linear
height takes both signs along the cone's lines, so the point is no extremum) -- the maximum of
``h`` on ``K`` is then at a smooth point. A rigid (isolated) critical point is a component of
its own and solves no Lagrange system: it is the caller's to find. For a generic ``c`` every
solution at a smooth point is nondegenerate (``h`` is a Morse function, Sard), hence isolated,
and a homotopy of :mod:`engine.space.homotopy` finds all of them. The system is bihomogeneous
in ``(u, lambda)``: the bars have degrees ``(2, 0)``, the Lagrange equations ``(1, 1)``, so the
linear-product start of :mod:`engine.space.linear_product` needs ``2^E C(M, E)`` paths (the
coefficient of ``a^M b^E`` in ``(2a)^E (a + b)^M``; 240 for a pentagon with one bar pinned)
instead of the total degree's ``2^(M + E)`` (1024); the total-degree start remains the
fallback where the linear product's paths fail. This is the completeness argument of the
surfaces (``search.argument = "proved"``): every compact component holds a real regular
solution, every real regular solution seeds a mesh unless a mesh covers it already.

**The Morse check.** With every critical point of ``h`` on a closed smooth surface, their
indices (negative eigenvalues of the Hessian of ``h`` restricted to the surface,
``-Z^T H_lambda Z`` with ``H_lambda = sum lambda_a Hess(l_a^2)``) satisfy
``sum (-1)^index = chi``: the triangulation's Euler characteristic must agree, component by
component.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.model.report import count_text
from engine.space.homotopy import FAR, REGULAR, SINGULAR, TOTAL_DEGREE, Tracked, track
from engine.space.linear_product import LinearProduct, Structure, bezout
from engine.space.surfaces.geometry import Surface
from engine.space.witnesses import FAR_REACH, REAL_TOL, _reach, bar_quadrics, bounded

#: Newton iterations refining a critical point of the height.
NEWTON_ITERATIONS = 40
#: Relative change of ``(u, lambda)`` below which Newton has converged.
NEWTON_TOL = 1e-12
#: Eigenvalues of the height's Hessian on the surface below this (relative to the norm of
#: ``H_lambda``) make a critical point degenerate.
HESSIAN_RTOL = 1e-8
#: Times the homotopy is tracked (with a new gamma and patch) while paths fail.
TRACK_ATTEMPTS = 2
#: Two critical points of the height closer than this (relative to the median bar length) are
#: the same.
SAME_REL = 1e-6


@dataclass(frozen=True)
class HeightCritical:
    """Critical points of the height: ``points`` (K, M), ``multipliers`` (K, E), ``index``
    (K,) (0 minimum, 1 saddle, 2 maximum; -1 degenerate)."""

    points: np.ndarray
    multipliers: np.ndarray
    index: np.ndarray


@dataclass(frozen=True)
class HeightWitnesses:
    """Outcome of :func:`height_witnesses`: the real regular solutions (refined, with
    indices), the path count and the start system they came from (``"linear product"`` or
    ``"total degree"``), counts of the ends and whether the argument holds."""

    critical: HeightCritical
    paths: int
    counts: dict[str, int]
    success: bool
    message: str
    start: str = TOTAL_DEGREE


class LagrangeSystem:
    """``[X_u^T Q_a X_u; c x_0^2 - sum_a mu_a 2 Q_a[1:] X_u]`` in homogeneous scaled
    coordinates ``X = (x_0, y, mu)``, ``X_u = (x_0, y)``; ``u = centre + scale y / x_0`` and
    ``lambda = mu / (scale x_0)`` (the multipliers of the unscaled system)."""

    def __init__(self, linkage: Linkage, cons: Constraints, c: np.ndarray) -> None:
        self.quad, self.scale, self.centre = bar_quadrics(linkage, cons)  # (E, M+1, M+1)
        self.e, self.m = cons.n_constraints, cons.n_free
        self.c = np.asarray(c, dtype=float) / np.linalg.norm(c)
        self.degrees = np.full(self.e + self.m, 2)
        self._rows = self.quad.transpose(0, 2, 1).reshape(-1, self.m + 1)  # (E (M+1), M+1)
        self._lower = self.quad[:, 1:, :].reshape(self.e, -1)  # (E, M (M + 1))

    @property
    def paths(self) -> int:
        """The total-degree start's path count."""
        return 2 ** (self.e + self.m)

    @property
    def structure(self) -> Structure:
        """The bihomogeneous structure: groups ``y`` and ``mu``; bars ``(2, 0)``, Lagrange
        equations ``(1, 1)``."""
        m, e = self.m, self.e
        return Structure((np.arange(1, m + 1), np.arange(m + 1, m + e + 1)),
                         np.array([[2, 0]] * e + [[1, 1]] * m))

    @property
    def product_paths(self) -> int:
        """The linear-product start's path count (the bihomogeneous Bezout number)."""
        return bezout(self.structure)

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (N, n) and Jacobians (N, n, n + 1) at ``x`` (N, n + 1), ``n = M + E``."""
        e, m = self.e, self.m
        xu, mu = x[:, :m + 1], x[:, m + 1:]
        p = len(x)
        # (matrix products rather than einsum: this is the homotopy's inner loop)
        grads = 2.0 * (xu @ self._rows.T).reshape(p, e, m + 1)  # (N, E, M + 1)
        qv = 0.5 * np.matmul(grads, xu[:, :, None])[:, :, 0]
        x0 = x[:, 0]
        lag = self.c[None] * (x0 ** 2)[:, None] - np.matmul(mu[:, None, :],
                                                            grads[:, :, 1:])[:, 0]
        jac = np.zeros((p, e + m, m + e + 1), dtype=complex)
        jac[:, :e, :m + 1] = grads
        # d lag_i / d X_u = 2 c_i x0 e_0 - sum_a mu_a 2 Q_a[1 + i, :]
        jac[:, e:, :m + 1] = -2.0 * (mu @ self._lower).reshape(p, m, m + 1)
        jac[:, e:, 0] += 2.0 * self.c[None] * x0[:, None]
        jac[:, e:, m + 1:] = -grads[:, :, 1:].transpose(0, 2, 1)
        return np.concatenate([qv, lag], axis=1), jac


def _index(surface: Surface, u: np.ndarray, lam: np.ndarray) -> int:
    """The Morse index of the height at a critical point (-1 where degenerate)."""
    hess = np.asarray(surface.cons.stress_hessian(lam, sparse=False))
    z = surface.frame(u).basis
    ev = np.linalg.eigvalsh(-(z.T @ hess @ z))
    scale = max(float(np.abs(hess).max()), 1e-300)
    if np.abs(ev).min() <= HESSIAN_RTOL * scale:
        return -1
    return int((ev < 0).sum())


def refine(surface: Surface, c: np.ndarray, u0: np.ndarray, max_move: float = np.inf
           ) -> tuple[np.ndarray, np.ndarray] | None:
    """Newton on ``[f; c - J^T lambda] = 0`` from ``u0`` (``lambda`` in least squares), each
    step's move of ``u`` cut to ``max_move`` (a trust region: a start near one critical point
    should not jump to another); None where it does not converge onto the surface."""
    c = np.asarray(c, dtype=float) / np.linalg.norm(c)
    u = np.array(u0, dtype=float)
    lam = np.linalg.lstsq(surface.jacobian(u).T, c, rcond=None)[0]
    e = len(lam)
    for _ in range(NEWTON_ITERATIONS):
        jac = surface.jacobian(u)
        hess = np.asarray(surface.cons.stress_hessian(lam, sparse=False))
        res = np.concatenate([surface.values(u), c - jac.T @ lam])
        big = np.block([[jac, np.zeros((e, e))], [-hess, -jac.T]])
        try:
            step = np.linalg.solve(big, -res)
        except np.linalg.LinAlgError:
            return None
        move = float(np.linalg.norm(step[:len(u)]))
        if move > max_move:
            step *= max_move / move
        u, lam = u + step[:len(u)], lam + step[len(u):]
        if not np.isfinite(u).all():
            return None
        if np.linalg.norm(step) <= NEWTON_TOL * max(1.0, float(np.linalg.norm(u))):
            break
    if surface.cons.max_residual(u) > surface.atol:
        return None
    if np.linalg.norm(c - surface.jacobian(u).T @ lam) > 1e-8:
        return None
    return u, lam


def classify_points(surface: Surface, c: np.ndarray, starts: np.ndarray,
                    max_move: float = np.inf) -> HeightCritical:
    """Refine ``starts`` (K, M) to critical points of the height (Newton moves of at most
    ``max_move``), drop duplicates and the ones that do not converge, and give each its
    index."""
    same = SAME_REL * float(np.median(surface.linkage.lengths[surface.cons.bars]))
    pts: list[np.ndarray] = []
    lams: list[np.ndarray] = []
    for u0 in np.asarray(starts, dtype=float).reshape(-1, surface.n):
        got = refine(surface, c, u0, max_move)
        if got is None:
            continue
        if pts and np.linalg.norm(np.asarray(pts) - got[0], axis=1).min() <= same:
            continue
        pts.append(got[0])
        lams.append(got[1])
    idx = np.array([_index(surface, u, lam) for u, lam in zip(pts, lams, strict=True)],
                   dtype=np.int64)
    return HeightCritical(np.asarray(pts).reshape(-1, surface.n),
                          np.asarray(lams).reshape(-1, surface.cons.n_constraints), idx)


def generic_height(n_free: int, seed: int) -> tuple[np.ndarray, np.random.Generator]:
    """A random unit height ``c`` (M,) drawn from ``seed``, and the generator that then draws
    the rest (:func:`engine.space.surfaces.explore.explore_surfaces`'s)."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=n_free)
    return c / np.linalg.norm(c), rng


def height_witnesses(surface: Surface, c: np.ndarray, rng: np.random.Generator,
                     deadline: Deadline = NEVER, paths_max: int = 4096) -> HeightWitnesses:
    """Every real critical point of ``h = c . u`` on the surface, by the total-degree
    homotopy of the Lagrange system (module docstring)."""
    lk, cons = surface.linkage, surface.cons
    empty = HeightCritical(np.zeros((0, cons.n_free)), np.zeros((0, cons.n_constraints)),
                           np.zeros(0, dtype=np.int64))
    if not bounded(lk, cons):
        return HeightWitnesses(empty, 0, {}, False, "the configuration space may be unbounded "
                               "(a piece of the bar graph holds no pinned vertex)")
    system = LagrangeSystem(lk, cons, c)
    fewest = min(system.paths, system.product_paths)
    if fewest > paths_max:
        return HeightWitnesses(empty, fewest, {}, False,
                               f"{count_text(fewest)} paths exceed the bound of {paths_max}")
    reach = _reach(lk, cons, system.scale)
    res = _track(system, rng, deadline, FAR_REACH * reach * 10.0, paths_max)
    m = cons.n_free
    x0 = res.ends[:, 0]
    y = res.ends[:, 1:m + 1] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    size = np.linalg.norm(y, axis=1)
    near = np.isfinite(size) & (size <= reach) & (np.abs(x0) > 0)
    imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
    real = (res.state == REGULAR) & near & (imag <= REAL_TOL)
    regular = (res.state == REGULAR) & near
    singular = (res.state == SINGULAR) & near
    ended = np.isin(res.state, (REGULAR, SINGULAR, FAR))
    # a partition of the paths, as in engine.space.witnesses
    counts = {"paths": res.paths, "regular": int(regular.sum()),
              "singular": int(singular.sum()), "far": int((ended & ~(regular | singular)).sum()),
              "failed": int((~ended).sum()), "real": int(real.sum()), "steps": res.steps}
    starts = system.centre + system.scale * y[real].real
    crit = classify_points(surface, system.c, starts)
    counts["refined"] = len(crit.points)
    ok = res.success and len(crit.points) == int(real.sum())
    message = res.message if not res.success else (
        "every path ended" if ok else
        f"{int(real.sum()) - len(crit.points)} real ends did not refine to distinct points")
    return HeightWitnesses(crit, res.paths, counts, ok, message, res.start)


def start_order(product_paths: int, total_paths: int, paths_max: int) -> list[bool]:
    """The starts tried in turn (True: the linear product, False: the total degree), each
    ``TRACK_ATTEMPTS`` times: the linear product first where it has fewer paths, then the
    total degree where it fits ``paths_max``."""
    order = [True] * TRACK_ATTEMPTS if product_paths < total_paths else []
    return order + ([False] * TRACK_ATTEMPTS if total_paths <= paths_max else [])


def _track(system: LagrangeSystem, rng: np.random.Generator, deadline: Deadline, far: float,
           paths_max: int) -> Tracked:
    """The linear-product homotopy where it has fewer paths, tracked up to ``TRACK_ATTEMPTS``
    times (a failed path is a matter of the random gamma, patch and factors: each attempt draws
    new ones); then, where paths still failed, the total-degree homotopy (within
    ``paths_max``) the same way."""
    res: Tracked | None = None
    for product in start_order(system.product_paths, system.paths, paths_max):
        start = LinearProduct(system.structure, system.degrees, rng) if product else None
        res = track(system, system.degrees, rng, deadline, far=far, start=start)
        if res.success or deadline.expired():
            break
    assert res is not None  # (one of the two starts fits paths_max: checked by the caller)
    return res


def pl_critical_vertices(vertices: np.ndarray, triangles: np.ndarray, height: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The PL critical vertices of ``height`` on a closed triangulated surface (Banchoff):
    each vertex's number of sign changes of ``height - height[v]`` around its link; returns
    the vertices with 0 or at least 4 changes and their PL index sum ``1 - changes / 2``."""
    del vertices  # (the heights say everything)
    tri = np.asarray(triangles, dtype=np.int64)
    changes = np.zeros(int(tri.max()) + 1 if len(tri) else 0, dtype=np.int64)
    for k in range(3):
        v, a, b = tri[:, k], tri[:, (k + 1) % 3], tri[:, (k + 2) % 3]
        mixed = (height[a] > height[v]) != (height[b] > height[v])
        np.add.at(changes, v, mixed.astype(np.int64))
    used = np.unique(tri)
    crit = used[(changes[used] == 0) | (changes[used] >= 4)]
    return crit, 1 - changes[crit] // 2


def ring(triangles: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """``vertices`` and their neighbours in the triangulation (sorted, unique)."""
    tri = np.asarray(triangles, dtype=np.int64)
    touch = np.isin(tri, vertices).any(axis=1)
    return np.union1d(np.asarray(vertices, dtype=np.int64), tri[touch].ravel())


def assign(points: np.ndarray, meshes: list[np.ndarray], radius: float) -> np.ndarray:
    """The mesh (index into ``meshes``, each (N_k, M) vertices) nearest each point, -1 where
    no mesh vertex is within ``radius``."""
    out = np.full(len(points), -1, dtype=np.int64)
    best = np.full(len(points), np.inf)
    for k, verts in enumerate(meshes):
        if not len(verts) or not len(points):
            continue
        d, _ = cKDTree(verts).query(points)
        take = (d < best) & (d <= radius)
        out[take], best[take] = k, d[take]
    return out
