"""Triangulating one component of a configuration surface by a marching (advancing-front)
method with Newton projection: Hartmann, *A marching method for the triangulation of
surfaces*, The Visual Computer 14 (1998), carried from R^3 to the configuration space R^M.

The mesh starts as a hexagon of six triangles around a seed, laid out in the seed's positive
tangent frame (:mod:`.geometry`) with edges ``step`` and projected onto the surface. Its
boundary is kept as *fronts*: cycles of vertices, the mesh on their left. Each step takes the
front vertex ``p`` with the smallest *front angle* (the uncovered angle between its two front
neighbours, measured counter-clockwise in ``p``'s positive frame) and

* if a front vertex ``q`` other than ``p``'s neighbours lies within ``CLOSE * step`` of ``p``
  and inside its uncovered angle, joins ``p`` and ``q``: a front is *split* in two (``q`` on
  the same front) or two fronts are *merged* (``q`` on another): this is how handles and
  meeting fronts are closed;
* else, if the angle is below ``SMALL_ANGLE``, adds the triangle of ``p`` and its neighbours;
* else fills the angle with ``n = floor(3 angle / pi) + 1`` triangles (one fewer where they
  would be thinner than ``MIN_SPLIT_ANGLE``), their new vertices at distance ``step`` from
  ``p`` in its tangent plane, projected onto the surface.

A front of three vertices is closed by one triangle. Started from the fans around cones'
apexes (:class:`Fan`), the step is graded near each apex (the cone's width times the distance
to it, up to ``step``) and the front entries of the finest step are advanced first. Every
operation keeps the mesh a 2-manifold with boundary (the fronts), so a mesh without fronts is
a closed surface; the geometric checks (triangles positive in their vertices' frames, close to
the tangent planes) and the Morse check of :mod:`.morse` are what vouch that it is *this*
surface. The steps are bounded by a triangle budget and the deadline: a mesh stopped early
keeps its fronts (``closed`` False).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from engine.model.budget import NEVER, Deadline
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.homology import edges_of

#: Front vertices within this many steps of the front vertex being processed are joined to it.
CLOSE = 1.0
#: Front angles below this are closed by one triangle (Hartmann: 75 degrees).
SMALL_ANGLE = np.deg2rad(75.0)
#: A fan of triangles whose angle at ``p`` would fall below this is made one triangle coarser.
MIN_SPLIT_ANGLE = 0.8
#: A projected new vertex may move at most this many steps off its tangent-plane point.
MAX_PROJECTION_MOVE = 0.5
#: A graded mesh (:class:`Fan`) advances the front entries whose step is within this factor
#: of the smallest first (:func:`_priority`).
FINEST = 1.5
#: Front vertices whose new vertices could not be projected are retried this many times
#: (the step halved each time) before the mesh stops as stuck.
RETRIES = 2


@dataclass(frozen=True)
class Mesh:
    """A marched mesh of one component.

    Attributes
    ----------
    vertices : (N, M) float
        Points on the surface (configuration coordinates).
    triangles : (T, 3) int
        Counter-clockwise in the positive frames.
    frames : (N, M, 2) float
        The positive tangent frame at each vertex.
    gaps : (N,) float
        ``s_min / s_max`` of ``J`` at each vertex (small near a critical point).
    fronts : list of (k,) int arrays
        What is still open (empty for a closed surface).
    closed : bool
    message : str
    apexes : (K,) int
        The vertices that are apexes of cones (their frames mean nothing; their links are two
        cycles, one per nappe).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    frames: np.ndarray
    gaps: np.ndarray
    fronts: list[np.ndarray]
    closed: bool
    message: str
    apexes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


@dataclass(frozen=True)
class Fan:
    """The start of a mesh around a cone's apex (:func:`.cones.cone_fans`).

    Attributes
    ----------
    apex : (M,) float
    rings : list of (n, M) float
        One ring per nappe, counter-clockwise in their positive frames: the first fronts.
    slope : float
        Within ``step / slope`` of the apex the step is ``slope`` times the distance to it
        (never below ``slope`` times half the rings' distance): a cone's features (the gap
        between its nappes, a nappe's width) grow as the distance, so a graded step resolves
        them at every distance. ``inf``: the step everywhere.
    """

    apex: np.ndarray
    rings: list[np.ndarray]
    slope: float = np.inf


