"""Meshes moved onto a nearby linkage's surface: the vertices on the new lengths, the frames
tangent, orthonormal and positive (against the SVD one point at a time), a five-bar's mesh
moved across a small change judged complete by the surface search with the dense grid's
Euler characteristic, and a mesh not moved across a critical value."""

from __future__ import annotations

import numpy as np

from engine.model.constraints import Constraints
from engine.space.surfaces.explore import SurfaceOptions, explore_surfaces
from engine.space.surfaces.geometry import Surface
from engine.space.surfaces.transport import MOVE_MAX, frames_many, project_many, transport
from tests.engine.space.surfaces.conftest import (
    five_bar,
    five_bar_reference,
    pentagon,
    pentagon_betti,
    sphere_3d,
)


def test_projected_vertices_and_frames():
    lk = pentagon((1.0, 1.0, 1.0, 1.0, 1.0))
    surface = Surface(lk, Constraints(lk))
    rng = np.random.default_rng(0)
    start = lk.coordinates() + 0.02 * rng.normal(size=(40, 6))
    x, ok = project_many(surface, start)
    assert ok.all()
    for u in x:
        assert surface.cons.max_residual(u) <= surface.atol
    frames, gaps = frames_many(surface, x)
    for u, z, gap in zip(x, frames, gaps, strict=True):
        jac = surface.jacobian(u)
        assert np.abs(jac @ z).max() < 1e-10  # tangent
        assert np.allclose(z.T @ z, np.eye(2), atol=1e-12)  # orthonormal
        assert np.linalg.det(np.vstack([jac, z.T])) > 0  # positive
        one = surface.frame(u)
        assert np.isclose(gap, one.gap, rtol=1e-10)
        # the same oriented plane as the frame taken one point at a time
        assert np.allclose(z @ z.T, one.basis @ one.basis.T, atol=1e-10)
        assert np.isclose(np.linalg.det(z.T @ one.basis), 1.0, atol=1e-10)


def test_a_mesh_moved_across_a_small_change_is_judged_complete():
    lengths = (2.0, 1.0, 1.4, 1.6, 1.0)
    opt = SurfaceOptions(step_rel=0.4)
    first = explore_surfaces(five_bar(*lengths), options=opt)
    assert first.search.complete
    moved_lk = five_bar(*lengths)
    moved_lk = moved_lk.with_lengths(moved_lk.lengths + np.array([0.0, 2e-3, 0.0, 0.0]))
    surface = Surface(moved_lk, Constraints(moved_lk))
    step = float(first.search["step"])
    meshes = [transport(surface, c.vertices, c.triangles, step) for c in first.components]
    assert all(m is not None for m in meshes)
    res = explore_surfaces(moved_lk, options=opt, start_on_space=False,
                           meshes=[m for m in meshes if m is not None])
    chi, comps = five_bar_reference(2.0, 1.0, 1.4 + 2e-3, 1.6, 1.0)
    assert res.search.complete and res.search.argument == "proved"
    assert len(res.components) == comps
    assert sum(c.homology.euler for c in res.components) == chi
    for m, c in zip(meshes, res.components, strict=False):
        assert m is not None and np.array_equal(m.vertices, c.vertices)  # none marched anew
        for u in c.vertices:
            assert surface.cons.max_residual(u) <= surface.atol


def test_too_long_a_move_is_refused():
    lk = sphere_3d(1.3)
    res = explore_surfaces(lk)
    comp = res.components[0]
    step = float(res.search["step"])
    bigger = lk.with_lengths(lk.lengths * (1.0 + 2 * MOVE_MAX * step / 1.3))
    assert transport(Surface(bigger), comp.vertices, comp.triangles, step) is None
    close = lk.with_lengths(lk.lengths * 1.001)
    moved = transport(Surface(close), comp.vertices, comp.triangles, step)
    assert moved is not None and moved.closed
    assert np.allclose(np.linalg.norm(moved.vertices, axis=1), 1.3 * 1.001)


def test_a_mesh_is_not_moved_across_a_critical_value():
    """The pentagon at (2, 1, 1, 1, 1) + 0.1 in one bar and - 0.1: different topology
    (Farber and Schuetz); the first side's mesh is not moved onto the second (its necks would
    have to move by several steps)."""
    base = np.array([2.0, 1.0, 1.0, 1.0, 1.0])
    d_l = np.array([0.0, 0.1, 0.0, 0.0, 0.0])
    plus, minus = tuple(base + d_l), tuple(base - d_l)
    assert pentagon_betti(plus) != pentagon_betti(minus)
    first = explore_surfaces(pentagon(plus))
    assert first.search.complete
    lk = pentagon(minus)
    step = float(first.search["step"])
    surface = Surface(lk, Constraints(lk))
    moved = [transport(surface, c.vertices, c.triangles, step) for c in first.components]
    assert any(m is None for m in moved)
