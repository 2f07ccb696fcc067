"""The critical lengths of a spherical four-bar over a map's box of two of its chords, in closed
form.

A *spherical four-bar* (the ``spherical-four-bar`` preset is one; recognised from its structure by
:func:`spherical_four_bar`) is a 3D linkage of a pinned centre ``O``, two more pins ``G1``,
``G2`` and two free tips ``A``, ``B``: bars ``OA`` and ``OB`` to the centre, the crank ``L1``
(``G1 A``), the coupler ``L2`` (``A B``) and the rocker ``L3`` (``B G2``), nothing else (bars
between pins are inert). Every length sits in a triangle with the centre: ``L1`` in ``O G1 A``,
``L2`` in ``O A B``, ``L3`` in ``O B G2``, with the other two sides fixed (``|OG1|``, ``OA``;
``OA``, ``OB``; ``OB``, ``|OG2|``). So each chord sets the *arc* (the angle at ``O``)::

    alpha_i = arccos((p_i^2 + q_i^2 - L_i^2) / (2 p_i q_i)),   |p_i - q_i| <= L_i <= p_i + q_i

(on a sphere of radius ``R`` with every point on it: ``L_i = 2 R sin(alpha_i / 2)``), and the
ground arc ``gamma`` is the angle ``G1 O G2``. Only the directions ``a = A / |A|``, ``b`` move:
``a`` on the circle of radius ``alpha_1`` about ``g1``, ``b`` on that of radius ``alpha_3`` about
``g2``, ``angle(a, b) = alpha_2``.

**Critical configurations.** A self-stress ``omega`` balances ``A``:
``omega_OA A + omega_1 (A - G1) + omega_2 (A - B) = 0``, and ``B`` alike. With ``omega_2 = 0``,
``A`` is balanced only on the line ``O G1`` (``alpha_1`` 0 or ``pi``) or ``B`` on ``O G2``.
With ``omega_2 != 0``, ``B`` lies in the plane ``O G1 A`` and ``A`` in the plane ``O B G2``:
either ``O, A, B`` on one line (``alpha_2`` 0 or ``pi``) or both planes are ``O A B``, which then
holds ``G1`` and ``G2``: every joint on the great circle through the pins (``gamma`` strictly
between 0 and ``pi``: that circle is one). Conversely each of these carries a stress (the plane
ones: five bars, four in-plane coordinates). So a configuration is critical iff it is **flat**
(every joint in the plane ``O G1 G2``) or a triangle of the centre is flat.

**Critical values.** Walking the great circle from ``g1`` (at angle 0, ``g2`` at ``gamma``), the
tips of a flat configuration sit at ``s1 alpha_1`` and ``s1 alpha_1 + s2 alpha_2``, and
``g2`` at ``s1 alpha_1 + s2 alpha_2 + s3 alpha_3``; every choice of signs is a configuration
(each arc in ``[0, pi]`` is the angle between its ends), so the flat critical values are exactly::

    s1 alpha_1 + s2 alpha_2 + s3 alpha_3 - gamma = 2 pi k,    s in {-1, +1}^3, k in {-1, 0, 1}

(the spherical Grashof equalities; ``k = 0`` with all signs ``+`` is the planar ``L1 + L2 + L3 =
g`` in the limit ``R -> infinity``, the other ``k`` need arcs summing past ``pi`` and have no
planar analogue). A flat triangle ``alpha_i`` 0 or ``pi`` is critical where the rest assembles
with it: ``a`` on its circle about ``g1`` puts ``d = angle(a, g2)`` anywhere in
``[|gamma - alpha_1|, min(gamma + alpha_1, 2 pi - gamma - alpha_1)]``, and ``b`` exists iff ``d``
is in ``[|alpha_2 - alpha_3|, min(alpha_2 + alpha_3, 2 pi - alpha_2 - alpha_3)]``
(:func:`assembles`). Beyond ``alpha_i``'s range (``L_i`` outside ``[|p - q|, p + q]``) the space
is empty; its edge is that flat triangle.

**In a map of two chords** each axis sets one arc (monotone: ``dL / dalpha = p q sin(alpha) / L
<= min(p, q)``, since ``L >= p sin(alpha)`` and ``L >= q sin(alpha)``), the third is fixed: in the
arcs the flat critical values are straight segments of slope +-1 and the flat triangles
segments of the lines ``alpha = 0, pi``, each mapped back to lengths and sampled uniformly (the
bound on ``dL / dalpha`` keeps samples at most ``step`` apart). Maps over ``OA`` or ``OB``
(both arcs of a tip move: not separable) are drawn from the flat configurations themselves
(:mod:`.spherical_radii`).

>>> from engine.catalogue.presets import build_preset
>>> lk = build_preset("spherical-four-bar")
>>> curves = spherical_curves(lk, (2, 3), np.array([[0.3, 0.9], [0.65, 1.95]]), 0.01, 1e-9)
>>> len(curves)
4
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage

#: An arc within this (radians) of 0 or ``pi`` for a fixed chord, or a ground arc this close to 0
#: or ``pi``, is degenerate: a triangle of the centre flat at every length of the map (every
#: point critical) or the pins on one line through the centre (a continuous symmetry).
DEGENERATE_ARC = 1e-9
#: Segments this close (in the arcs) are one.
SAME_SEGMENT = 1e-12

Curves = list[np.ndarray]

#: What every curve of :func:`spherical_curves` is (the slice's argument completes "every
#: critical curve in the box is ...").
SPHERICAL_CURVES = (
    "a flat configuration of the spherical four-bar (every joint on the great circle through "
    "its pins: a signed sum of its arcs and the ground arc a multiple of 2 pi) or a triangle "
    "of the centre flat where the rest assembles (closed form: in the arcs over two chords, "
    "from the planar flat configurations over a radius)")


@dataclass(frozen=True)
class SphericalFourBar:
    """The bars and fixed geometry of a spherical four-bar (see the module docstring).

    ``chords`` (3,) the bar indices of ``L1, L2, L3``; ``radii`` (2,) those of ``OA, OB``;
    ``pin_radii`` (2,) ``|OG1|, |OG2|``; ``gamma`` the ground arc ``G1 O G2``."""

    chords: tuple[int, int, int]
    radii: tuple[int, int]
    pin_radii: tuple[float, float]
    gamma: float

    def sides(self, lengths: np.ndarray) -> np.ndarray:
        """(3, 2) the two sides at the centre of each chord's triangle, at ``lengths`` (E,)."""
        ra, rb = float(lengths[self.radii[0]]), float(lengths[self.radii[1]])
        return np.array([[self.pin_radii[0], ra], [ra, rb], [rb, self.pin_radii[1]]])

    def arcs(self, lengths: np.ndarray) -> np.ndarray:
        """(3,) the arcs ``alpha_i`` at ``lengths`` (E,); NaN where a triangle does not close."""
        pq = self.sides(lengths)
        c = np.asarray(lengths, dtype=float)[list(self.chords)]
        return arc(pq[:, 0], pq[:, 1], c)


