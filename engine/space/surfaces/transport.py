"""A closed mesh of one linkage's surface moved onto the surface of a nearby linkage (the same
bars, lengths changed a little): every vertex projected onto the new lengths at once, the
frames and gaps taken again, the triangles kept.

Where no critical value lies between the two linkages' lengths their surfaces are isotopic,
and a mesh whose every vertex moves a small part of a step is a mesh of the new surface. That
is not assumed: the moved mesh is handed to :func:`.explore.explore_surfaces` as a mesh of the
new linkage and judged as a marched one is (the fold and tangent checks in the new frames,
every critical point of a generic height found by the homotopy of the *new* linkage on a mesh,
the Morse sum of each component equal to its Euler characteristic). A mesh that fails is no
answer; the caller marches instead.
"""

from __future__ import annotations

import numpy as np

from engine.model.batched import BatchedConstraints
from engine.space.surfaces.geometry import PROJECT_ITERATIONS, Surface
from engine.space.surfaces.mesh import Mesh

#: Largest move of a vertex onto the new surface, in steps of the mesh: beyond it the
#: triangles would be distorted, and the mesh is not moved.
MOVE_MAX = 0.2


def frames_many(surface: Surface, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positive tangent frames (N, M, 2) and gaps (N,) at ``points`` (N, M), as
    :meth:`.geometry.Surface.frame` takes them one at a time."""
    jac = BatchedConstraints(surface.cons).jacobians(points)  # (N, E, M)
    _, s, vt = np.linalg.svd(jac)
    basis = vt[:, -2:, :].transpose(0, 2, 1).copy()  # (N, M, 2)
    negative = np.linalg.det(np.concatenate([jac, basis.transpose(0, 2, 1)], axis=1)) < 0
    basis[negative] = basis[negative][:, :, ::-1]
    gaps = np.where(s[:, 0] > 0, s[:, -1] / np.where(s[:, 0] > 0, s[:, 0], 1.0), 0.0)
    return basis, gaps


def project_many(surface: Surface, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Newton with minimum-norm steps ``-J^+ f`` from every row of ``points`` (N, M) at
    once (:meth:`.geometry.Surface.project`'s iteration): the points and whether each is within
    ``residual_atol`` of every length."""
    batch = BatchedConstraints(surface.cons)
    x = np.array(points, dtype=float)
    targets = batch.lengths ** 2
    live = np.ones(len(x), dtype=bool)
    for _ in range(PROJECT_ITERATIONS):
        sq = batch.squared_lengths(x[live])
        res = np.abs(np.sqrt(sq) - batch.lengths).max(axis=1, initial=0.0)
        idx = np.flatnonzero(live)
        live[idx[res <= surface.atol]] = False
        keep = res > surface.atol
        if not keep.any():
            break
        idx, sq = idx[keep], sq[keep]
        jac = batch.jacobians(x[idx])
        try:
            coef = np.linalg.solve(jac @ jac.transpose(0, 2, 1), (sq - targets)[:, :, None])
        except np.linalg.LinAlgError:
            break  # a singular J J^T: those points stay off the surface, and the mesh fails
        x[idx] -= (jac.transpose(0, 2, 1) @ coef)[:, :, 0]
    sq = batch.squared_lengths(x)
    ok = np.isfinite(x).all(axis=1) & (
        np.abs(np.sqrt(sq) - batch.lengths).max(axis=1, initial=0.0) <= surface.atol)
    return x, ok


def transport(surface: Surface, vertices: np.ndarray, triangles: np.ndarray, step: float
              ) -> Mesh | None:
    """The closed mesh ``vertices`` (N, M), ``triangles`` (T, 3) of a nearby linkage moved onto
    ``surface`` (module docstring); None where a vertex does not reach the surface or moves
    more than ``MOVE_MAX`` steps.

    Examples
    --------
    A sphere of radius 1 (a pinned bar in 3D) meshed as an octahedron, moved onto radius 1.01:

    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> vs = [VertexSpec("P", (0, 0, 0), True), VertexSpec("A", (1, 0, 0))]
    >>> s = Surface(build_linkage(3, vs, [BarSpec("r", ("P", "A"), 1.01)]))
    >>> pts = np.vstack([np.eye(3), -np.eye(3)])
    >>> tri = np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2],
    ...                 [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]])
    >>> moved = transport(s, pts, tri, 1.0)
    >>> np.allclose(np.linalg.norm(moved.vertices, axis=1), 1.01), moved.closed
    (True, True)
    """
    x, ok = project_many(surface, vertices)
    if not ok.all() or np.linalg.norm(x - vertices, axis=1).max(initial=0.0) > MOVE_MAX * step:
        return None
    frames, gaps = frames_many(surface, x)
    return Mesh(x, np.asarray(triangles, dtype=np.int64).reshape(-1, 3), frames, gaps, [],
                True, "closed (moved from a nearby linkage's mesh)")
