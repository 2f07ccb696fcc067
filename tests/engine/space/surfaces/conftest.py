"""Linkages with two degrees of freedom, and independent references for their topology."""

from __future__ import annotations

from itertools import combinations

import numpy as np
from scipy.optimize import minimize
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from engine.model.constraints import project
from engine.model.linkage import BarSpec, Linkage, VertexSpec, build_linkage
from engine.model.tolerances import Tolerances


def on_space(linkage: Linkage) -> Linkage:
    res = project(linkage, Tolerances())
    return linkage.with_positions(res.positions)


def pentagon(lengths: tuple[float, ...]) -> Linkage:
    """A planar pentagon P0 P1 A B C with the bar P0 P1 (``lengths[0]``) pinned; the others
    in order P1 A, A B, B C, C P0. Starts near a convex pentagon and is projected."""
    pts = [np.zeros(2), np.array([lengths[0], 0.0])]
    th = 0.0
    for k in range(3):
        th += 2 * np.pi / 5
        pts.append(pts[-1] + lengths[k + 1] * np.array([np.cos(th), np.sin(th)]))
    ids = ["P0", "P1", "A", "B", "C"]
    vs = [VertexSpec(i, tuple(p), i in ("P0", "P1")) for i, p in zip(ids, pts, strict=True)]
    ends = [("P0", "P1"), ("P1", "A"), ("A", "B"), ("B", "C"), ("C", "P0")]
    bs = [BarSpec(f"b{i}", e, float(x)) for i, (e, x) in enumerate(zip(ends, lengths,
                                                                        strict=True))]
    return on_space(build_linkage(2, vs, bs))


def pentagon_betti(lengths: tuple[float, ...]) -> tuple[int, int, int]:
    """Farber and Schuetz, *Homology of planar polygon spaces* (Geom. Dedicata 125, 2007),
    Thm. 1: for generic lengths the space of planar n-gons modulo orientation-preserving
    isometries has ``b_i = a_i + a_{n-3-i}``, ``a_i`` the number of short subsets of size
    ``i + 1`` holding a fixed longest side (short: less than half the perimeter)."""
    n = len(lengths)
    longest = int(np.argmax(lengths))
    total = sum(lengths)
    others = [k for k in range(n) if k != longest]

    def a(i: int) -> int:
        return sum(1 for sub in combinations(others, i)
                   if lengths[longest] + sum(lengths[k] for k in sub) < total / 2)

    return tuple(a(i) + a(n - 3 - i) for i in range(n - 2))  # type: ignore[return-value]


def five_bar(ground: float, l1: float, l2: float, l3: float, l4: float) -> Linkage:
    """Pins P0 = (0, 0), P4 = (ground, 0); cranks P0 A (l1), P4 C (l4); coupler A B (l2),
    B C (l3). Started where the two circles of B meet."""
    for t1 in np.linspace(0.3, 6.0, 40):
        for t2 in np.linspace(0.3, 6.0, 40):
            a = l1 * np.array([np.cos(t1), np.sin(t1)])
            c = np.array([ground, 0.0]) + l4 * np.array([np.cos(t2), np.sin(t2)])
            d = float(np.linalg.norm(c - a))
            if abs(l2 - l3) + 0.05 < d < l2 + l3 - 0.05:
                x = (d ** 2 + l2 ** 2 - l3 ** 2) / (2 * d)
                y = np.sqrt(l2 ** 2 - x ** 2)
                e = (c - a) / d
                b = a + x * e + y * np.array([-e[1], e[0]])
                vs = [VertexSpec("P0", (0.0, 0.0), True), VertexSpec("P4", (ground, 0.0), True),
                      VertexSpec("A", tuple(a)), VertexSpec("B", tuple(b)),
                      VertexSpec("C", tuple(c))]
                bs = [BarSpec("L1", ("P0", "A")), BarSpec("L2", ("A", "B")),
                      BarSpec("L3", ("B", "C")), BarSpec("L4", ("P4", "C"))]
                return build_linkage(2, vs, bs)
    raise AssertionError("no assembly")