def arc(p: np.ndarray | float, q: np.ndarray | float, c: np.ndarray | float) -> np.ndarray:
    """The angle opposite ``c`` in the triangle of sides ``p, q, c`` (NaN where it does not
    close: ``c`` outside ``[|p - q|, p + q]``)."""
    p, q, c = (np.asarray(v, dtype=float) for v in (p, q, c))
    cos = (p * p + q * q - c * c) / (2 * p * q)
    with np.errstate(invalid="ignore"):
        return np.where(np.abs(cos) <= 1.0, np.arccos(np.clip(cos, -1.0, 1.0)), np.nan)


def chord(p: float, q: float, alpha: np.ndarray) -> np.ndarray:
    """The side opposite the angle ``alpha`` between sides ``p`` and ``q`` (inverse of
    :func:`arc`)."""
    return np.sqrt(np.maximum(p * p + q * q - 2 * p * q * np.cos(alpha), 0.0))


def assembles(alpha: np.ndarray, gamma: float) -> np.ndarray:
    """Whether the spherical four-bar of arcs ``alpha`` (..., 3) and ground arc ``gamma`` has a
    configuration (see the module docstring): ``angle(a, g2)`` over ``a``'s circle meets the
    range the coupler and rocker allow."""
    alpha = np.asarray(alpha, dtype=float)
    a1, a2, a3 = alpha[..., 0], alpha[..., 1], alpha[..., 2]
    lo = np.maximum(np.abs(gamma - a1), np.abs(a2 - a3))
    hi = np.minimum(np.minimum(gamma + a1, 2 * np.pi - gamma - a1),
                    np.minimum(a2 + a3, 2 * np.pi - a2 - a3))
    return np.asarray(lo <= hi)