class _Builder:
    def __init__(self, surface: Surface, step: float) -> None:
        self.s, self.h = surface, step
        self.count = 0
        self.x = np.empty((64, surface.n))  # (capacity, M): vertices
        self.z = np.empty((64, surface.n, 2))  # their frames
        self.gap = np.empty(64)
        self.size = np.empty(64)  # the step at each vertex (Fan.slope)
        self.tri: list[tuple[int, int, int]] = []
        self.fronts: list[list[int]] = []
        self.apexes: list[int] = []
        self.grading: list[tuple[np.ndarray, float, float]] = []  # apex, slope, floor

    def add(self, u: np.ndarray) -> int:
        if self.count == len(self.x):
            self.x = np.concatenate([self.x, np.empty_like(self.x)])
            self.z = np.concatenate([self.z, np.empty_like(self.z)])
            self.gap = np.concatenate([self.gap, np.empty_like(self.gap)])
            self.size = np.concatenate([self.size, np.empty_like(self.size)])
        fr = self.s.frame(u)
        k = self.count
        self.x[k], self.z[k], self.gap[k] = u, fr.basis, fr.gap
        size = self.h
        for apex, slope, floor in self.grading:
            size = min(size, max(slope * float(np.linalg.norm(u - apex)), floor))
        self.size[k] = size
        self.count += 1
        return k

    def new_point(self, p: int, direction: np.ndarray, length: float) -> int | None:
        """A vertex ``length`` from ``p`` along the unit ``direction`` of its frame, projected."""
        guess = self.x[p] + length * (self.z[p] @ direction)
        u, ok = self.s.project(guess)
        if not ok or np.linalg.norm(u - guess) > MAX_PROJECTION_MOVE * length:
            return None
        return self.add(u)

    def local(self, p: int, q: np.ndarray) -> np.ndarray:
        """Coordinates (k, 2) of points ``q`` (k, M) in ``p``'s frame, relative to ``p``."""
        return (q - self.x[p]) @ self.z[p]

    def start(self, seed: np.ndarray) -> bool:
        """The first hexagon (its step halved up to ``RETRIES`` times where a vertex does not
        project: a small component, or a seed near a fold of the projection)."""
        c = self.add(seed)
        for attempt in range(RETRIES + 1):
            ring = []
            for k in range(6):
                t = k * np.pi / 3
                v = self.new_point(c, np.array([np.cos(t), np.sin(t)]), self.h * 0.5 ** attempt)
                if v is None:
                    break
                ring.append(v)
            if len(ring) == 6:
                self.tri += [(c, ring[k], ring[(k + 1) % 6]) for k in range(6)]
                self.fronts.append(ring)
                return True
            self.count = c + 1
        return False


    def start_cones(self, fans: list[Fan]) -> None:
        """Every cone's apex and a fan around it on each nappe (:func:`.cones.cone_fans`):
        the rings are the first fronts; the step graded near each apex (:class:`Fan`)."""
        for fan in fans:
            if np.isfinite(fan.slope):
                inner = min(float(np.linalg.norm(r - fan.apex, axis=1).min()) for r in fan.rings)
                self.grading.append((fan.apex, fan.slope, 0.5 * fan.slope * inner))
        for fan in fans:
            a = self.add(fan.apex)
            self.apexes.append(a)
            for ring in fan.rings:
                idx = [self.add(u) for u in ring]
                self.tri += [(a, idx[k], idx[(k + 1) % len(idx)]) for k in range(len(idx))]
                self.fronts.append(idx)