def five_bar_reference(ground: float, l1: float, l2: float, l3: float, l4: float,
                       n: int = 360) -> tuple[int, int]:
    """Euler characteristic and component count of the five-bar's configuration space from a
    dense grid of the crank angles: the space is the double cover of the region
    ``R = {(t1, t2): |l2 - l3| <= |A - C| <= l2 + l3}`` of the torus, branched along its
    boundary circles (B is one of the two intersections of two circles), so
    ``chi = 2 chi(R)``; ``chi(R)`` is that of the grid's cubical complex (grid points in R,
    their edges and squares, periodic), and each component of R with a boundary is one
    component (the whole torus would be two). Needs ``l2 != l3`` (where they are equal the
    circles of B coincide at ``A = C``: a whole circle of B over one point of R)."""
    assert l2 != l3
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    t1, t2 = np.meshgrid(t, t, indexing="ij")
    ax, ay = l1 * np.cos(t1), l1 * np.sin(t1)
    cx, cy = ground + l4 * np.cos(t2), l4 * np.sin(t2)
    d = np.hypot(cx - ax, cy - ay)
    inside = (d >= abs(l2 - l3)) & (d <= l2 + l3)
    right, up = np.roll(inside, -1, 0), np.roll(inside, -1, 1)
    diag = np.roll(right, -1, 1)
    v = int(inside.sum())
    e = int((inside & right).sum() + (inside & up).sum())
    f = int((inside & right & up & diag).sum())
    chi_r = v - e + f
    # components of R on the torus (4-neighbour union-find, periodic)
    parent = np.arange(n * n)

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    idx = np.arange(n * n).reshape(n, n)
    for nb, ok in ((np.roll(idx, -1, 0), inside & right), (np.roll(idx, -1, 1), inside & up)):
        for i, j in zip(idx[ok].tolist(), nb[ok].tolist(), strict=True):
            ri, rj = find(i), find(j)
            if ri != rj:
                parent[ri] = rj
    roots = {find(i) for i in idx[inside].tolist()}
    comps = len(roots) * (2 if inside.all() else 1)
    return 2 * chi_r, comps


def sphere_3d(radius: float = 1.3) -> Linkage:
    """One bar from a pin in 3D: its free end moves on a sphere."""
    vs = [VertexSpec("P", (0.0, 0.0, 0.0), True), VertexSpec("A", (radius, 0.0, 0.0))]
    return build_linkage(3, vs, [BarSpec("r", ("P", "A"))])


def slider_torus() -> Linkage:
    """3D, D = 2: A on a sphere (bar to the pin P), B sliding in the plane z = 0 on a circle
    about the pin Q, and the bar A B. For every B the spheres about P and B meet in a circle
    (|1.2 - 2.2| < |P - B| in [1.7, 3.3] < 1.2 + 2.2): a circle bundle over a circle, an
    orientable one (a regular level set): a torus."""
    q = np.array([2.5, 0.0, 0.0])
    b = q + np.array([0.8, 0.0, 0.0])
    # A on both spheres: |A| = 1.2, |A - B| = 2.2
    x = (1.2 ** 2 - 2.2 ** 2 + 3.3 ** 2) / (2 * 3.3)
    a = np.array([x, np.sqrt(1.2 ** 2 - x ** 2), 0.0])
    vs = [VertexSpec("P", (0.0, 0.0, 0.0), True), VertexSpec("Q", tuple(q), True),
          VertexSpec("A", tuple(a)), VertexSpec("B", tuple(b), (False, False, True))]
    bs = [BarSpec("PA", ("P", "A"), 1.2), BarSpec("QB", ("Q", "B"), 0.8),
          BarSpec("AB", ("A", "B"), 2.2)]
    return build_linkage(3, vs, bs)