def spherical_four_bar(linkage: Linkage) -> SphericalFourBar | None:
    """The spherical four-bar of ``linkage`` (see the module docstring), or None: 3D, two free
    tips (no sliders), each held by a bar to a common pinned centre and a bar to a pin of its
    own, joined by one coupler, nothing else with a free end; the pins off the centre and not on
    one line through it.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> sf = spherical_four_bar(build_preset("spherical-four-bar"))
    >>> sf.chords, sf.radii, round(sf.gamma, 6)
    ((2, 3, 4), (0, 1), 1.287002)
    >>> spherical_four_bar(build_preset("rotor-chain-3d", {"n": 2})) is None
    True
    """
    if linkage.dimension != 3:
        return None
    fixed = np.asarray(linkage.fixed, dtype=bool)
    full: np.ndarray = np.asarray(fixed.all(axis=1), dtype=bool)
    if np.any(fixed.any(axis=1) & ~full):
        return None
    tips = np.flatnonzero(~full)
    ends = np.asarray(linkage.ends)
    live = np.flatnonzero(linkage.active)
    if len(tips) != 2 or len(live) != 5:
        return None
    a, b = (int(t) for t in tips)
    pins: dict[int, list[tuple[int, int]]] = {a: [], b: []}  # tip -> [(pin, bar)]
    coupler = []
    for k in live:
        i, j = int(ends[k, 0]), int(ends[k, 1])
        if not full[i] and not full[j]:
            coupler.append(int(k))
        else:
            tip, pin = (i, j) if full[j] else (j, i)
            pins[tip].append((pin, int(k)))
    if len(coupler) != 1 or any(len(v) != 2 for v in pins.values()):
        return None
    shared = {p for p, _ in pins[a]} & {p for p, _ in pins[b]}
    if len(shared) != 1:
        return None  # no centre, or both pins shared (a symmetry about their axis)
    o = shared.pop()
    pos = np.asarray(linkage.positions, dtype=float)
    radius = {t: next(k for p, k in pins[t] if p == o) for t in (a, b)}
    ground = {t: next((p, k) for p, k in pins[t] if p != o) for t in (a, b)}
    g1, g2 = pos[ground[a][0]] - pos[o], pos[ground[b][0]] - pos[o]
    n1, n2 = float(np.linalg.norm(g1)), float(np.linalg.norm(g2))
    if n1 == 0.0 or n2 == 0.0:
        return None
    gamma = float(np.arccos(np.clip(g1 @ g2 / (n1 * n2), -1.0, 1.0)))
    if not DEGENERATE_ARC < gamma < np.pi - DEGENERATE_ARC:
        return None
    return SphericalFourBar((ground[a][1], coupler[0], ground[b][1]), (radius[a], radius[b]),
                            (n1, n2), gamma)


