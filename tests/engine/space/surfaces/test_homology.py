"""Homology of standard triangulations against their known topology (sphere, torus, Klein
bottle, projective plane, disjoint unions), over Z/2 and Q."""

from __future__ import annotations

import numpy as np
import pytest

from engine.space.surfaces.homology import manifold_defects, orientable, surface_homology


def grid_surface(n: int, m: int, twist: bool) -> np.ndarray:
    """The n x m square grid with opposite sides glued (each square cut into two triangles):
    a torus, or a Klein bottle when the gluing across the ``i`` wrap reflects ``j``."""

    def vid(i: int, j: int) -> int:
        if i >= n:
            i -= n
            if twist:
                j = (m - j) % m
        return i * m + (j % m)

    tri = []
    for i in range(n):
        for j in range(m):
            a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
            tri += [(a, b, c), (a, c, d)]
    return np.array(tri)


TETRAHEDRON = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
OCTAHEDRON = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                       [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
#: the six-vertex projective plane (the hemi-icosahedron)
RP2 = np.array([[1, 2, 3], [1, 3, 4], [1, 4, 5], [1, 5, 6], [1, 6, 2], [2, 3, 5], [3, 4, 6],
                [4, 5, 2], [5, 6, 3], [6, 2, 4]]) - 1


@pytest.mark.parametrize(("name", "tri", "euler", "z2", "q", "orient"), [
    ("tetrahedron", TETRAHEDRON, 2, (1, 0, 1), (1, 0, 1), True),
    ("octahedron", OCTAHEDRON, 2, (1, 0, 1), (1, 0, 1), True),
    ("torus", grid_surface(5, 4, False), 0, (1, 2, 1), (1, 2, 1), True),
    ("klein", grid_surface(5, 5, True), 0, (1, 2, 1), (1, 1, 0), False),
    ("rp2", RP2, 1, (1, 1, 1), (1, 0, 0), False),
    ("two spheres", np.vstack([TETRAHEDRON, OCTAHEDRON + 4]), 4, (2, 0, 2), (2, 0, 2), True),
    ("disk", TETRAHEDRON[:3], 1, (1, 0, 0), (1, 0, 0), True),
])
def test_standard_triangulations(name: str, tri: np.ndarray, euler: int, z2: tuple[int, ...],
                                 q: tuple[int, ...], orient: bool) -> None:
    h = surface_homology(tri)
    assert h.euler == euler
    assert h.betti_z2 == z2
    assert h.betti_q == q
    assert h.orientable is orient
    # the Euler characteristic is the alternating sum over either field
    assert sum((-1) ** k * b for k, b in enumerate(h.betti_z2)) == euler
    assert sum((-1) ** k * b for k, b in enumerate(h.betti_q)) == euler


@pytest.mark.parametrize("tri", [TETRAHEDRON, OCTAHEDRON, RP2, grid_surface(5, 4, False),
                                 grid_surface(5, 5, True)])
def test_closed_surfaces_have_no_defects(tri: np.ndarray) -> None:
    assert manifold_defects(tri) == {"open_edges": 0, "branched_edges": 0,
                                     "pinched_vertices": 0, "repeated_triangles": 0}


def test_defects_are_found() -> None:
    assert manifold_defects(TETRAHEDRON[:3])["open_edges"] == 3
    # three triangles on one edge
    fan = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]])
    assert manifold_defects(fan)["branched_edges"] == 1
    # two tetrahedra sharing a vertex: closed, but the vertex's link is two cycles
    pinched = np.vstack([TETRAHEDRON, np.where(TETRAHEDRON == 0, 0, TETRAHEDRON + 3)])
    d = manifold_defects(pinched)
    assert d["pinched_vertices"] == 1 and d["open_edges"] == 0
    assert manifold_defects(np.vstack([TETRAHEDRON, TETRAHEDRON[:1]]))["repeated_triangles"] == 1


def test_orientation_flip_does_not_matter() -> None:
    flipped = TETRAHEDRON.copy()
    flipped[1] = flipped[1][::-1]
    assert orientable(flipped)


def test_genus_of_large_grids() -> None:
    """A fine torus and a genus-2 surface (two tori joined along a removed triangle each)."""
    torus = grid_surface(40, 30, False)
    h = surface_homology(torus)
    assert (h.betti_z2, h.betti_q, h.genus) == ((1, 2, 1), (1, 2, 1), 1)
    a, b = grid_surface(6, 6, False), grid_surface(6, 6, False) + 36
    # remove a triangle from each and glue the two boundaries
    ta, tb = a[0], b[0]
    glue = {int(tb[0]): int(ta[0]), int(tb[1]): int(ta[2]), int(tb[2]): int(ta[1])}
    b2 = np.vectorize(lambda v: glue.get(int(v), int(v)))(b[1:])
    g2 = surface_homology(np.vstack([a[1:], b2]))
    assert (g2.euler, g2.betti_q, g2.orientable, g2.genus) == (-2, (1, 4, 1), True, 2)


