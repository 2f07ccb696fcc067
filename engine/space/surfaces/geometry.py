"""The configuration surface ``f(u) = l(u)^2 - L^2 = 0`` of a linkage with ``D = M - E = 2``
as the marching method needs it: oriented tangent frames and projection onto the surface.

Orientation: a regular level set of ``f: R^M -> R^E`` is orientable, its normal space being
spanned by the rows of ``J`` everywhere. A tangent frame ``Z`` (M, 2) is *positive* when
``det [J; Z^T] > 0``; this orientation is continuous along the smooth surface, so triangles
laid out counter-clockwise in positive frames are coherently oriented everywhere.

Curvature: along a curve ``u(t)`` on the surface with unit velocity ``x`` (tangent),
``f(u(t)) = 0`` gives ``J u'' + q(x) = 0`` with ``q_a(x) = x^T Hess(l_a^2) x = 2 |x_i - x_j|^2``
(the bar's ends' velocities), so the normal part of the acceleration, the normal curvature
vector, is ``-J^+ q(x)``; :meth:`Surface.curvatures` gives its largest norm over the unit
tangents at many points (what bounds the mesh's step: a chord of length ``h`` leaves the
tangent plane by about ``h kappa / 2`` radians).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.batched import BatchedConstraints
from engine.model.constraints import Constraints
from engine.model.errors import InvalidLinkage
from engine.model.linkage import Linkage
from engine.space.witnesses import bounded

#: Gauss-Newton iterations of a projection onto the surface.
PROJECT_ITERATIONS = 12
#: The step of a component meshed again (its geometric checks failed), relative to the last.
REMESH_FACTOR = 0.6
#: A component meshed again has its step at most this over the largest normal curvature at
#: the last mesh's vertices (:meth:`Surface.curvatures`): edges leave the tangent planes by
#: about 24 degrees (30 for a front's closing edges of 1.3 steps), with room for a coarse mesh
#: that misses the curvature's peak by a quarter (the spatial quadrilateral (0.731, 1.725,
#: 0.424, 1.52): 19 at a cap, where 0.6 times the step twice left edges at 66 degrees).
CURVATURE_STEP = 0.8
#: The step of a component meshed again is at least this times the last.
FINER_MIN = 1 / 16
#: Unit tangent directions (over half a turn: ``q`` is even in ``x``) at which the normal
#: curvature is sampled; its norm is a trigonometric polynomial of degree 4 in the angle, so
#: 32 samples find its largest value to within a few percent.
CURVATURE_SAMPLES = 32


@dataclass(frozen=True)
class Frame:
    """An oriented orthonormal tangent frame ``basis`` (M, 2) at a point, and ``gap``, the
    smallest singular value of ``J`` over its largest (0 at a critical point)."""

    basis: np.ndarray
    gap: float


class Surface:
    """The constraints of a ``D = 2`` linkage, with frames and projections.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> import numpy as np
    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> pts = {"P0": (0, 0), "P1": (1, 0), "A": (1.3, 0.9), "B": (0.5, 1.5), "C": (-0.3, 0.9)}
    >>> vs = [VertexSpec(k, p, k in ("P0", "P1")) for k, p in pts.items()]
    >>> bs = [BarSpec(f"b{i}", e) for i, e in enumerate(
    ...     [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")])]
    >>> s = Surface(build_linkage(2, vs, bs))
    >>> s.frame(s.linkage.coordinates()).basis.shape
    (6, 2)
    """

    def __init__(self, linkage: Linkage, cons: Constraints | None = None,
                 residual_atol: float = 1e-9) -> None:
        self.linkage = linkage
        self.cons = cons or Constraints(linkage)
        self.atol = residual_atol
        self.n = self.cons.n_free

    def values(self, u: np.ndarray) -> np.ndarray:
        """``f(u) = l^2 - L^2`` (E,)."""
        return self.cons.squared_lengths(u) - self.cons.targets

    def jacobian(self, u: np.ndarray) -> np.ndarray:
        """``J(u)`` (E, M), dense."""
        return np.asarray(self.cons.jacobian(u, sparse=False))

    def frame(self, u: np.ndarray) -> Frame:
        """The positive orthonormal tangent frame at ``u`` (module docstring)."""
        jac = self.jacobian(u)
        _, s, vt = np.linalg.svd(jac)
        basis = vt[-2:].T.copy()  # (M, 2): the last right singular vectors
        if np.linalg.det(np.vstack([jac, basis.T])) < 0:
            basis = basis[:, ::-1].copy()
        gap = float(s[-1] / s[0]) if len(s) and s[0] > 0 else 0.0
        return Frame(basis, gap)

    def curvatures(self, us: np.ndarray, frames: np.ndarray | None = None) -> np.ndarray:
        """The largest normal curvature (1 / length) over the unit tangents at each point of
        ``us`` (N, M) (module docstring), with their ``frames`` (N, M, 2) where known; large
        near a critical point of the linkage (``J^+`` grows as one over its gap).

        Examples
        --------
        One bar of length 1.3 from a pin in 3D: its end's sphere has curvature 1 / 1.3.

        >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
        >>> lk = build_linkage(3, [VertexSpec("P", (0, 0, 0), True),
        ...                        VertexSpec("A", (1.3, 0, 0))], [BarSpec("r", ("P", "A"))])
        >>> s = Surface(lk)
        >>> round(float(s.curvatures(lk.coordinates()[None])[0]) * 1.3, 9)
        1.0
        """
        us = np.asarray(us, dtype=float).reshape(-1, self.n)
        if frames is None:
            frames = np.array([self.frame(u).basis for u in us]).reshape(-1, self.n, 2)
        batch = BatchedConstraints(self.cons)
        origin = batch.bar_vectors(np.zeros((1, self.n)))  # (1, E, d): the pins' part
        w1 = batch.bar_vectors(frames[:, :, 0]) - origin  # (N, E, d): bar velocities
        w2 = batch.bar_vectors(frames[:, :, 1]) - origin
        q = 2.0 * np.stack([np.einsum("nad,nad->na", w1, w1), np.einsum("nad,nad->na", w1, w2),
                            np.einsum("nad,nad->na", w2, w2)], axis=2)  # (N, E, 3)
        normal = np.linalg.pinv(batch.jacobians(us)) @ q  # (N, M, 3)
        t = np.linspace(0.0, np.pi, CURVATURE_SAMPLES, endpoint=False)
        basis = np.stack([np.cos(t) ** 2, 2 * np.cos(t) * np.sin(t), np.sin(t) ** 2])  # (3, T)
        return np.linalg.norm(normal @ basis, axis=1).max(axis=1)  # (N,)

    def project(self, u: np.ndarray) -> tuple[np.ndarray, bool]:
        """Gauss-Newton (minimum-norm steps ``-J^+ f``) from ``u`` onto the surface: the point
        and whether every bar is within ``residual_atol`` of its length."""
        x = np.array(u, dtype=float)
        target = self.cons.linkage.lengths[self.cons.bars]
        for _ in range(PROJECT_ITERATIONS):
            sq = self.cons.squared_lengths(x)  # one pass gives the residual and f
            if not sq.size or float(np.abs(np.sqrt(sq) - target).max()) <= self.atol:
                return x, True
            jac = self.jacobian(x)
            try:
                step = jac.T @ np.linalg.solve(jac @ jac.T, sq - self.cons.targets)
            except np.linalg.LinAlgError:
                return x, False
            if not np.isfinite(step).all():
                return x, False
            x = x - step
        return x, self.cons.max_residual(x) <= self.atol


def finer_step(surface: Surface, step: float, points: np.ndarray, frames: np.ndarray | None,
               room: float) -> float:
    """The step of a mesh marched again: ``REMESH_FACTOR`` times the last, shorter where the
    largest normal curvature ``kappa`` at ``points`` (N, M) asks for it (``CURVATURE_STEP /
    kappa``: a chord of that length leaves the tangent plane by about ``CURVATURE_STEP / 2``
    radians) and the triangle budget leaves ``room`` for it (how many times the last mesh's
    triangles: they scale as the step's inverse square), at least ``FINER_MIN`` times the
    last.

    Examples
    --------
    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> lk = build_linkage(3, [VertexSpec("P", (0, 0, 0), True),
    ...                        VertexSpec("A", (0.1, 0, 0))], [BarSpec("r", ("P", "A"))])
    >>> u = lk.coordinates()[None]
    >>> round(finer_step(Surface(lk), 1.0, u, None, 1e6), 6), finer_step(Surface(lk), 1.0, u,
    ...                                                                    None, 10.0)
    (0.08, 0.6)
    """
    kappa = float(surface.curvatures(points, frames).max()) if len(points) else 0.0
    finer = max(min(REMESH_FACTOR, CURVATURE_STEP / (kappa * step) if kappa > 0 else 1.0),
                FINER_MIN)
    return step * (finer if finer ** -2 <= room else REMESH_FACTOR)


def require_two_dof(linkage: Linkage, cons: Constraints) -> None:
    """Raise :class:`InvalidLinkage` unless ``M - E = 2`` with something fixed and a bounded
    configuration space (every moving vertex on a bar, every piece of the bar graph pinned:
    the components are then compact, and each can be meshed whole)."""
    if cons.n_free - cons.n_constraints != 2 or not linkage.anything_fixed:
        raise InvalidLinkage(
            "surfaces need two degrees of freedom (M - E = 2 with something fixed); this "
            f"linkage has M = {cons.n_free}, E = {cons.n_constraints}"
            + ("" if linkage.anything_fixed else " and nothing fixed"),
            loc=("bars",),
        )
    moving = ~np.asarray(linkage.fixed, dtype=bool).all(axis=1)
    on_bar = np.zeros(linkage.n_vertices, dtype=bool)
    on_bar[linkage.ends[cons.bars].ravel()] = True
    if (moving & ~on_bar).any() or not bounded(linkage, cons):
        raise InvalidLinkage(
            "the configuration space is unbounded (a moving vertex on no bar, or a piece of "
            "the bar graph with no pinned vertex): its surfaces cannot be meshed whole",
            loc=("bars",),
        )
