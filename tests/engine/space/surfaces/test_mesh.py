"""The marching triangulation: closed 2-manifolds on the constraints, triangles in the tangent
planes, and the topology of planar pentagon spaces against Farber and Schuetz's formula."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from engine.model.budget import Deadline
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.homology import surface_homology
from engine.space.surfaces.mesh import Fan, components, march
from tests.engine.space.surfaces.conftest import pentagon, pentagon_betti
from tests.engine.space.surfaces.test_geometry import fd_jacobian, lengths


def closed_manifold(tri: np.ndarray) -> bool:
    """Every edge in exactly two triangles, once in each direction (coherent orientation),
    and every vertex's link one cycle."""
    directed = Counter((int(a), int(b)) for t in tri for a, b in zip(t, np.roll(t, -1),
                                                                       strict=True))
    if any(n != 1 or directed.get((b, a)) != 1 for (a, b), n in directed.items()):
        return False
    for v in np.unique(tri):
        nxt = {}
        for t in tri[(tri == v).any(axis=1)]:
            k = int(np.flatnonzero(t == v)[0])
            nxt[int(t[(k + 1) % 3])] = int(t[(k + 2) % 3])
        start = next(iter(nxt))
        w, seen = start, 0
        while True:
            w = nxt[w]
            seen += 1
            if w == start:
                break
        if seen != len(nxt):
            return False
    return True


@pytest.mark.parametrize("lengths_", [(1, 1, 1, 1, 1), (1, 1, 2, 2, 3), (1, 2, 2.2, 2.4, 3),
                                      (1, 2, 2, 2, 3.5), (1, 1, 1, 1, 3.5)])
def test_pentagon_spaces_have_the_published_homology(lengths_):
    lk = pentagon(lengths_)
    step = 0.35 * float(np.median(lk.lengths))
    m = march(Surface(lk), lk.coordinates(), step, 60_000)
    assert m.closed, m.message
    h = surface_homology(m.triangles)
    expected = pentagon_betti(lengths_)
    assert h.betti_q == expected and h.betti_z2 == expected
    assert h.orientable
    assert closed_manifold(m.triangles)


def test_vertices_on_the_constraints_and_triangles_in_the_tangent_planes():
    lk = pentagon((1, 1, 1, 1, 1.5))
    m = march(Surface(lk), lk.coordinates(), 0.15, 60_000)
    assert m.closed
    res = np.array([np.abs(lengths(lk, u) - lk.lengths)[lk.active].max() for u in m.vertices])
    assert res.max() <= 1e-9
    x, tri = m.vertices, m.triangles
    # the tangent planes from finite differences: the null space of the lengths' Jacobian
    tangent = np.array([np.linalg.svd(fd_jacobian(lk, u))[2][-2:].T for u in x])  # (N, M, 2)
    e = np.stack([x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]], axis=2)
    plane = np.linalg.qr(e)[0]  # (T, M, 2)
    cos = np.stack([np.linalg.svd(np.einsum("tmi,tmj->tij", plane, tangent[tri[:, k]]),
                                  compute_uv=False)[:, -1] for k in range(3)])
    worst = float(np.degrees(np.arccos(np.clip(cos.min(), -1.0, 1.0))))
    # the angle grows as the step times the curvature (65 degrees at step 0.25)
    assert worst < 45.0
    assert len(tri) == 2 * (len(x) - 2 + 2 * 4)  # closed genus 4: F = 2 (V - chi)


def test_refining_leaves_the_topology_unchanged():
    lk = pentagon((1, 1, 2, 2, 3))
    homs = []
    for step in (0.8, 0.5, 0.35):
        m = march(Surface(lk), lk.coordinates(), step, 60_000)
        assert m.closed
        homs.append((surface_homology(m.triangles).betti_q, len(m.triangles)))
    assert {h for h, _ in homs} == {(1, 4, 1)}
    assert homs[0][1] < homs[1][1] < homs[2][1]


def test_budget_and_deadline_leave_open_fronts():
    lk = pentagon((1, 1, 1, 1, 1))
    m = march(Surface(lk), lk.coordinates(), 0.3, 200)
    assert not m.closed and m.fronts and "budget" in m.message
    assert 200 <= len(m.triangles) < 220
    m = march(Surface(lk), lk.coordinates(), 0.3, 10_000, Deadline.after(0.0))
    assert not m.closed and "deadline" in m.message and len(m.triangles) == 6


def test_components_part_a_mesh_and_keep_each_closed():
    """Two meshes side by side in one (the second's indices shifted) part into the two, each
    re-indexed, with the same topology and vertices."""
    a = march(Surface(pentagon((1, 1, 1, 1, 1))), pentagon((1, 1, 1, 1, 1)).coordinates(), 0.5,
              60_000)
    shifted = type(a)(np.vstack([a.vertices, a.vertices + 10.0]),
                      np.vstack([a.triangles, a.triangles + len(a.vertices)]),
                      np.concatenate([a.frames, a.frames]), np.concatenate([a.gaps, a.gaps]),
                      [], True, "closed")
    parts = components(shifted)
    assert len(parts) == 2
    for k, part in enumerate(parts):
        assert part.closed and np.array_equal(part.triangles, a.triangles)
        assert np.allclose(part.vertices, a.vertices + 10.0 * k)
        assert surface_homology(part.triangles).betti_q == pentagon_betti((1, 1, 1, 1, 1))


def test_a_graded_fan_keeps_the_topology_and_grades_the_edges():
    """A fan (mesh.Fan) around a regular point of the equilateral pentagon's space, its step
    0.3 times the distance to that point up to 0.3: a closed surface of genus 4 as with one
    step, each edge near the point about as long as the graded step at its ends (between a
    third and three times), and more triangles than with one step."""
    lk = pentagon((1, 1, 1, 1, 1))
    s = Surface(lk)
    u0 = lk.coordinates()
    frame = s.frame(u0).basis
    ring = np.array([s.project(u0 + 0.1 * frame @ [np.cos(t), np.sin(t)])[0]
                     for t in np.arange(10) * 2 * np.pi / 10])
    m = march(s, None, 0.3, 60_000, fans=[Fan(u0, [ring], 0.3)])
    plain = march(s, u0, 0.3, 60_000)
    assert m.closed and closed_manifold(m.triangles) and m.apexes.tolist() == [0]
    assert surface_homology(m.triangles).betti_q == pentagon_betti((1, 1, 1, 1, 1))
    assert len(m.triangles) > len(plain.triangles)
    x, tri = m.vertices, m.triangles
    edges = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]),
                              axis=1), axis=0)
    edges = edges[(edges != 0).all(axis=1)]  # not the fan's spokes
    r = np.linalg.norm(x - u0, axis=1)
    size = np.minimum(0.3, np.maximum(0.3 * r, 0.5 * 0.3 * 0.1))  # the graded step
    length = np.linalg.norm(x[edges[:, 1]] - x[edges[:, 0]], axis=1)
    near = r[edges].max(axis=1) < 0.6
    expect = size[edges].mean(axis=1)
    assert near.sum() > 50
    assert np.all((length[near] > expect[near] / 3) & (length[near] < 3 * expect[near]))