def _front_entries(b: _Builder) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every front entry: (front, position, vertex) and the uncovered angle there (from the
    previous front vertex counter-clockwise to the next, in the vertex's frame)."""
    fk_l: list[int] = []
    pos_l: list[int] = []
    p_l: list[int] = []
    a_l: list[int] = []
    c_l: list[int] = []
    for k, fr in enumerate(b.fronts):
        fk_l += [k] * len(fr)
        pos_l += range(len(fr))
        p_l += fr
        a_l += fr[-1:] + fr[:-1]
        c_l += fr[1:] + fr[:1]
    fk, pos = np.array(fk_l), np.array(pos_l)
    p, a, c = np.array(p_l), np.array(a_l), np.array(c_l)
    z = b.z[p]  # (k, M, 2)
    va = np.einsum("km,kmj->kj", b.x[a] - b.x[p], z)
    vc = np.einsum("km,kmj->kj", b.x[c] - b.x[p], z)
    ang = np.mod(np.arctan2(vc[:, 1], vc[:, 0]) - np.arctan2(va[:, 1], va[:, 0]), 2 * np.pi)
    return fk, pos, p, ang


def _close_partner(b: _Builder, k: int, i: int, omega: float, entries: tuple[np.ndarray, ...]
                   ) -> tuple[int, int] | None:
    """The nearest front entry (front, position) to join to the entry ``(k, i)`` (module
    docstring), or None."""
    fr = b.fronts[k]
    p, a, c = fr[i], fr[i - 1], fr[(i + 1) % len(fr)]
    fk, pos, verts, _ = entries
    pts = b.x[verts]
    d = np.linalg.norm(pts - b.x[p], axis=1)
    cand = (d < CLOSE * b.size[p]) & (verts != p) & (verts != a) & (verts != c)
    if not cand.any():
        return None
    loc = b.local(p, pts[cand])
    normal = np.sqrt(np.maximum(d[cand] ** 2 - (loc ** 2).sum(axis=1), 0.0))
    va = b.local(p, b.x[a][None])[0]
    phi = np.mod(np.arctan2(loc[:, 1], loc[:, 0]) - np.arctan2(va[1], va[0]), 2 * np.pi)
    inside = (phi > 0.0) & (phi < omega) & (normal < 0.5 * d[cand])
    if not inside.any():
        return None
    idx = np.flatnonzero(cand)[inside]
    best = idx[np.argmin(d[idx])]
    return int(fk[best]), int(pos[best])


def _join(b: _Builder, k: int, i: int, k2: int, j: int) -> None:
    """Split front ``k`` at positions ``i`` and ``j`` (k2 == k), or merge fronts ``k`` and
    ``k2`` through the entries ``i`` and ``j``."""
    fr = b.fronts[k]
    if k2 == k:
        if j < i:
            i, j = j, i
        one = fr[i:j + 1]  # p .. q, closed by q -> p
        two = fr[j:] + fr[:i + 1]  # q .. p, closed by p -> q
        b.fronts[k] = one
        b.fronts.append(two)
        return
    other = b.fronts[k2]
    a = fr[i:] + fr[:i]  # p first
    c = other[j:] + other[:j]  # q first
    b.fronts[k] = a + [a[0]] + c + [c[0]]
    del b.fronts[k2]


def _grow(b: _Builder, k: int, i: int, omega: float) -> bool:
    """Fill the uncovered angle at entry ``(k, i)``; False where no new vertex projects."""
    fr = b.fronts[k]
    p, a, c = fr[i], fr[i - 1], fr[(i + 1) % len(fr)]
    if omega < SMALL_ANGLE:
        b.tri.append((p, a, c))
        del fr[i]
        return True
    n = int(np.floor(3 * omega / np.pi)) + 1
    if n > 1 and omega / n < MIN_SPLIT_ANGLE:
        n -= 1
    va = b.local(p, b.x[a][None])[0]
    t0 = np.arctan2(va[1], va[0])
    for attempt in range(RETRIES + 1):
        length = float(b.size[p]) * 0.5 ** attempt
        first = b.count
        new = []
        for m in range(1, n):
            t = t0 + m * omega / n
            v = b.new_point(p, np.array([np.cos(t), np.sin(t)]), length)
            if v is None:
                break
            new.append(v)
        if len(new) == n - 1:
            chain = [a, *new, c]
            b.tri += [(p, chain[m], chain[m + 1]) for m in range(n)]
            fr[i:i + 1] = new
            return True
        b.count = first
    return False


def march(surface: Surface, seed: np.ndarray | None, step: float, max_triangles: int,
          deadline: Deadline = NEVER,
          fans: list[Fan] | None = None) -> Mesh:
    """Mesh the component through ``seed`` (on the surface) with edges about ``step``; or,
    with ``fans`` (apexes and their rings, :func:`.cones.cone_fans`) instead of a seed, every
    component through those cones at once (:func:`components` parts them), the edges graded
    near the apexes (:class:`Fan`).

    Examples
    --------
    A pentagon with one bar pinned (lengths 1, 1, 1, 1, 1.4):

    >>> from engine.model.linkage import build_linkage, VertexSpec, BarSpec
    >>> pts = {"P0": (0, 0), "P1": (1, 0), "A": (1.3, 0.9), "B": (0.5, 1.5), "C": (-0.3, 0.9)}
    >>> vs = [VertexSpec(k, p, k in ("P0", "P1")) for k, p in pts.items()]
    >>> bs = [BarSpec(f"b{i}", e) for i, e in enumerate(
    ...     [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")])]
    >>> s = Surface(build_linkage(2, vs, bs))
    >>> m = march(s, s.linkage.coordinates(), 0.4, 20000)
    >>> m.closed
    True
    """
    b = _Builder(surface, step)
    if fans:
        b.start_cones(fans)
    elif seed is None or not b.start(np.asarray(seed, dtype=float)):
        return _result(b, "the first hexagon did not project onto the surface")
    stuck: set[int] = set()
    while b.fronts:
        if deadline.expired():
            return _result(b, "stopped by the deadline")
        if len(b.tri) >= max_triangles:
            return _result(b, f"stopped at the budget of {max_triangles} triangles")
        small = [k for k, fr in enumerate(b.fronts) if len(fr) <= 3]
        if small:
            k = small[0]
            fr = b.fronts.pop(k)
            if len(fr) == 3:
                b.tri.append((fr[1], fr[0], fr[2]))
            continue
        entries = _front_entries(b)
        fk, pos, verts, ang = entries
        order = np.argsort(_priority(b, verts, ang, stuck))
        pick = next((int(o) for o in order if int(verts[o]) not in stuck), None)
        if pick is None:
            return _result(b, f"{len(stuck)} front vertices could not be advanced (no new "
                           "vertex projects onto the surface: a critical point or a fold?)")
        k, i, omega = int(fk[pick]), int(pos[pick]), float(ang[pick])
        partner = _close_partner(b, k, i, omega, entries)
        if partner is not None:
            _join(b, k, i, *partner)
            continue
        if not _grow(b, k, i, omega):
            stuck.add(int(verts[pick]))
        else:
            stuck.clear()
    _flip_folded(b)
    return _result(b, "closed")


def _priority(b: _Builder, verts: np.ndarray, ang: np.ndarray, stuck: set[int]) -> np.ndarray:
    """The order in which front entries are taken: the smallest front angle first
    (Hartmann), among the entries whose step is within ``FINEST`` of the smallest (of those
    not stuck); with one step everywhere, the angles themselves. A graded mesh thus grows out
    from its apexes first, as advancing-front methods take the smallest faces first: a coarse
    front that reached a fine one still waiting would pass it by."""
    if not b.grading:
        return ang
    size = b.size[verts]
    free = ~np.isin(verts, list(stuck)) if stuck else np.ones(len(verts), dtype=bool)
    if not free.any():
        return ang
    return ang + 4 * np.pi * (size > FINEST * float(size[free].min()))


def _negative(b: _Builder, tri: np.ndarray) -> np.ndarray:
    """How many of each triangle's vertices see it negative (clockwise) in their frames."""
    x = b.x
    e1 = x[tri[:, 1]] - x[tri[:, 0]]
    e2 = x[tri[:, 2]] - x[tri[:, 0]]
    out = np.zeros(len(tri), dtype=np.int64)
    for k in range(3):
        z = b.z[tri[:, k]]
        p = np.einsum("tm,tmj->tj", e1, z)
        q = np.einsum("tm,tmj->tj", e2, z)
        out += p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0] <= 0
    return out


