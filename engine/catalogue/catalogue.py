"""Catalogue of frameworks for 3D and rigidity theory, registered as presets.

Each entry is a classical example whose first- and second-order behaviour is known, so that
prestress stability and second-order rigidity (:mod:`engine.local.prestress`) can be tried on it.
Nothing is pinned except in the rotor chain: rigid motions are quotiented out by the analysis.

- ``tetrahedron`` (3D): regular, edge ``a``. First-order rigid.
- ``octahedron`` (3D): regular (vertices ``+-a`` on the axes). First-order rigid (Dehn).
- ``bricard-line`` (3D): Bricard's line-symmetric flexible octahedron (type I): vertices
  ``0 = (x0, 0, 0)``, ``2 = (x2, y2, z2)``, ``4 = (x4, y4, z4)`` and their images under the half
  turn about the z-axis (``1, 3, 5``); opposite pairs ``0-1``, ``2-3``, ``4-5`` are not joined.
- ``bricard-plane`` (3D): Bricard's plane-symmetric flexible octahedron (type II): ``0 = (0, y0,
  z0)`` and ``1 = (0, y1, z1)`` in the mirror ``x = 0``, ``2 = (x2, 0, 0)``, ``4 = (x4, y4, 0)``
  and their mirror images ``3, 5``. (Type III has a realisation only with flat poses to pass
  through; it is not included.)
- ``three-prism`` (2D): triangles ``a0 a1 a2 = (0,0), (2,0), (1,2)`` and ``b_i = ratio R(twist)
  a_i + (dx, dy)``, legs ``a_i-b_i``. With ``twist = 0`` the legs are concurrent (Desargues):
  infinitesimally flexible; ``twist != 0`` is generic (first-order rigid).
- ``three-prism-flexible`` (2D): the same with ``ratio = 1, twist = 0``: the legs are parallel and
  equal and the prism flexes (a continuous family of parallelograms).
- ``k33-conic`` (2D): K(3,3) with its six vertices on the ellipse ``(x/rx)^2 + (y/ry)^2 = 1``
  (angles alternating between the two classes): one self-stress, one flex.
- ``k33-dixon`` (2D): Dixon's first flexible K(3,3): one class on the x-axis, the other on the
  y-axis (PyRigi's ``dixonI`` realisation).
- ``cn-symmetric-four-regular`` (2D): PyRigi's ``CnSymmetricFourRegular(n)`` (``n`` even, at
  least 8): a C_n-symmetric 4-regular graph on the unit circle; several stresses and flexes.
- ``rotor-chain-3d`` (3D): ``n`` hinged rotors: tip ``T_k`` held by two bars ``r{k}a``,
  ``r{k}b`` of length ``sqrt(r^2 + h^2)`` to pins at ``c_k -+ h axis_k`` (a hinge: a circle of
  radius ``r`` about ``c_k = (k a, 0, 0)``), ``axis_k = (0, sin(k tilt), cos(k tilt))``;
  consecutive tips joined by bars ``l{k}`` of length ``l``. Rotor 0 at angle ``theta`` in its
  plane, the chain solved outwards (``side`` picks the intersection). ``tilt = 0`` is the
  Kane-Lubensky chain lifted to 3D.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from engine.model.errors import InvalidParameter
from engine.model.linkage import BarSpec, VertexSpec

Params = dict[str, float]
Specs = tuple[list[VertexSpec], list[BarSpec]]


@dataclass(frozen=True)
class CatalogueEntry:
    """A named framework family (fields as :class:`engine.catalogue.presets.Preset`, plus
    dimension)."""

    name: str
    description: str
    parameters: Mapping[str, float]
    integers: frozenset[str]
    build: Callable[[Params], Specs]
    dimension: int


def circle_intersection(
    c0: np.ndarray, r0: float, c1: np.ndarray, r1: float, side: float
) -> np.ndarray | None:
    """Intersection of circles ``|x - c0| = r0`` and ``|x - c1| = r1`` on the given side of
    ``c0 -> c1``; None when they do not meet."""
    delta = c1 - c0
    dist = float(np.hypot(*delta))
    if dist == 0.0:
        return None
    along = (dist**2 + r0**2 - r1**2) / (2 * dist)
    h2 = r0**2 - along**2
    if h2 < -1e-12 * max(r0, r1) ** 2:
        return None
    e = delta / dist
    normal = np.array([-e[1], e[0]])
    return c0 + along * e + np.sign(side or 1.0) * np.sqrt(max(h2, 0.0)) * normal


def polar(angle: float, radius: float) -> np.ndarray:
    """The point at ``angle`` on the circle of ``radius`` about the origin."""
    return radius * np.array([np.cos(angle), np.sin(angle)])


def _framework(points: np.ndarray, edges: list[tuple[int, int]], prefix: str = "v") -> Specs:
    """Free vertices ``{prefix}{i}`` at ``points`` (V, d) and bars ``e{k}`` on ``edges``."""
    vertices = [VertexSpec(f"{prefix}{i}", p.tolist()) for i, p in enumerate(points)]
    bars = [
        BarSpec(f"e{k}", (f"{prefix}{i}", f"{prefix}{j}")) for k, (i, j) in enumerate(edges)
    ]
    return vertices, bars


_OCTAHEDRAL = [(0, 2), (0, 3), (0, 4), (0, 5), (1, 2), (1, 3), (1, 4), (1, 5),
               (2, 4), (2, 5), (3, 4), (3, 5)]  # opposite pairs 0-1, 2-3, 4-5 not joined


def _tetrahedron(p: Params) -> Specs:
    pts = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    pts *= p["a"] / (2 * np.sqrt(2))
    return _framework(pts, [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])


def _octahedron(p: Params) -> Specs:
    a = p["a"]
    pts = np.array([[0, 0, -a], [0, 0, a], [-a, 0, 0], [a, 0, 0], [0, -a, 0], [0, a, 0]], float)
    return _framework(pts, _OCTAHEDRAL)


def _bricard_line(p: Params) -> Specs:
    half_turn = np.diag([-1.0, -1.0, 1.0])
    base = np.array([[p["x0"], 0, 0], [p["x2"], p["y2"], p["z2"]], [p["x4"], p["y4"], p["z4"]]])
    pts = np.array([base[0], half_turn @ base[0], base[1], half_turn @ base[1],
                    base[2], half_turn @ base[2]])
    return _framework(pts, _OCTAHEDRAL)


def _bricard_plane(p: Params) -> Specs:
    mirror = np.diag([-1.0, 1.0, 1.0])
    v2, v4 = np.array([p["x2"], 0, 0]), np.array([p["x4"], p["y4"], 0])
    pts = np.array([[0, p["y0"], p["z0"]], [0, p["y1"], p["z1"]], v2, mirror @ v2, v4,
                    mirror @ v4])
    return _framework(pts, _OCTAHEDRAL)


def _three_prism(p: Params) -> Specs:
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 2.0]])
    c, s = np.cos(p["twist"]), np.sin(p["twist"])
    other = p["ratio"] * tri @ np.array([[c, s], [-s, c]]) + np.array([p["dx"], p["dy"]])
    edges = [(0, 1), (1, 2), (0, 2), (3, 4), (4, 5), (3, 5), (0, 3), (1, 4), (2, 5)]
    return _framework(np.vstack([tri, other]), edges)


_K33 = [(i, j) for i in (0, 2, 4) for j in (1, 3, 5)]


def _k33_conic(p: Params) -> Specs:
    angles = np.array([0.3, 1.2, 2.4, 3.3, 4.4, 5.5])  # classes {0, 2, 4} and {1, 3, 5}
    pts = np.column_stack([p["rx"] * np.cos(angles), p["ry"] * np.sin(angles)])
    return _framework(pts, _K33)


def _k33_dixon(p: Params) -> Specs:
    pts = np.array([[p["x0"], 0], [0, p["y1"]], [p["x2"], 0], [0, p["y3"]], [p["x4"], 0],
                    [0, p["y5"]]], float)
    return _framework(pts, _K33)


def _cn_four_regular(p: Params) -> Specs:
    n = int(p["n"])
    if n % 2 or not 8 <= n <= 200:
        raise InvalidParameter(f"n must be even and between 8 and 200, got {n}", loc=("n",))
    edges = [(0, n - 1), (n - 3, 0), (n - 2, 1), (n - 1, 2)]
    edges += [(i, i - 1) for i in range(1, n)] + [(i, i + 3) for i in range(n - 3)]
    angles = 2 * np.pi * np.arange(n) / n
    return _framework(np.column_stack([np.cos(angles), np.sin(angles)]), edges)


def _circle_sphere(
    centre: np.ndarray, radius: float, u: np.ndarray, v: np.ndarray, point: np.ndarray,
    dist: float, side: float,
) -> np.ndarray | None:
    """The point of the circle ``centre + radius (cos phi u + sin phi v)`` at distance ``dist``
    from ``point`` (``side`` picks one of the two); None when there is none."""
    rel = centre - point
    alpha, beta = 2 * radius * rel @ u, 2 * radius * rel @ v
    gamma = dist**2 - rel @ rel - radius**2
    amp = float(np.hypot(alpha, beta))
    if amp == 0.0 or abs(gamma) > amp:
        return None
    phi = np.arctan2(beta, alpha) + side * np.arccos(gamma / amp)
    return centre + radius * (np.cos(phi) * u + np.sin(phi) * v)


def _rotor_chain_3d(p: Params) -> Specs:
    n = int(p["n"])
    if not 2 <= n <= 2000:
        raise InvalidParameter(f"n must lie between 2 and 2000, got {n}", loc=("n",))
    for key in ("h", "r", "l", "a"):
        if p[key] <= 0:
            raise InvalidParameter(f"must be positive, got {p[key]!r}", loc=(key,))
    k = np.arange(n)
    centres = np.column_stack([k * p["a"], np.zeros(n), np.zeros(n)])
    # the angle reduced first: k * tilt must not overflow for a huge (but valid) angle
    tilt = k * math.remainder(p["tilt"], 2 * math.pi)
    axes = np.column_stack([np.zeros(n), np.sin(tilt), np.cos(tilt)])
    u = np.tile([1.0, 0.0, 0.0], (n, 1))
    v = np.cross(axes, u)
    r = p["r"]
    for step in np.linspace(0.0, 2 * np.pi, 721)[:-1]:
        theta = p["theta"] + step
        tips = [centres[0] + r * (np.cos(theta) * u[0] + np.sin(theta) * v[0])]
        for j in range(1, n):
            nxt = _circle_sphere(centres[j], r, u[j], v[j], tips[-1], p["l"], p["side"])
            if nxt is None:
                break
            tips.append(nxt)
        if len(tips) == n:
            break
    else:
        raise InvalidParameter(
            "the lengths admit no configuration: the 3D rotor chain assembles at no angle",
            loc=(),
        )
    hinge = float(np.hypot(r, p["h"]))
    vertices, bars = [], []
    for j in range(n):
        for end, sgn in (("a", -1.0), ("b", 1.0)):
            pin = centres[j] + sgn * p["h"] * axes[j]
            vertices.append(VertexSpec(f"P{j}{end}", pin.tolist(), True))
            bars.append(BarSpec(f"r{j}{end}", (f"P{j}{end}", f"T{j}"), hinge))
        vertices.append(VertexSpec(f"T{j}", tips[j].tolist()))
    bars += [BarSpec(f"l{j}", (f"T{j}", f"T{j + 1}"), p["l"]) for j in range(n - 1)]
    return vertices, bars


CATALOGUE: tuple[CatalogueEntry, ...] = (
    CatalogueEntry("tetrahedron", "Regular tetrahedron in 3D, edge a: first-order rigid.",
                   {"a": 1.0}, frozenset(), _tetrahedron, 3),
    CatalogueEntry("octahedron", "Regular octahedron in 3D, vertices +-a on the axes: "
                   "first-order rigid.", {"a": 1.0}, frozenset(), _octahedron, 3),
    CatalogueEntry(
        "bricard-line",
        "Bricard's line-symmetric flexible octahedron (type I): v0 = (x0, 0, 0), "
        "v2 = (x2, y2, z2), v4 = (x4, y4, z4) and their half turns about the z-axis v1, v3, v5; "
        "opposite pairs v0-v1, v2-v3, v4-v5 are not joined. Flexible: never prestress stable.",
        {"x0": 1.0, "x2": 1.0, "y2": 2.0, "z2": 1.0, "x4": 2.0, "y4": -1.0, "z4": -1.0},
        frozenset(), _bricard_line, 3,
    ),
    CatalogueEntry(
        "bricard-plane",
        "Bricard's plane-symmetric flexible octahedron (type II): v0 = (0, y0, z0) and "
        "v1 = (0, y1, z1) in the mirror x = 0, v2 = (x2, 0, 0), v4 = (x4, y4, 0) and their mirror "
        "images v3, v5. Flexible: never prestress stable.",
        {"y0": 1.0, "z0": 1.0, "y1": 1.0, "z1": -2.0, "x2": 1.0, "x4": 1.0, "y4": 1.0},
        frozenset(), _bricard_plane, 3,
    ),
    CatalogueEntry(
        "three-prism",
        "Planar three-prism: triangle v0 v1 v2 = (0,0), (2,0), (1,2), triangle v3 v4 v5 = "
        "ratio R(twist) v_i + (dx, dy), legs v_i - v_{i+3}. twist = 0 makes the legs concurrent "
        "(infinitesimally flexible, yet rigid); twist != 0 is first-order rigid.",
        {"ratio": 0.5, "twist": 0.0, "dx": 0.5, "dy": 3.0}, frozenset(), _three_prism, 2,
    ),
    CatalogueEntry(
        "three-prism-flexible",
        "Planar three-prism with parallel legs of equal length (ratio = 1, twist = 0): it flexes "
        "through parallelograms. Same parameters as three-prism.",
        {"ratio": 1.0, "twist": 0.0, "dx": 0.5, "dy": 3.0}, frozenset(), _three_prism, 2,
    ),
    CatalogueEntry(
        "k33-conic",
        "K(3,3) with its vertices on the ellipse (x/rx)^2 + (y/ry)^2 = 1 (classes v0 v2 v4 and "
        "v1 v3 v5, alternating around it): one self-stress and one flex.",
        {"rx": 2.0, "ry": 1.0}, frozenset(), _k33_conic, 2,
    ),
    CatalogueEntry(
        "k33-dixon",
        "Dixon's first flexible K(3,3): v0, v2, v4 on the x-axis at x0, x2, x4 and v1, v3, v5 on "
        "the y-axis at y1, y3, y5. Flexible: never prestress stable.",
        {"x0": 1.0, "x2": -2.0, "x4": 3.0, "y1": 1.0, "y3": -2.0, "y5": 3.0},
        frozenset(), _k33_dixon, 2,
    ),
    CatalogueEntry(
        "cn-symmetric-four-regular",
        "PyRigi's CnSymmetricFourRegular(n): a C_n-symmetric 4-regular framework on the unit "
        "circle (n even, 8 <= n <= 200): several self-stresses and flexes, prestress stable.",
        {"n": 8}, frozenset({"n"}), _cn_four_regular, 2,
    ),
    CatalogueEntry(
        "rotor-chain-3d",
        "n hinged rotors in 3D: tip T{k} on a circle of radius r about (k a, 0, 0) (bars r{k}a, "
        "r{k}b to pins at distance h along the hinge axis (0, sin(k tilt), cos(k tilt))), "
        "consecutive tips joined by bars l{k} of length l; rotor 0 at angle theta.",
        {"n": 6, "a": 1.0, "r": 1.5, "l": 1.5, "h": 0.5, "tilt": 0.3, "theta": 1.3, "side": 1.0},
        frozenset({"n"}), _rotor_chain_3d, 3,
    ),
)
