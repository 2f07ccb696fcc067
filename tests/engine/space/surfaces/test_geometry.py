"""Tangent frames and projection onto a D = 2 configuration surface, against finite
differences of the bar lengths."""

from __future__ import annotations

import numpy as np
import pytest

from engine.model.linkage import BarSpec, VertexSpec, build_linkage
from engine.space.surfaces.geometry import Surface
from tests.engine.space.surfaces.conftest import pentagon, slider_torus, sphere_3d


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


def test_curvature_of_a_sphere_and_of_a_flat_torus():
    """Closed forms: the sphere of radius R has normal curvature 1 / R in every direction; two
    independent pendula of radii a and b sweep a flat torus in R^4 whose normal curvature along
    ``cos t e_a + sin t e_b`` is ``sqrt(cos^4 t / a^2 + sin^4 t / b^2)``, largest ``1 / min(a,
    b)``."""
    s = Surface(sphere_3d(1.3))
    rng = np.random.default_rng(5)
    pts = [s.project(s.linkage.coordinates() + 0.5 * rng.normal(size=3))[0] for _ in range(5)]
    assert np.allclose(s.curvatures(np.array(pts)), 1 / 1.3, rtol=1e-9)
    vs = [VertexSpec("P", (0, 0), True), VertexSpec("Q", (5, 0), True),
          VertexSpec("A", (0.3, 0.4)), VertexSpec("B", (5, 2))]
    torus = Surface(build_linkage(2, vs, [BarSpec("a", ("P", "A")), BarSpec("b", ("Q", "B"))]))
    assert np.allclose(torus.curvatures(torus.linkage.coordinates()[None]), 1 / 0.5,
                       rtol=1e-9)


def quadrilateral_point(lengths, phi, theta):
    """The spatial quadrilateral of tests/service/test_spatial_polygons.py written as a map of
    two angles (``v2`` on its circle in the plane, ``v3`` on the circle where two spheres
    meet): its free coordinates ``(v2x, v2y, v3x, v3y, v3z)``."""
    l1, l2, l3, l4 = lengths
    v2 = np.array([l1 + l2 * np.cos(phi), l2 * np.sin(phi), 0.0])
    d = np.linalg.norm(v2)
    e = v2 / d
    x = (l4 ** 2 - l3 ** 2 + d ** 2) / (2 * d)
    r = np.sqrt(l4 ** 2 - x ** 2)
    n1 = np.array([-e[1], e[0], 0.0])
    v3 = x * e + r * (np.cos(theta) * n1 + np.sin(theta) * np.array([0.0, 0.0, 1.0]))
    return np.concatenate([v2[:2], v3])


def test_curvature_against_a_parametrisation():
    """The largest normal curvature against finite differences of a parametrisation written
    here: ``|P_N r_ww| / |r_w|^2`` over directions ``w`` of the parameters (``P_N``: onto the
    normal space, the complement of ``r_phi, r_theta``)."""
    lengths = (1.0, 0.6, 0.8, 0.6)
    h = 1e-4
    for phi, theta in ((2.2, 0.3), (2.6, 1.9), (3.5, 4.0)):
        u = quadrilateral_point(lengths, phi, theta)
        r_p = (quadrilateral_point(lengths, phi + h, theta)
               - quadrilateral_point(lengths, phi - h, theta)) / (2 * h)
        r_t = (quadrilateral_point(lengths, phi, theta + h)
               - quadrilateral_point(lengths, phi, theta - h)) / (2 * h)
        tangent = np.linalg.qr(np.stack([r_p, r_t], axis=1))[0]
        best = 0.0
        for w in np.linspace(0, np.pi, 360, endpoint=False):
            dp, dt = np.cos(w), np.sin(w)
            f = [quadrilateral_point(lengths, phi + k * h * dp, theta + k * h * dt)
                 for k in (-1, 0, 1)]
            r_w = (f[2] - f[0]) / (2 * h)
            r_ww = (f[2] - 2 * f[1] + f[0]) / h ** 2
            normal = r_ww - tangent @ (tangent.T @ r_ww)
            best = max(best, float(np.linalg.norm(normal) / (r_w @ r_w)))
        vs = [VertexSpec("v0", (0, 0, 0), True), VertexSpec("v1", (1.0, 0, 0), True),
              VertexSpec("v2", (u[0], u[1], 0.0), (False, False, True)),
              VertexSpec("v3", tuple(u[2:]))]
        bs = [BarSpec("l2", ("v1", "v2"), 0.6), BarSpec("l3", ("v2", "v3"), 0.8),
              BarSpec("l4", ("v3", "v0"), 0.6)]
        s = Surface(build_linkage(3, vs, bs))
        assert s.curvatures(u[None])[0] == pytest.approx(best, rel=1e-3)
