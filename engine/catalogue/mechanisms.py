"""Mechanisms for issue 25, registered as presets: two planar linkages and three 3D linkages with
two degrees of freedom, and a spherical four-bar (one).

The planar ones are two cranks on pins, their tips ``A`` and ``C`` joined through a middle vertex
``B`` by two couplers; ``B`` is where the couplers' circles meet, ``side`` picks which (in the
spherical four-bar, where the spheres about ``A`` and ``G2`` meet on the sphere about ``O``). The
crank angles ``theta1``, ``theta2`` are tried first; where the linkage does not assemble there,
the first pair of angles after them (steps of 2 degrees on both) where it does.

Lengths that give no linkage raise :class:`InvalidLinkage`, which
:func:`engine.catalogue.presets.build_preset` turns into a 422 naming the parameters the request
gave (the one changed, not a default it offends).

- ``pentagon`` (2D, D = 2): pins ``P0 = (0, 0)``, ``P1 = (L0, 0)`` joined by the pinned bar
  ``L0``; bars ``L1`` (``P1-A``), ``L2`` (``A-B``), ``L3`` (``B-C``), ``L4`` (``C-P0``); ``A`` at
  angle ``theta1`` about ``P1``, ``C`` at ``theta2`` about ``P0``.
- ``five-bar`` (2D, D = 2): pins ``P1 = (0, 0)``, ``P2 = (a, 0)``; cranks ``L1`` (``P1-A``) and
  ``L4`` (``P2-C``), couplers ``L2`` (``A-B``), ``L3`` (``B-C``).
- ``spherical-four-bar`` (3D, D = 1): centre ``O`` and ground pins ``G1 = (R, 0, 0)``, ``G2`` on
  the sphere of radius ``R`` in the plane z = 0 at chord ``g`` from ``G1``; ``A`` and ``B`` on the
  sphere (bars ``OA``, ``OB`` of length ``R``), crank ``L1`` (``G1-A``), coupler ``L2``
  (``A-B``), rocker ``L3`` (``G2-B``). The triangles ``O G1 A``, ``O A B``, ``O B G2`` hinge about
  ``OA`` and ``OB`` and turn about ``OG1`` and ``OG2``: every axis through ``O``.
- ``sphere-slider`` (3D, D = 2): ``A`` on a sphere about the pin ``P`` (bar ``PA``), ``B`` sliding
  in the plane z = 0 on a circle about the pin ``Q`` (bar ``QB``), the coupler ``AB``: a torus.
- ``spherical-five-bar`` (3D, D = 2): the spherical four-bar's centre and ground pins, three
  moving points ``A``, ``B``, ``C`` on the sphere (bars ``OA``, ``OB``, ``OC``), cranks ``L1``
  (``G1-A``) and ``L4`` (``G2-C``), couplers ``L2`` (``A-B``) and ``L3`` (``B-C``).
- ``spatial-quadrilateral`` (3D, D = 2): ``v0`` pinned at the origin, ``v1`` at ``(l1, 0, 0)``,
  ``v2`` sliding in the plane z = 0 at angle ``phi`` about ``v1`` (bar ``l2``), ``v3`` free at
  angle ``theta`` about the diagonal ``v0 v2`` (bars ``l3``, ``l4``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from engine.catalogue.catalogue import CatalogueEntry, circle_intersection, polar
from engine.model.errors import InvalidLinkage
from engine.model.linkage import BarSpec, VertexSpec

Params = dict[str, float]
Specs = tuple[list[VertexSpec], list[BarSpec]]
Point = np.ndarray

#: Steps of the search for an assembly over both crank angles (2 degrees each).
_STEPS = 180


def _meet_sphere(radius: float, p: Point, dp: float, q: Point, dq: float,
                 side: float) -> Point | None:
    """The point ``x`` with ``|x| = radius``, ``|x - p| = dp``, ``|x - q| = dq`` (``p``, ``q``
    on that sphere) on the side ``side`` of the plane through ``0, p, q``; None if none."""
    normal = np.cross(p, q)
    nn = float(normal @ normal)
    if nn <= 1e-24 * radius**4:
        return None
    # x . p = (2 R^2 - dp^2) / 2 and x . q likewise: x = s p + t q + u normal
    gram = np.array([[p @ p, p @ q], [p @ q, q @ q]])
    rhs = np.array([radius**2 - dp**2 / 2, radius**2 - dq**2 / 2])
    try:
        s, t = np.linalg.solve(gram, rhs)  # nonsingular: p x q is not zero
    except np.linalg.LinAlgError:
        return None
    base = s * p + t * q
    u2 = (radius**2 - float(base @ base)) / nn
    if u2 < 0.0:
        return None
    return base + side * math.sqrt(u2) * normal


def _scan(p: Params, attempt: Callable[[float, float], Specs | None], what: str,
          cranks: int = 2) -> Specs:
    """``attempt(theta1, theta2)`` from the given angles on, in steps of 2 degrees (only
    ``theta1`` when there is one crank)."""
    grid = 2 * np.pi * np.arange(_STEPS) / _STEPS
    for d1 in grid:
        for d2 in grid if cranks == 2 else grid[:1]:
            specs = attempt(p["theta1"] + float(d1), p["theta2"] + float(d2))
            if specs is not None:
                return specs
    raise InvalidLinkage(
        f"the lengths admit no configuration: {what} assembles at no pair of crank angles "
        "(2 degree steps)")


def _closes(p: Params, keys: tuple[str, ...], what: str) -> None:
    """A polygon with sides ``keys`` closes (in a non-flat way) only when its longest side is
    shorter than the sum of the others: otherwise a 422 naming the longest."""
    longest = max(keys, key=lambda k: p[k])
    rest = sum(p[k] for k in keys) - p[longest]
    if not p[longest] < rest:
        raise InvalidLinkage(
            f"{what} does not close: {longest} = {p[longest]:g} is not shorter than the sum "
            f"of the other sides ({rest:g})")


def _ring(pins: list[tuple[str, Point]], tips: tuple[Point, Point, Point],
          bars: list[tuple[str, str, str, float]]) -> Specs:
    """Pinned ``pins``, free tips ``A, B, C`` and ``bars`` as ``(id, end, end, length)``."""
    vertices = [VertexSpec(name, pos.tolist(), True) for name, pos in pins]
    vertices += [VertexSpec(name, pos.tolist()) for name, pos in zip("ABC", tips, strict=True)]
    return vertices, [BarSpec(b, (u, v), length) for b, u, v, length in bars]


def _pentagon(p: Params) -> Specs:
    _closes(p, ("L0", "L1", "L2", "L3", "L4"), "the pentagon")
    p0, p1 = np.zeros(2), np.array([p["L0"], 0.0])

    def attempt(t1: float, t2: float) -> Specs | None:
        a, c = p1 + polar(t1, p["L1"]), p0 + polar(t2, p["L4"])
        b = circle_intersection(a, p["L2"], c, p["L3"], p["side"])
        if b is None:
            return None
        return _ring([("P0", p0), ("P1", p1)], (a, b, c), [
            ("L0", "P0", "P1", p["L0"]), ("L1", "P1", "A", p["L1"]),
            ("L2", "A", "B", p["L2"]), ("L3", "B", "C", p["L3"]), ("L4", "C", "P0", p["L4"])])

    return _scan(p, attempt, "the pentagon")


def _five_bar(p: Params) -> Specs:
    _closes(p, ("a", "L1", "L2", "L3", "L4"), "the five-bar")
    p1, p2 = np.zeros(2), np.array([p["a"], 0.0])

    def attempt(t1: float, t2: float) -> Specs | None:
        a, c = p1 + polar(t1, p["L1"]), p2 + polar(t2, p["L4"])
        b = circle_intersection(a, p["L2"], c, p["L3"], p["side"])
        if b is None:
            return None
        return _ring([("P1", p1), ("P2", p2)], (a, b, c), [
            ("L1", "P1", "A", p["L1"]), ("L2", "A", "B", p["L2"]),
            ("L3", "B", "C", p["L3"]), ("L4", "P2", "C", p["L4"])])

    return _scan(p, attempt, "the five-bar")


def _chord_angle(p: Params, key: str) -> float:
    """The angle at the centre of a chord ``key`` of the sphere of radius ``R``; a 422 naming
    it when it is longer than the diameter (or as long: the three points would be collinear)."""
    if not p[key] < 2 * p["R"]:
        raise InvalidLinkage(
            f"the chord {key} = {p[key]:g} must be shorter than the sphere's diameter 2 R = "
            f"{2 * p['R']:g}")
    return 2 * math.asin(p[key] / (2 * p["R"]))


def _on_circle(radius: float, pole: Point, chord: float, angle: float) -> Point:
    """The point of the sphere of ``radius`` at ``chord`` from ``pole`` (on it), at ``angle``
    about the axis through ``pole``."""
    axis = pole / np.linalg.norm(pole)
    u = np.cross(axis, [0.0, 0.0, 1.0])
    if float(u @ u) < 1e-12:
        u = np.cross(axis, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    alpha = 2 * math.asin(chord / (2 * radius))
    return radius * (math.cos(alpha) * axis
                     + math.sin(alpha) * (math.cos(angle) * u + math.sin(angle) * v))


def _sphere_pins(p: Params) -> tuple[Point, Point, Point]:
    r = p["R"]
    gamma = _chord_angle(p, "g")
    return np.zeros(3), np.array([r, 0.0, 0.0]), r * np.array([math.cos(gamma),
                                                               math.sin(gamma), 0.0])


def _spherical_four_bar(p: Params) -> Specs:
    for key in ("L1", "L2", "L3"):
        _chord_angle(p, key)
    o, g1, g2 = _sphere_pins(p)
    r = p["R"]

    def attempt(t1: float, _: float) -> Specs | None:
        a = _on_circle(r, g1, p["L1"], t1)
        b = _meet_sphere(r, a, p["L2"], g2, p["L3"], p["side"])
        if b is None:
            return None
        vertices = [VertexSpec("O", o.tolist(), True), VertexSpec("G1", g1.tolist(), True),
                    VertexSpec("G2", g2.tolist(), True), VertexSpec("A", a.tolist()),
                    VertexSpec("B", b.tolist())]
        bars = [BarSpec("OA", ("O", "A"), r), BarSpec("OB", ("O", "B"), r),
                BarSpec("L1", ("G1", "A"), p["L1"]), BarSpec("L2", ("A", "B"), p["L2"]),
                BarSpec("L3", ("G2", "B"), p["L3"])]
        return vertices, bars

    return _scan(p | {"theta2": 0.0}, attempt, "the spherical four-bar", cranks=1)


def _sphere_slider(p: Params) -> Specs:
    r, c, d, s = p["r"], p["c"], p["d"], p["s"]
    if not (abs(r - c) < d - s and d + s < r + c):
        raise InvalidLinkage(
            "the sphere-slider is a torus only when |r - c| < d - s and d + s < r + c (got "
            f"|r - c| = {abs(r - c):g}, d - s = {d - s:g}, d + s = {d + s:g}, "
            f"r + c = {r + c:g})")
    b = np.array([d + s * math.cos(p["theta"]), s * math.sin(p["theta"]), 0.0])
    dist = float(np.hypot(b[0], b[1]))
    along = (r**2 - c**2 + dist**2) / (2 * dist)  # |r - c| < dist < r + c: a circle of A
    a = along * b / dist + p["side"] * math.sqrt(r**2 - along**2) * np.array([0.0, 0.0, 1.0])
    vertices = [VertexSpec("P", [0.0, 0.0, 0.0], True), VertexSpec("Q", [d, 0.0, 0.0], True),
                VertexSpec("A", a.tolist()), VertexSpec("B", b.tolist(), [False, False, True])]
    bars = [BarSpec("PA", ("P", "A"), r), BarSpec("QB", ("Q", "B"), s),
            BarSpec("AB", ("A", "B"), c)]
    return vertices, bars


def _spherical_five_bar(p: Params) -> Specs:
    for key in ("L1", "L2", "L3", "L4"):
        _chord_angle(p, key)
    o, g1, g2 = _sphere_pins(p)
    r = p["R"]

    def attempt(t1: float, t2: float) -> Specs | None:
        a, c = _on_circle(r, g1, p["L1"], t1), _on_circle(r, g2, p["L4"], t2)
        b = _meet_sphere(r, a, p["L2"], c, p["L3"], p["side"])
        if b is None:
            return None
        pos = {"O": o, "G1": g1, "G2": g2, "A": a, "B": b, "C": c}
        vertices = [VertexSpec(k, x.tolist(), k in ("O", "G1", "G2")) for k, x in pos.items()]
        bars = [BarSpec("OA", ("O", "A"), r), BarSpec("OB", ("O", "B"), r),
                BarSpec("OC", ("O", "C"), r), BarSpec("L1", ("G1", "A"), p["L1"]),
                BarSpec("L2", ("A", "B"), p["L2"]), BarSpec("L3", ("B", "C"), p["L3"]),
                BarSpec("L4", ("G2", "C"), p["L4"])]
        return vertices, bars

    return _scan(p, attempt, "the spherical five-bar")


#: The smallest radius of ``v3``'s circle (relative to its bars) a spatial quadrilateral is
#: started on: smaller is (near) a flat triangle ``v0 v2 v3``, the next angle ``phi`` is tried.
_CIRCLE_RTOL = 1e-3


def _spatial_quadrilateral(p: Params) -> Specs:
    l1, l2, l3, l4 = p["l1"], p["l2"], p["l3"], p["l4"]
    lo, hi = max(abs(l1 - l2), abs(l3 - l4)), min(l1 + l2, l3 + l4)
    if not lo < hi:
        raise InvalidLinkage(
            "the quadrilateral does not close: its diagonal v0 v2 must lie in both "
            f"[|l1 - l2|, l1 + l2] = [{abs(l1 - l2):g}, {l1 + l2:g}] and [|l3 - l4|, l3 + l4] = "
            f"[{abs(l3 - l4):g}, {l3 + l4:g}]")
    v0, v1 = np.zeros(3), np.array([l1, 0.0, 0.0])
    z = np.array([0.0, 0.0, 1.0])

    def attempt(phi: float, _: float) -> Specs | None:
        v2 = v1 + l2 * np.array([math.cos(phi), math.sin(phi), 0.0])
        d = float(np.linalg.norm(v2))
        if not lo < d < hi or d == 0.0:
            return None
        e = v2 / d
        along = (l4**2 - l3**2 + d**2) / (2 * d)
        radius = math.sqrt(max(l4**2 - along**2, 0.0))
        if radius <= _CIRCLE_RTOL * min(l3, l4):
            return None
        u = np.cross(z, e)  # in the plane z = 0, normal to the diagonal: (u, z, e) orthonormal
        v3 = along * e + radius * (math.cos(p["theta"]) * u + math.sin(p["theta"]) * z)
        pos = {"v0": v0, "v1": v1, "v2": v2, "v3": v3}
        fixed: dict[str, bool | list[bool]] = {"v0": True, "v1": True,
                                               "v2": [False, False, True], "v3": False}
        vertices = [VertexSpec(k, x.tolist(), fixed[k]) for k, x in pos.items()]
        ends = (("v0", "v1"), ("v1", "v2"), ("v2", "v3"), ("v3", "v0"))
        bars = [BarSpec(f"l{k + 1}", e_, p[f"l{k + 1}"]) for k, e_ in enumerate(ends)]
        return vertices, bars

    return _scan(p | {"theta1": p["phi"], "theta2": 0.0}, attempt, "the quadrilateral",
                 cranks=1)


#: Parameters that are lengths (positive) in these presets.
LENGTHS = frozenset({"L0", "L4", "R", "g", "c", "d", "s", "l1", "l2", "l3", "l4"})

MECHANISMS: tuple[CatalogueEntry, ...] = (
    CatalogueEntry(
        "pentagon",
        "Planar pentagon P0 P1 A B C with the bar L0 (P0-P1) pinned, P0 = (0, 0), "
        "P1 = (L0, 0); bars L1 (P1-A), L2 (A-B), L3 (B-C), L4 (C-P0); A at angle theta1 about "
        "P1, C at theta2 about P0. Two degrees of freedom: its configuration space is a surface. "
        "The lengths must close (the longest shorter than the sum of the others); they are "
        "generic when no subset sums to half the perimeter (the equilateral default is: a "
        "surface of genus 4).",
        {"L0": 1.0, "L1": 1.0, "L2": 1.0, "L3": 1.0, "L4": 1.0,
         "theta1": 2 * math.pi / 5, "theta2": 3 * math.pi / 5, "side": 1.0},
        frozenset(), _pentagon, 2,
    ),
    CatalogueEntry(
        "five-bar",
        "Planar five-bar (a two-crank robot): pins P1 = (0, 0), P2 = (a, 0); cranks L1 (P1-A) at "
        "angle theta1 and L4 (P2-C) at theta2, couplers L2 (A-B) and L3 (B-C). Two degrees of "
        "freedom: a surface (the default lengths are generic: genus 4).",
        {"a": 1.0, "L1": 1.0, "L2": 1.3, "L3": 1.2, "L4": 1.0,
         "theta1": 2.0, "theta2": 1.0, "side": 1.0},
        frozenset(), _five_bar, 2,
    ),
    CatalogueEntry(
        "spherical-four-bar",
        "Spherical four-bar built from bars in 3D: centre O and ground pins G1 = (R, 0, 0) and "
        "G2 (in the plane z = 0, chord g from G1) pinned; A and B on the sphere of radius R "
        "(bars OA, OB), crank L1 (G1-A) at angle theta1 about the axis O G1, coupler L2 (A-B), "
        "rocker L3 (G2-B); every joint axis passes through O. One degree of freedom (D = 1: a "
        "curve, traced like the planar four-bar). Chords shorter than 2 R.",
        {"R": 1.0, "g": 1.2, "L1": 0.6, "L2": 1.3, "L3": 1.0, "theta1": 1.0, "side": 1.0},
        frozenset(), _spherical_four_bar, 3,
    ),
    CatalogueEntry(
        "sphere-slider",
        "A 3D linkage with two degrees of freedom: pins P = (0, 0, 0) and Q = (d, 0, 0); A on the "
        "sphere of radius r about P (bar PA), B sliding in the plane z = 0 on the circle of "
        "radius s about Q (bar QB, B's z fixed) at angle theta, coupler AB of length c; side "
        "picks A above or below that plane. D = 2: for every B, A runs on the circle where two "
        "spheres meet, so with |r - c| < d - s and d + s < r + c (checked) the space is a "
        "torus.",
        {"d": 2.5, "r": 1.2, "s": 0.8, "c": 2.2, "theta": 0.0, "side": 1.0},
        frozenset(), _sphere_slider, 3,
    ),
    CatalogueEntry(
        "spherical-five-bar",
        "Spherical five-bar built from bars in 3D: centre O and ground pins G1 = (R, 0, 0) and "
        "G2 (in the plane z = 0, chord g from G1) pinned; A, B and C on the sphere of radius R "
        "(bars OA, OB, OC), crank L1 (G1-A) at angle theta1 about the axis O G1, crank L4 "
        "(G2-C) at theta2 about O G2, couplers L2 (A-B) and L3 (B-C); side picks B on either "
        "side of the plane O A C. Two degrees of freedom (D = 2: a surface; the default lengths "
        "are generic: one surface of genus 3). Chords shorter than 2 R.",
        {"R": 1.0, "g": 1.2, "L1": 0.6, "L2": 1.0, "L3": 0.9, "L4": 0.7,
         "theta1": 1.0, "theta2": 1.0, "side": 1.0},
        frozenset(), _spherical_five_bar, 3,
    ),
    CatalogueEntry(
        "spatial-quadrilateral",
        "Spatial quadrilateral v0 v1 v2 v3 (a spatial polygon space): v0 pinned at the origin, "
        "v1 at (l1, 0, 0) (the bar l1 joins two pins), v2 sliding in the plane z = 0 (its z "
        "fixed) at angle phi about v1 (bar l2), v3 free at angle theta about the diagonal "
        "v0 v2 (bars l3 = v2 v3, l4 = v3 v0; theta = pi/2 is above the plane). Two degrees of "
        "freedom (D = 2): for generic lengths two spheres, one sphere or one torus (the "
        "default), by where the diagonal's range ends. The diagonal must have room: "
        "max(|l1 - l2|, |l3 - l4|) < min(l1 + l2, l3 + l4).",
        {"l1": 1.0, "l2": 0.5, "l3": 1.2, "l4": 1.0, "phi": 2.0, "theta": math.pi / 2},
        frozenset(), _spatial_quadrilateral, 3,
    ),
)
