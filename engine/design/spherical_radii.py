"""The critical lengths of a spherical four-bar over a map's box with a radius (``OA`` or ``OB``)
among its axes, in closed form from its flat configurations.

Notation of :mod:`.spherical_curves`: a configuration is critical iff it is flat (every joint in
the plane ``Pi`` of ``O, G1, G2``) or a triangle of the centre is flat (``O G1 A``, ``O A B`` or
``O B G2`` on one line). With a radius among the axes the arcs are no longer separable (``OA``
sets both ``alpha_1`` and ``alpha_2``), so the flat critical values are drawn from the flat
configurations themselves: in ``Pi`` the three bars that are not axes hold the tips ``A``,
``B`` to a one-parameter family, and the axes' lengths along it are the curves:

- a tip held by two of them to pins (one of two mirror points: two circles about pins meet),
  the other tip on a circle about a pin or about that tip: its angle ``phi`` runs round the
  circle, each axis a distance to the moving tip (moving at most ``radius`` per radian);
- else the coupler ``L2`` joins a tip on a circle about pin ``P`` (radius ``r1``) and one on a
  circle about pin ``Q`` (``r3``): a planar four-bar of ground ``|PQ|``, ``A`` at angle
  ``theta`` about ``P``, ``B`` where two circles meet. ``|A - Q|`` grows with ``|theta -
  theta_Q|``, so the angles where ``B`` exists are ``theta_Q +- [u_a, u_b]``, the ends in closed
  form (``|A - Q|`` is ``L2 + r3`` or ``|L2 - r3|``): one loop per arc (the two places of
  ``B`` meet at its ends), two for the whole circle. Near an arc's end ``B`` moves as a square
  root of the angle: samples are halved until consecutive points are at most ``step`` apart.

A flat triangle is a line in the map (``L = p + q`` or ``|p - q|``, with an axis among
``p, q, L``), critical where the rest assembles (:func:`.spherical_curves.assembles`): that
changes only where the line meets a flat curve or another triangle's range, so each line is cut
there and its pieces kept by their midpoints.

>>> from engine.catalogue.presets import build_preset
>>> lk = build_preset("spherical-four-bar")
>>> curves = radius_curves(lk, (0, 1), np.array([[0.8, 1.2], [0.8, 1.2]]), 0.01, 1e-9)
>>> len(curves) >= 1
True
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from engine.design.spherical_curves import (
    DEGENERATE_ARC,
    SphericalFourBar,
    _clip_segment,
    arc,
    assembles,
    spherical_four_bar,
)
from engine.model.linkage import Linkage

#: Halvings of the parameter between two samples at most (near an arc's end ``B`` moves as a
#: square root: 2^-50 of a turn puts consecutive points within ``1e-7`` of the radius).
MAX_HALVINGS = 50
#: Samples of the flat family at most (beyond it the closed form declines).
MAX_SAMPLES = 400_000

Curves = list[np.ndarray]
Point = np.ndarray


def _meet(c0: Point, r0: float, c1: Point, r1: float) -> list[Point]:
    """The (up to two) points of the plane at ``r0`` from ``c0`` and ``r1`` from ``c1``."""
    d = float(np.linalg.norm(c1 - c0))
    if d == 0.0:
        return []
    along = (d * d + r0 * r0 - r1 * r1) / (2 * d)
    h2 = r0 * r0 - along * along
    if h2 < 0.0:
        return []
    e = (c1 - c0) / d
    n = np.array([-e[1], e[0]])
    return [c0 + along * e + s * np.sqrt(h2) * n for s in (1.0, -1.0)]


def _plane_pins(sf: SphericalFourBar) -> dict[str, Point]:
    """``O``, ``G1``, ``G2`` in coordinates of the plane ``Pi`` (``G1`` on the first axis)."""
    n1, n2 = sf.pin_radii
    return {"O": np.zeros(2), "G1": np.array([n1, 0.0]),
            "G2": n2 * np.array([np.cos(sf.gamma), np.sin(sf.gamma)])}


#: The bars by name: ends (pins by name, tips ``A``, ``B``).
BARS = {"OA": ("O", "A"), "OB": ("O", "B"), "L1": ("G1", "A"), "L2": ("A", "B"),
        "L3": ("G2", "B")}


def _names(sf: SphericalFourBar) -> dict[int, str]:
    return {sf.radii[0]: "OA", sf.radii[1]: "OB", sf.chords[0]: "L1", sf.chords[1]: "L2",
            sf.chords[2]: "L3"}


Family = tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]


def _refined(positions: Callable[[np.ndarray], np.ndarray], t: np.ndarray, step: float
             ) -> Family | None:
    """``positions`` (t -> (n, 2)) with its parameters ``t`` (sorted), midpoints added
    wherever the images of neighbours are more than ``step`` apart; None past the sample
    budget."""
    pts = positions(t)
    for _ in range(MAX_HALVINGS):
        far = np.linalg.norm(np.diff(pts, axis=0), axis=1) > step
        if not far.any():
            break
        mid = 0.5 * (t[:-1][far] + t[1:][far])
        t = np.sort(np.concatenate([t, mid]))
        if len(t) > MAX_SAMPLES:
            return None
        pts = positions(t)
    return positions, t


def _family(sf: SphericalFourBar, lengths: np.ndarray, axes: tuple[int, int], step: float
            ) -> list[Family] | None:
    """The axes' lengths along every flat configuration (each a function of a parameter and
    its samples, not yet cut to the box); None past the sample budget."""
    names = _names(sf)
    axis_names = [names[a] for a in axes]
    fixed = {n: float(lengths[b]) for b, n in names.items() if n not in axis_names}
    pins = _plane_pins(sf)
    held = {t: [n for n in fixed if t in BARS[n] and BARS[n][0] in pins] for t in "AB"}

    def other(bar: str, end: str) -> str:
        a, b = BARS[bar]
        return b if a == end else a

    def image(place: dict[str, np.ndarray]) -> np.ndarray:
        def at(p: str, n: int) -> np.ndarray:
            return place[p] if p in place else np.broadcast_to(pins[p], (n, 2))

        n = len(next(iter(place.values())))
        return np.column_stack([np.linalg.norm(at(BARS[a][0], n) - at(BARS[a][1], n), axis=1)
                                for a in axis_names])

    out: list[Family] = []
    two = [t for t in "AB" if len(held[t]) == 2]
    if two:  # a tip at one of two mirror points, the other on a circle
        tip = two[0]
        mover = "B" if tip == "A" else "A"
        (b0, b1), = [held[tip]]
        spots = _meet(pins[BARS[b0][0]], fixed[b0], pins[BARS[b1][0]], fixed[b1])
        (rest,) = [n for n in fixed if n not in (b0, b1)]
        for spot in spots:
            centre = spot if other(rest, mover) == tip else pins[other(rest, mover)]
            r = fixed[rest]

            def along(t: np.ndarray, centre: Point = centre, r: float = r,
                      spot: Point = spot) -> np.ndarray:
                m = centre[None, :] + r * np.column_stack([np.cos(t), np.sin(t)])
                return image({mover: m, tip: np.broadcast_to(spot, m.shape)})

            n0 = max(int(np.ceil(2 * np.pi * r * np.sqrt(2) / step)), 8) + 1
            fam = _refined(along, np.linspace(0.0, 2 * np.pi, n0), step)
            if fam is None:
                return None
            out.append(fam)
        return out
    # a planar four-bar P - A - B - Q, coupler L2
    (ba,), (bb,) = held["A"], held["B"]
    p, q = pins[BARS[ba][0]], pins[BARS[bb][0]]
    r1, l2, r3 = fixed[ba], fixed["L2"], fixed[bb]
    g = float(np.linalg.norm(q - p))
    if g == 0.0:
        return None
    tq = float(np.arctan2(*(q - p)[::-1]))

    def u_of(dist: float) -> float:  # |theta - theta_Q| where |A - Q| = dist
        return float(np.arccos(np.clip((r1 * r1 + g * g - dist * dist) / (2 * r1 * g), -1, 1)))

    ua, ub = u_of(abs(l2 - r3)), u_of(l2 + r3)
    if l2 + r3 < abs(r1 - g) or abs(l2 - r3) > r1 + g:
        return out  # B never exists
    arcs = [(tq - ub, tq + ub)] if ua == 0.0 else [(tq + ua, tq + ub), (tq - ub, tq - ua)]
    if ua == 0.0 and ub == np.pi:
        arcs = [(0.0, 2 * np.pi)]
    elif ub == np.pi and ua > 0.0:
        arcs = [(tq + ua, tq + 2 * np.pi - ua)]
    for lo, hi in arcs:
        for side in ((1.0, -1.0) if hi - lo >= 2 * np.pi else (1.0,)):
            def loop(t: np.ndarray, lo: float = lo, hi: float = hi, side: float = side
                     ) -> np.ndarray:
                # t in [0, 2]: out along +, back along - (the whole circle: one side per loop)
                whole = hi - lo >= 2 * np.pi
                theta = lo + (hi - lo) * np.where(t <= 1, t, 2 - t) if not whole \
                    else lo + (hi - lo) * t / 2
                sgn = np.where(t <= 1, 1.0, -1.0) if not whole else np.full(len(t), side)
                a = p[None, :] + r1 * np.column_stack([np.cos(theta), np.sin(theta)])
                d = np.linalg.norm(q[None, :] - a, axis=1)
                e = (q[None, :] - a) / np.maximum(d, 1e-300)[:, None]
                along = (d * d + l2 * l2 - r3 * r3) / (2 * d)
                h = np.sqrt(np.maximum(l2 * l2 - along * along, 0.0))
                b = a + along[:, None] * e + (sgn * h)[:, None] * np.column_stack(
                    [-e[:, 1], e[:, 0]])
                return image({"A": a, "B": b})

            n0 = max(int(np.ceil(2 * (hi - lo) * r1 * np.sqrt(2) / step)), 16) + 1
            fam = _refined(loop, np.linspace(0.0, 2.0, n0), step)
            if fam is None:
                return None
            out.append(fam)
    return out


def _runs(family: Family, lo: np.ndarray, hi: np.ndarray) -> Curves:
    """The pieces of a sampled family inside ``[lo, hi]``, each ended where it crosses the
    edge (bisected on the family's parameter: the crossing lies on the curve)."""
    f, t = family
    points = f(t)
    inside = np.all((points >= lo) & (points <= hi), axis=1)
    out: Curves = []
    run: list[np.ndarray] = []

    def cut(t_in: float, t_out: float) -> np.ndarray:
        for _ in range(MAX_HALVINGS):
            mid = 0.5 * (t_in + t_out)
            q = f(np.array([mid]))[0]
            if np.all((q >= lo) & (q <= hi)):
                t_in = mid
            else:
                t_out = mid
        return np.clip(f(np.array([t_in]))[0], lo, hi)

    for k, q in enumerate(points):
        if inside[k]:
            if not run and k > 0:
                run.append(cut(float(t[k]), float(t[k - 1])))
            run.append(q)
        elif run:
            run.append(cut(float(t[k - 1]), float(t[k])))
            out.append(np.array(run))
            run = []
    if run:
        out.append(np.array(run))
    return [r for r in out if len(r) >= 2]


def _triangle_lines(sf: SphericalFourBar, lengths: np.ndarray, axes: tuple[int, int]
                    ) -> list[tuple[np.ndarray, float, int, float]]:
    """The flat triangles as lines ``n . (x, y) = c`` of the map: ``(n, c, triangle, arc)``
    with ``arc`` its angle there (0 or ``pi``), for each triangle with an axis among its
    sides."""
    # (a negative side is a pin's distance from the centre: -1 for G1, -2 for G2)
    sides = [(-1, sf.radii[0], sf.chords[0]), (sf.radii[0], sf.radii[1], sf.chords[1]),
             (sf.radii[1], -2, sf.chords[2])]
    out = []
    for k, tri in enumerate(sides):
        const, rows = np.zeros(3), np.zeros((3, 2))  # each side as const + rows . (x, y)
        for m, s in enumerate(tri):
            if s < 0:
                const[m] = sf.pin_radii[-s - 1]
            elif s in axes:
                rows[m, axes.index(s)] = 1.0
            else:
                const[m] = float(lengths[s])
        if not rows.any():
            continue
        for sp, sq, arc_at in ((1.0, 1.0, np.pi), (1.0, -1.0, 0.0), (-1.0, 1.0, 0.0)):
            # chord = sp p + sq q:  (rows[2] - sp rows[0] - sq rows[1]) . xy = sp cp + sq cq - cc
            coef = rows[2] - sp * rows[0] - sq * rows[1]
            c = sp * const[0] + sq * const[1] - const[2]
            if coef.any():
                out.append((coef, float(c), k, arc_at))
    return out


def _crossings(n: np.ndarray, c: float, p0: np.ndarray, d: np.ndarray, curves: Curves,
               near: float) -> list[float]:
    """Where the segment ``p0 + t d`` (t in [0, 1]) of the line ``n . x = c`` meets the
    polylines, as ``t``: their sign changes of ``n . x - c`` (interpolated), and the points
    within ``near`` of the line (projected: a curve touching the line between two samples)."""
    out: list[float] = []
    dd, nn = float(d @ d), float(np.linalg.norm(n))
    for pts in curves:
        v = pts @ n - c
        for i in np.flatnonzero(v[:-1] * v[1:] <= 0.0):
            w = v[i] - v[i + 1]
            x = pts[i] if w == 0.0 else pts[i] + (v[i] / w) * (pts[i + 1] - pts[i])
            out.append(float((x - p0) @ d) / dd)
        close = pts[np.abs(v) <= near * nn]
        out += ((close - p0) @ d / dd).tolist()
    return out


def _assembling(sf: SphericalFourBar, lengths: np.ndarray, axes: tuple[int, int], k: int,
                at: float, xy: np.ndarray) -> np.ndarray:
    """(m,) whether the linkage assembles at the map's points ``xy`` (m, 2) with triangle
    ``k`` flat (its arc ``at``)."""
    ln = np.tile(lengths, (len(xy), 1))
    ln[:, list(axes)] = xy
    ra, rb = ln[:, sf.radii[0]], ln[:, sf.radii[1]]
    p = np.column_stack([np.full(len(xy), sf.pin_radii[0]), ra, rb])
    q = np.column_stack([ra, rb, np.full(len(xy), sf.pin_radii[1])])
    arcs = arc(p, q, ln[:, list(sf.chords)])  # (m, 3)
    arcs[:, k] = at
    return np.asarray(~np.isnan(arcs).any(axis=1) & assembles(np.nan_to_num(arcs), sf.gamma))


def _edge_pieces(sf: SphericalFourBar, lengths: np.ndarray, axes: tuple[int, int],
                 line: tuple[np.ndarray, float, int, float],
                 box: tuple[np.ndarray, np.ndarray], step: float, flat: Curves,
                 lines: list[tuple[np.ndarray, float, int, float]]) -> Curves:
    """The pieces in the box of a flat triangle's line where the rest assembles: the line cut
    at a quarter step and wherever a flat curve or another triangle's line meets it, each
    interval kept by its midpoint, a change between two intervals bisected to its place."""
    n, c, k, at = line
    seg = _clip_segment(n, c, *box)
    if seg is None or not float((seg[1] - seg[0]) @ (seg[1] - seg[0])) > 0.0:
        return []
    p0, d = seg[0], seg[1] - seg[0]
    size = float(np.linalg.norm(d))
    cuts = np.linspace(0.0, 1.0, max(int(np.ceil(4 * size / step)), 4) + 1).tolist()
    cuts += [t for t in _crossings(n, c, p0, d, flat, step) if 0.0 < t < 1.0]
    for n2, c2, _, _ in lines:  # another triangle's range ends on its own lines
        den = float(n2 @ d)
        if den != 0.0 and 0.0 < (t := (c2 - float(n2 @ p0)) / den) < 1.0:
            cuts.append(t)
    ts = np.unique(np.array(cuts))
    mids = 0.5 * (ts[:-1] + ts[1:])
    ok = _assembling(sf, lengths, axes, k, at, p0[None, :] + mids[:, None] * d[None, :])

    def edge(t_in: float, t_out: float) -> float:  # where assembling ends between them
        for _ in range(MAX_HALVINGS):
            mid = 0.5 * (t_in + t_out)
            if _assembling(sf, lengths, axes, k, at, (p0 + mid * d)[None, :])[0]:
                t_in = mid
            else:
                t_out = mid
        return t_in

    out: Curves = []
    start = 0.0 if ok[0] else None
    for i in range(1, len(ok) + 1):
        if i < len(ok) and ok[i] == ok[i - 1]:
            continue
        if i < len(ok) and ok[i]:
            start = edge(float(mids[i]), float(mids[i - 1]))
        elif start is not None:
            end = 1.0 if i == len(ok) else edge(float(mids[i - 1]), float(mids[i]))
            a, b = p0 + start * d, p0 + end * d
            m = max(int(np.ceil(float(np.linalg.norm(b - a)) / step)), 1) + 1
            out.append(a[None, :] + np.linspace(0, 1, m)[:, None] * (b - a)[None, :])
            start = None
    return out


def radius_curves(linkage: Linkage, axes: tuple[int, int], box: np.ndarray, step: float,
                  shortest: float) -> Curves | None:
    """Every critical curve of a spherical four-bar over the box of two of its bars, a
    radius among them (see the module docstring), each piece (n, 2) sampled at most ``step``
    apart; None when the linkage is not a spherical four-bar, no axis is a radius, a triangle
    without an axis is flat (every length critical) or the samples exceed ``MAX_SAMPLES``.

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
    if sf is None or axes[0] == axes[1] or not set(axes) & set(sf.radii) or \
            not set(axes) <= set(sf.radii) | set(sf.chords):
        return None
    lengths = np.asarray(linkage.lengths, dtype=float)
    free = [{sf.radii[0], sf.chords[0]}, set(sf.radii) | {sf.chords[1]},
            {sf.radii[1], sf.chords[2]}]  # the bars of each triangle that may be axes
    fixed_arcs = sf.arcs(lengths)
    for k in range(3):
        if not free[k] & set(axes):
            if np.isnan(fixed_arcs[k]):
                return []  # that triangle never closes: empty all over the box
            if not DEGENERATE_ARC < fixed_arcs[k] < np.pi - DEGENERATE_ARC:
                return None
    lo, hi = np.maximum(box[:, 0], shortest), box[:, 1].astype(float)
    family = _family(sf, lengths, axes, step)
    if family is None:
        return None
    curves = [r for c in family for r in _runs(c, lo, hi)]
    lines = _triangle_lines(sf, lengths, axes)
    flat = list(curves)
    for n, c, k, at in lines:
        curves += _edge_pieces(sf, lengths, axes, (n, c, k, at), (lo, hi), step, flat, lines)
    return curves
