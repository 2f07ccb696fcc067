"""The configuration surface ``f(u) = l(u)^2 - L^2 = 0`` of a linkage with ``D = M - E = 2``
as the marching method needs it: oriented tangent frames and projection onto the surface.

Orientation: a regular level set of ``f: R^M -> R^E`` is orientable, its normal space being
spanned by the rows of ``J`` everywhere. A tangent frame ``Z`` (M, 2) is *positive* when
``det [J; Z^T] > 0``; this orientation is continuous along the smooth surface, so triangles
laid out counter-clockwise in positive frames are coherently oriented everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.constraints import Constraints
from engine.model.linkage import Linkage

#: Gauss-Newton iterations of a projection onto the surface.
PROJECT_ITERATIONS = 12


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