def dense_ranks(tri: np.ndarray) -> tuple[int, int]:
    """``rank d2`` over Z/2 and over Q from the dense boundary matrix (an independent
    reference: Gaussian elimination mod 2 and a floating-point rank of small integer
    matrices)."""
    pairs = {}
    cols = []
    for t in tri.tolist():
        col = {}
        for j in range(3):
            a, b = t[j], t[(j + 1) % 3]
            key = (min(a, b), max(a, b))
            pairs.setdefault(key, len(pairs))
            col[pairs[key]] = 1 if a < b else -1
        cols.append(col)
    d2 = np.zeros((len(pairs), len(tri)), dtype=np.int64)
    for k, col in enumerate(cols):
        for r, v in col.items():
            d2[r, k] = v
    m = (d2 % 2).astype(np.uint8)
    rank2, row = 0, 0
    for c in range(m.shape[1]):
        hit = np.flatnonzero(m[row:, c]) + row if row < m.shape[0] else np.zeros(0, int)
        if not len(hit):
            continue
        m[[row, hit[0]]] = m[[hit[0], row]]
        below = np.flatnonzero(m[:, c])
        below = below[below != row]
        m[below] ^= m[row]
        row += 1
        rank2 += 1
    return rank2, int(np.linalg.matrix_rank(d2.astype(float)))


def scrambled(tri: np.ndarray, seed: int) -> np.ndarray:
    """The same complex with its vertices renumbered, its triangles shuffled and some of them
    reversed (the homology does not change)."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(int(tri.max()) + 1)
    out = perm[tri][rng.permutation(len(tri))]
    flip = rng.random(len(out)) < 0.5
    out[flip] = out[flip][:, ::-1]
    return out


PINCHED_SPHERES = np.vstack([TETRAHEDRON, np.where(TETRAHEDRON == 0, 0, TETRAHEDRON + 3)])


def pinched_torus(n: int = 5) -> np.ndarray:
    """A sphere (a cylinder of three rings of ``n`` vertices capped by two poles) with its two
    poles made one vertex (as a cone's apex joins its two nappes): ``S^2 v S^1``, Betti
    numbers (1, 1, 1) over any field."""
    ring = [np.arange(n) + k * n for k in range(3)]
    pole = 3 * n
    tri = []
    for k in range(2):
        for j in range(n):
            a, b = ring[k][j], ring[k][(j + 1) % n]
            c, d = ring[k + 1][(j + 1) % n], ring[k + 1][j]
            tri += [(a, b, c), (a, c, d)]
    for j in range(n):
        tri += [(pole, ring[0][(j + 1) % n], ring[0][j]),
                (pole, ring[2][j], ring[2][(j + 1) % n])]
    return np.array(tri)


@pytest.mark.parametrize(("name", "tri", "z2", "q", "orient"), [
    # every edge in two triangles: the fast ranks (sphere v sphere, the pinched torus)
    ("two spheres at a point", PINCHED_SPHERES, (1, 0, 2), (1, 0, 2), True),
    ("pinched torus", pinched_torus(), (1, 1, 1), (1, 1, 1), True),
    ("klein and sphere", np.vstack([grid_surface(5, 5, True), TETRAHEDRON + 25]),
     (2, 2, 2), (2, 1, 1), False),
    ("rp2 at a point of a torus", np.vstack([RP2, np.where(grid_surface(4, 4, False) == 0, 0,
                                                           grid_surface(4, 4, False) + 6)]),
     (1, 3, 2), (1, 2, 1), False),
])
def test_surfaces_with_paired_edges(name: str, tri: np.ndarray, z2: tuple[int, ...],
                                    q: tuple[int, ...], orient: bool) -> None:
    """Complexes with every edge in two triangles (pinched or in several pieces) against the
    dense ranks and the wedge sums' known homology."""
    h = surface_homology(tri)
    v = len(np.unique(tri))
    rank2, rank_q = dense_ranks(tri)
    assert h.betti_z2[2] == h.triangles - rank2 and h.betti_q[2] == h.triangles - rank_q
    assert h.betti_z2[0] == h.betti_q[0]
    assert h.euler == v - h.edges + h.triangles
    assert manifold_defects(tri)["open_edges"] == manifold_defects(tri)["branched_edges"] == 0
    assert (h.betti_z2, h.betti_q, h.orientable) == (z2, q, orient)


@pytest.mark.parametrize("seed", range(6))
def test_paired_ranks_against_dense_elimination(seed: int) -> None:
    """Scrambled closed surfaces (orientable and not, several pieces, pinched) against the
    dense reference, over both fields, and orientability against the coherent-orientation
    search."""
    bases = [grid_surface(4, 5, False), grid_surface(5, 5, True), RP2, OCTAHEDRON,
             PINCHED_SPHERES, np.vstack([pinched_torus(4), RP2 + 13])]
    tri = scrambled(bases[seed], seed)
    h = surface_homology(tri)
    rank2, rank_q = dense_ranks(tri)
    assert (h.betti_z2[2], h.betti_q[2]) == (h.triangles - rank2, h.triangles - rank_q)
    assert h.orientable is orientable(tri)