def _on_circle(pole: np.ndarray, chord: float, angles: np.ndarray) -> np.ndarray:
    """Points (N, 3) of the unit sphere at ``chord`` from ``pole`` (on it), at ``angles``
    about the axis through ``pole``."""
    u = np.cross(pole, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    v = np.cross(pole, u)
    alpha = 2 * np.arcsin(chord / 2)
    return np.cos(alpha) * pole + np.sin(alpha) * (np.cos(angles)[:, None] * u
                                                   + np.sin(angles)[:, None] * v)


def _sphere_pins(g: float) -> tuple[np.ndarray, np.ndarray]:
    gamma = 2 * np.arcsin(g / 2)
    return np.array([1.0, 0.0, 0.0]), np.array([np.cos(gamma), np.sin(gamma), 0.0])


def _middle(a: np.ndarray, c: np.ndarray, l2: float, l3: float
            ) -> tuple[np.ndarray, np.ndarray]:
    """Where the unit sphere and the spheres of radii ``l2`` about ``a`` and ``l3`` about ``c``
    (a, c (..., 3) on the unit sphere) meet: ``B = x a + y c + t (a x c)`` with ``B . a = 1 -
    l2^2 / 2``, ``B . c = 1 - l3^2 / 2``; the point with ``t >= 0`` and ``t^2`` (negative:
    no point)."""
    ac = np.sum(a * c, axis=-1)
    h1, h2 = 1 - l2 ** 2 / 2, 1 - l3 ** 2 / 2
    det = 1 - ac ** 2
    x, y = (h1 - ac * h2) / det, (h2 - ac * h1) / det
    t2 = (1 - (x * x + y * y + 2 * x * y * ac)) / det  # |a x c|^2 = det
    t = np.sqrt(np.maximum(t2, 0.0))
    return x[..., None] * a + y[..., None] * c + t[..., None] * np.cross(a, c), t2


def spherical_five_bar(g: float, l1: float, l2: float, l3: float, l4: float,
                       pin_b: str = "O") -> Linkage:
    """The spherical five-bar (unit sphere): ``O`` the centre, ``G1 = (1, 0, 0)`` and ``G2`` (in
    the plane z = 0, chord ``g`` from ``G1``) pinned; ``A``, ``B``, ``C`` on the sphere (bars
    ``OA``, ``OB``, ``OC``; ``pin_b`` replaces ``O`` as the pin of ``B``'s third bar), crank
    ``L1`` (``G1-A``), couplers ``L2`` (``A-B``), ``L3`` (``B-C``), crank ``L4`` (``G2-C``): every
    length is a chord. Started at the first crank angles (a grid) where ``B`` is real."""
    g1, g2 = _sphere_pins(g)
    t = np.linspace(0.1, 6.2, 48)
    a, c = _on_circle(g1, l1, t)[:, None], _on_circle(g2, l4, t)[None, :]
    a, c = np.broadcast_to(a, (48, 48, 3)), np.broadcast_to(c, (48, 48, 3))
    b, t2 = _middle(a, c, l2, l3)
    i, j = np.argwhere(t2 > 1e-3)[0]
    pins = {"O": np.zeros(3), "G1": g1, "G2": g2}
    pos = pins | {"A": a[i, j], "B": b[i, j], "C": c[i, j]}
    vs = [VertexSpec(k, tuple(p), k in pins) for k, p in pos.items()]
    bs = [BarSpec("OA", ("O", "A")), BarSpec("OB", (pin_b, "B")), BarSpec("OC", ("O", "C")),
          BarSpec("L1", ("G1", "A")), BarSpec("L2", ("A", "B")), BarSpec("L3", ("B", "C")),
          BarSpec("L4", ("G2", "C"))]
    return build_linkage(3, vs, bs)


def spherical_five_bar_reference(g: float, l1: float, l2: float, l3: float, l4: float,
                                 n: int = 400) -> list[int]:
    """The Euler characteristics (sorted) of the spherical five-bar's components from a dense
    grid of its crank angles, with ``B`` where three spheres meet: the space is the double
    cover of the region ``R`` of the torus where ``B`` is real, branched along its boundary
    circles, so each component of ``R`` with a boundary is one component of ``chi = 2
    chi(R_k)`` (the cubical complex of the grid points in ``R_k``, periodic), and ``R`` the
    whole torus is two (the two sides of the plane ``O A C`` never meet)."""
    g1, g2 = _sphere_pins(g)
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    a, c = _on_circle(g1, l1, t)[:, None], _on_circle(g2, l4, t)[None, :]
    inside = _middle(np.broadcast_to(a, (n, n, 3)), np.broadcast_to(c, (n, n, 3)), l2, l3)[1] >= 0
    right, up = np.roll(inside, -1, 0), np.roll(inside, -1, 1)
    idx = np.arange(n * n).reshape(n, n)
    rows = np.concatenate([idx[inside & right], idx[inside & up]])
    cols = np.concatenate([np.roll(idx, -1, 0)[inside & right], np.roll(idx, -1, 1)[inside & up]])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n * n, n * n))
    label = connected_components(graph, directed=False)[1].reshape(n, n)
    square = inside & right & up & np.roll(right, -1, 1)
    chis = []
    for k in np.unique(label[inside]):
        m = label == k
        chis.append(2 * int((m & inside).sum() - (m & inside & right).sum()
                            - (m & inside & up).sum() + (m & square).sum()))
    return sorted(chis * (2 if inside.all() else 1))


def cone_lengths(g: float, l1: float, l2: float, l4: float) -> tuple[tuple[float, ...], float]:
    """``(g, L1, L2, L3, L4)`` with ``L3`` putting ``A``, ``B``, ``C`` on one great circle where
    ``A`` and ``C`` are farthest apart (the largest ``|A - C|^2`` over the crank angles by
    BFGS from a grid of starts, on the cranks' circles computed here): the band's edge
    ``|A - C| = chord(L2) + chord(L3)`` shrinks to that point, a cone. Also that largest
    ``|A - C|^2``."""
    g1, g2 = _sphere_pins(g)

    def minus_s(x: np.ndarray) -> float:
        a, c = _on_circle(g1, l1, x[:1])[0], _on_circle(g2, l4, x[1:])[0]
        return -float(np.sum((a - c) ** 2))

    best = min((minimize(minus_s, [t1, t2], method="BFGS", options={"gtol": 1e-12})
                for t1 in np.linspace(0, 6, 4) for t2 in np.linspace(0, 6, 4)),
               key=lambda r: r.fun)
    chord = np.sqrt(-best.fun)
    l3 = 2 * np.sin(np.arcsin(chord / 2) - np.arcsin(l2 / 2))
    return (g, l1, l2, float(l3), l4), float(-best.fun)
