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