def _flip_folded(b: _Builder, passes: int = 10) -> None:
    """Flip the longest edge of each folded triangle (negative in two of its vertices'
    frames) with its neighbour across it, where the new edge is not an edge already: an edge
    flip keeps a closed surface closed and coherently oriented ((u, v, w), (v, u, w') become
    (u, w', w), (v, w, w'))."""
    for _ in range(passes):
        tri = np.asarray(b.tri, dtype=np.int64)
        bad = np.flatnonzero(_negative(b, tri) >= 2)
        if not len(bad):
            return
        where = {}
        for t, row in enumerate(tri.tolist()):
            for k in range(3):
                where[(row[k], row[(k + 1) % 3])] = t
        edges = set(where) | {(v, u) for u, v in where}
        for t in bad.tolist():
            row = tri[t].tolist()
            length = [np.linalg.norm(b.x[row[k]] - b.x[row[(k + 1) % 3]]) for k in range(3)]
            k = int(np.argmax(length))
            u, v, w = row[k], row[(k + 1) % 3], row[(k + 2) % 3]
            other = where.get((v, u))
            if other is None or other == t:
                continue
            w2 = next(x for x in tri[other].tolist() if x not in (u, v))
            if w2 == w or (w, w2) in edges:
                continue
            tri[t], tri[other] = (u, w2, w), (v, w, w2)
            b.tri = [(r[0], r[1], r[2]) for r in tri.tolist()]
            break  # the edge maps changed: the next pass rebuilds them