def _clip_segment(n: np.ndarray, c: float, lo: np.ndarray, hi: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """The piece of the line ``n . x = c`` (n (2,) nonzero) inside ``[lo, hi]``, as its two
    ends, or None."""
    p0 = n * c / float(n @ n)
    d = np.array([-n[1], n[0]])
    t_lo, t_hi = -np.inf, np.inf
    for m in range(2):
        if d[m] == 0.0:
            if not lo[m] <= p0[m] <= hi[m]:
                return None
            continue
        ta, tb = sorted(((lo[m] - p0[m]) / d[m], (hi[m] - p0[m]) / d[m]))
        t_lo, t_hi = max(t_lo, ta), min(t_hi, tb)
    if not t_hi >= t_lo:
        return None
    return p0 + t_lo * d, p0 + t_hi * d


def flat_lines(fixed: float, gamma: float) -> list[tuple[np.ndarray, float]]:
    """The flat critical values in the arcs ``(alpha_x, alpha_y)`` of two chords, the third
    chord's arc ``fixed``: lines ``n . alpha = c`` (n of +-1, the first +1), each once."""
    out: list[tuple[np.ndarray, float]] = []
    for sy, sf, k in itertools.product((1.0, -1.0), (1.0, -1.0), (-1, 0, 1)):
        for sg in (1.0, -1.0):  # (the ground's sign: both, so the x sign may be taken +)
            n, c = np.array([1.0, sy]), 2 * np.pi * k - sf * fixed + sg * gamma
            if not any(np.array_equal(n, m) and abs(c - e) <= SAME_SEGMENT for m, e in out):
                out.append((n, c))
    return out


def _arc_segments(alpha_f: float, gamma: float, order: tuple[int, int, int],
                  lo: np.ndarray, hi: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every critical segment in the rectangle ``[lo, hi]`` of the axes' arcs: the flat lines,
    and the lines ``alpha = 0, pi`` of each axis where the rest assembles. ``order`` puts the
    arcs ``(x, y, fixed)`` back as ``(alpha_1, alpha_2, alpha_3)``."""
    lines = flat_lines(alpha_f, gamma)
    segs = [s for n, c in lines if (s := _clip_segment(n, c, lo, hi)) is not None]
    for axis, edge in itertools.product(range(2), (0.0, np.pi)):
        if not lo[axis] <= edge <= hi[axis]:
            continue
        other = 1 - axis
        # the flat lines cut the edge where the assembly can change: between two cuts it
        # either assembles throughout or nowhere (its conditions are those lines' inequalities)
        cuts = [lo[other], hi[other]]
        for n, c in lines:
            t = (c - n[axis] * edge) / n[other]
            if lo[other] < t < hi[other]:
                cuts.append(float(t))
        cuts = sorted(cuts)
        for t0, t1 in itertools.pairwise(cuts):
            if t1 - t0 <= SAME_SEGMENT:
                continue
            mid = np.zeros(3)
            mid[order[axis]], mid[order[other]], mid[order[2]] = edge, 0.5 * (t0 + t1), alpha_f
            if bool(assembles(mid, gamma)):
                p, q = np.zeros(2), np.zeros(2)
                p[axis] = q[axis] = edge
                p[other], q[other] = t0, t1
                segs.append((p, q))
    return segs


def spherical_curves(linkage: Linkage, axes: tuple[int, int], box: np.ndarray, step: float,
                     shortest: float) -> Curves | None:
    """Every critical curve of a spherical four-bar over the box of two of its chords (see the
    module docstring), each piece (n, 2) sampled at most ``step`` apart; None when the linkage
    is not a spherical four-bar (:func:`spherical_four_bar`), an axis is not one of its chords,
    or the third chord's triangle is flat (every length of the box critical).

    Parameters
    ----------
    linkage : Linkage
    axes : (2,) int
        The bars whose lengths the map varies (``X``, ``Y``).
    box : (2, 2) float
        ``[[x_min, x_max], [y_min, y_max]]``, positive.
    step : float
        Longest distance between consecutive points of a piece.
    shortest : float
        Lengths below this are not drawn (as the box's lower edge).
    """
    sf = spherical_four_bar(linkage)
    if sf is None or not set(axes) <= set(sf.chords) or axes[0] == axes[1]:
        return None
    which = [sf.chords.index(b) for b in axes]
    third = ({0, 1, 2} - set(which)).pop()
    sides = sf.sides(np.asarray(linkage.lengths, dtype=float))  # (3, 2)
    alpha_f = float(arc(sides[third, 0], sides[third, 1], linkage.lengths[sf.chords[third]]))
    if np.isnan(alpha_f):
        return []  # the third triangle never closes: the space is empty all over the box
    if not DEGENERATE_ARC < alpha_f < np.pi - DEGENERATE_ARC:
        return None
    pq = sides[which]  # (2, 2)
    lo_len = np.maximum(np.maximum(box[:, 0], shortest), np.abs(pq[:, 0] - pq[:, 1]))
    hi_len = np.minimum(box[:, 1], pq.sum(axis=1))
    if np.any(lo_len > hi_len):
        return []  # an axis's triangle closes nowhere in the box: empty throughout
    # (the ends of a triangle's range exactly: arccos loses half the digits next to them)
    lo = np.array([0.0 if box[m, 0] <= abs(pq[m, 0] - pq[m, 1]) else
                   float(arc(pq[m, 0], pq[m, 1], lo_len[m])) for m in range(2)])
    hi = np.array([np.pi if box[m, 1] >= pq[m].sum() else
                   float(arc(pq[m, 0], pq[m, 1], hi_len[m])) for m in range(2)])
    order = (which[0], which[1], third)
    slope = pq.min(axis=1)  # (2,) bounds on dL / dalpha per axis
    curves = []
    for p, q in _arc_segments(alpha_f, sf.gamma, order, lo, hi):
        speed = float(np.hypot(*(slope * np.abs(q - p))))
        t = np.linspace(0.0, 1.0, max(int(np.ceil(speed / step)), 1) + 1)
        pts = p[None, :] + t[:, None] * (q - p)[None, :]
        xy = np.column_stack([chord(pq[m, 0], pq[m, 1], pts[:, m]) for m in range(2)])
        curves.append(np.clip(xy, lo_len, hi_len))
    return curves
