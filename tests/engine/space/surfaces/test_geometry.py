"""Tangent frames and projection onto a D = 2 configuration surface, against finite
differences of the bar lengths."""

from __future__ import annotations

import numpy as np

from engine.space.surfaces.geometry import Surface
from tests.engine.space.surfaces.conftest import pentagon, slider_torus


def lengths(linkage, u):
    pos = linkage.positions_of(u)
    return np.linalg.norm(pos[linkage.ends[:, 0]] - pos[linkage.ends[:, 1]], axis=1)


def fd_jacobian(linkage, u, h=1e-7):
    return np.stack([(lengths(linkage, u + h * e) - lengths(linkage, u - h * e)) / (2 * h)
                     for e in np.eye(len(u))], axis=1)[linkage.active]


def test_frame_spans_the_tangent_plane_and_is_positive():
    for lk in (pentagon((1, 1, 1, 1, 1)), slider_torus()):
        s = Surface(lk)
        u = lk.coordinates()
        fr = s.frame(u)
        z = fr.basis
        assert np.allclose(z.T @ z, np.eye(2), atol=1e-12)
        # tangent to every bar length (finite differences, not the engine's Jacobian)
        assert np.abs(fd_jacobian(lk, u) @ z).max() < 1e-6
        assert np.linalg.det(np.vstack([s.jacobian(u), z.T])) > 0
        assert 0 < fr.gap <= 1


def test_orientation_is_continuous_along_a_path():
    """Moving along the surface, the positive frame turns continuously: consecutive frames
    (projected into each other) keep the sign of their determinant."""
    lk = pentagon((1, 1, 1, 1, 1))
    s = Surface(lk)
    u = lk.coordinates()
    z = s.frame(u).basis
    for _ in range(200):
        u, ok = s.project(u + 0.02 * z[:, 0])
        assert ok
        z_new = s.frame(u).basis
        assert np.linalg.det(z.T @ z_new) > 0.9
        z = z_new


def test_projection_lands_on_the_lengths():
    lk = pentagon((1, 1, 2, 2, 3))
    s = Surface(lk)
    rng = np.random.default_rng(3)
    u0 = lk.coordinates()
    for _ in range(10):
        u, ok = s.project(u0 + 0.1 * rng.normal(size=len(u0)))
        assert ok
        assert np.abs(lengths(lk, u) - lk.lengths)[lk.active].max() <= 1e-9