def _result(b: _Builder, message: str) -> Mesh:
    return Mesh(
        vertices=b.x[:b.count].copy(),
        triangles=np.asarray(b.tri, dtype=np.int64).reshape(-1, 3),
        frames=b.z[:b.count].copy(),
        gaps=b.gap[:b.count].copy(),
        fronts=[np.asarray(fr, dtype=np.int64) for fr in b.fronts],
        closed=not b.fronts,
        message=message,
        apexes=np.asarray(b.apexes, dtype=np.int64),
    )


def components(mesh: Mesh) -> list[Mesh]:
    """The connected pieces of a mesh (vertices joined by triangles), each re-indexed; the
    open fronts go with the piece holding them."""
    n = len(mesh.vertices)
    tri = mesh.triangles
    if not len(tri):
        return [mesh]
    rows = np.concatenate([tri[:, 0], tri[:, 1]])
    cols = np.concatenate([tri[:, 1], tri[:, 2]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    used = np.unique(tri)
    out = []
    for k in np.unique(label[used]):
        keep = np.flatnonzero(label == k)
        new = np.full(n, -1, dtype=np.int64)
        new[keep] = np.arange(len(keep))
        mine = label[tri[:, 0]] == k
        fronts = [new[f] for f in mesh.fronts if len(f) and label[f[0]] == k]
        out.append(Mesh(mesh.vertices[keep], new[tri[mine]], mesh.frames[keep], mesh.gaps[keep],
                        fronts, not fronts, mesh.message if fronts else "closed",
                        new[mesh.apexes[label[mesh.apexes] == k]]))
    return out


#: Edge ends within this many (median) edge lengths of a cone's apex's ring (:func:`.cones.
#: cone_fans`) are left out of the tangent-angle check (an edge there leaves the tangent planes by
#: about half its length over the distance to the apex: 60 degrees at 1.3 steps on the pentagon at
#: (2, 1, 1, 1, 1) with one step everywhere); the meshes there are vouched for by the fold check,
#: the links (two cycles at each apex, one elsewhere) and the Morse count with the apexes' terms.
APEX_ZONE = 3.0


def geometry_checks(mesh: Mesh) -> tuple[int, float]:
    """Triangles negative in at least two of their vertices' positive frames (folded), and
    the largest angle between an edge and the tangent planes at its ends (an edge of a mesh
    that follows the surface leaves its tangent planes by about half the step times the
    curvature; unlike the plane of a thin triangle, an edge's direction is well defined)."""
    tri, x = mesh.triangles, mesh.vertices
    if not len(tri):
        return 0, 0.0
    frames = mesh.frames  # (N, M, 2)
    negative = np.zeros(len(tri), dtype=np.int64)
    e1 = x[tri[:, 1]] - x[tri[:, 0]]
    e2 = x[tri[:, 2]] - x[tri[:, 0]]
    for k in range(3):
        z = frames[tri[:, k]]
        a = np.einsum("tm,tmj->tj", e1, z)
        b = np.einsum("tm,tmj->tj", e2, z)
        # an apex's frame means nothing: its triangles are judged in the other two frames
        negative += (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] <= 0) & ~np.isin(tri[:, k],
                                                                            mesh.apexes)
    edges, _ = edges_of(tri)
    d = x[edges[:, 1]] - x[edges[:, 0]]
    length = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
    # an apex has no tangent plane, and a cone's curvature grows as one over the distance to
    # its apex: within APEX_ZONE edges of one the angle says nothing about cutting across
    near_apex = np.zeros(len(x), dtype=bool)
    for a in mesh.apexes:  # its ring's radius (the farthest neighbour) and APEX_ZONE edges
        nbr = np.unique(tri[(tri == a).any(axis=1)])
        reach = float(np.linalg.norm(x[nbr] - x[a], axis=1).max())
        near_apex |= np.linalg.norm(x - x[a], axis=1) <= reach + APEX_ZONE * float(
            np.median(length))
    worst = 0.0
    for end in (0, 1):
        inplane = np.linalg.norm(np.einsum("em,emj->ej", d, frames[edges[:, end]]), axis=1)
        off = np.sqrt(np.maximum(length ** 2 - inplane ** 2, 0.0)) / length
        off[near_apex[edges[:, end]]] = 0.0
        worst = max(worst, float(np.arcsin(np.clip(off, 0.0, 1.0)).max()))
    # a fold shows in the frames of most of a triangle's vertices; a sliver left by a join
    # (its area near zero) may lean across one vertex's frame without any overlap
    return int((negative >= 2).sum()), worst
