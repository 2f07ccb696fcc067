"""The critical curves of a three-rotor (a rotor chain of two cells) over a map's box, in closed
form.

Notation of :mod:`.chain_planes`: pins ``P_0, P_1, P_2``, rotors ``r_k`` to tips ``T_k``,
couplers ``l_0`` (``T_0 T_1``) and ``l_1`` (``T_1 T_2``), pin spacings ``a_k``, ``e_k`` the unit
vector from ``P_k`` to ``P_(k+1)``. A configuration is critical iff ``alpha_i = 0`` and
``beta_j = 0`` for some ``i <= j`` (``alpha_k = 0``: ``P_k, T_k, T_(k+1)`` on one line;
``beta_k = 0``: ``T_k, T_(k+1), P_(k+1)`` on one line), so the critical configurations are of
three kinds, and their lengths are the whole critical value set:

- ``(0, 0)``, ``(1, 1)``: a cell flat, its four joints on one line, ``s_1 r_k + s_2 l_k + s_3
  r_(k+1) = a_k`` (signs ``s``), with ``T_1 = P_1 - s_3 r_1 e_0`` (cell 0) or ``T_1 = P_1 + s_1
  r_1 e_1`` (cell 1). It is a configuration of the chain exactly where the other cell assembles
  at that ``T_1``: ``|r - l| <= |T_1 - P| <= r + l`` (that cell's pin ``P``, rotor ``r`` and
  coupler ``l``). On a line of the slice ``T_1`` is affine in the line's parameter, so the
  pieces where this holds end at real roots of two quadratics.
- ``(0, 1)``: both dyads straight, ``T_0`` on the line ``P_0 T_1`` and ``T_2`` on the line ``P_2
  T_1``: ``|T_1 - P_0| = |r_0 +- l_0|``, ``|T_1 - P_1| = r_1``, ``|T_1 - P_2| = |r_2 +- l_1|``,
  three circles through one point. Every such ``T_1`` extends to a configuration (``T_0`` and
  ``T_2`` on those lines), rigid where a component is born or dies. Each radius ``rho_k`` is
  affine in the map's axes ``(X, Y)`` (for a choice of the signs); the two axes are bars of at
  most two of them, so one radius ``rho_f`` is fixed: ``T_1 = P_f + rho_f (cos t, sin t)`` and
  the two other radii equal the distances ``D_k(t) = |T_1(t) - P_k|``, two linear equations in
  ``(X, Y)``: the explicit closed curve ``(X(t), Y(t))``; or, where both axes are bars of one
  radius, the third radius fixes ``t`` (``cos(t - phi) = h``) and the curve is a line.

Each piece in the box is sampled at most ``step`` apart (``(X(t), Y(t))`` moves at most
``|A^-1| sqrt(2) rho_f`` per radian).

>>> from engine.catalogue.presets import build_preset
>>> lk = build_preset("three-rotor")
>>> curves = two_cell_curves(lk, (3, 4), np.array([[0.6, 1.4], [0.6, 1.4]]), 0.01, 1e-9)
>>> len(curves) >= 3
True
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np

from engine.design.chain_planes import SIGNS, _affine
from engine.model.linkage import Linkage
from engine.space.chain_count import _chain_order

#: Samples of one closed curve beyond which the closed form declines (a curve whose radius is
#: this many tracing steps).
MAX_SAMPLES = 200_000
#: Relative size below which a fixed radius, a pin spacing or a determinant is zero (a
#: degenerate chain: the closed form declines or the piece is a point).
DEGENERATE_RTOL = 1e-12
#: Fewest samples of a closed curve (its chords within ``pi^2 / (2 * 64^2)``, 0.12 %, of its
#: radius: a loop smaller than a step is drawn round, not as a polygon of a few sides).
LOOP_SAMPLES = 65
#: Halvings of a curve's parameter between the samples around its crossing of the box's edge.
EDGE_BISECTIONS = 52

Curves = list[np.ndarray]


def two_cell_curves(linkage: Linkage, axes: tuple[int, int], box: np.ndarray, step: float,
                    shortest: float) -> Curves | None:
    """Every critical curve of a three-rotor over the box of two of its bars' lengths (see the
    module docstring), each piece (n, 2) in the box sampled at most ``step`` apart; None when
    the linkage is not a rotor chain of two cells, an axis is not one of its bars, it is
    degenerate (two pins on one point; a cell flat at every length of the box, see
    :func:`flat_everywhere`) or a closed curve would need more than ``MAX_SAMPLES`` samples.

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
    found = _chain_order(linkage)
    if found is None or len(found[0]) != 3:
        return None
    tips, rotors, couplers = found
    if not set(axes) <= set(rotors) | set(couplers):
        return None
    pins = _pins(linkage, rotors, tips)
    spacing = np.linalg.norm(np.diff(pins, axis=0), axis=1)  # (2,)
    scale = float(max(np.max(linkage.lengths), np.max(np.abs(pins)), 1.0))
    if np.min(spacing) <= DEGENERATE_RTOL * scale or \
            np.linalg.norm(pins[2] - pins[0]) <= DEGENERATE_RTOL * scale:
        return None
    lo = np.maximum(box[:, 0], shortest)
    cut = np.array([lo, box[:, 1]]).T  # (2, 2) the box the pieces are drawn in
    rows = _affine([rotors[0], couplers[0], rotors[1], couplers[1], rotors[2]], axes,
                   linkage.lengths)  # (5, 3): r0, l0, r1, l1, r2 over (1, X, Y)
    curves = _flat_cells(pins, spacing, rows, cut, step, scale)
    if curves is None:
        return None
    both = _both_straight(pins, rows, cut, step, scale)
    return None if both is None else curves + both


def flat_everywhere(linkage: Linkage, axes: tuple[int, int]) -> str | None:
    """A cell of a three-rotor that is flat at every length of the map (neither axis one of
    its bars, its lengths on a plane ``+-r_k +-l_k +-r_(k+1) = a_k``): every length where the
    other cell assembles at the flat cell's middle tip is then critical, a piece of the plane
    of the map rather than curves. The sentence that says so, or None."""
    found = _chain_order(linkage)
    if found is None or len(found[0]) != 3:
        return None
    tips, rotors, couplers = found
    pins = _pins(linkage, rotors, tips)
    scale = float(max(np.max(linkage.lengths), np.max(np.abs(pins)), 1.0))
    for k in range(2):
        bars = [rotors[k], couplers[k], rotors[k + 1]]
        if set(axes) & set(bars):
            continue
        lengths = linkage.lengths[bars]
        gap = np.abs(SIGNS @ lengths - float(np.linalg.norm(pins[k + 1] - pins[k])))
        if gap.min() <= DEGENERATE_RTOL * scale:
            names = "-".join(linkage.bar_ids[b] for b in bars)
            return (f"the four-bar cell {names} is flat at every length of the map (its lengths "
                    "on a plane +-r +-l +-r = a, its pins a apart): wherever the other cell "
                    "assembles at its flat configuration the lengths are critical, a piece of "
                    "the plane rather than curves")
    return None


def _pins(linkage: Linkage, rotors: list[int], tips: list[int]) -> np.ndarray:
    """The rotors' pins (3, 2), in chain order."""
    pos = np.asarray(linkage.positions, dtype=float)
    return np.array([pos[int(linkage.ends[b, 0]) if int(linkage.ends[b, 1]) == t
                         else int(linkage.ends[b, 1])] for b, t in zip(rotors, tips, strict=True)])


def _flat_cells(pins: np.ndarray, spacing: np.ndarray, rows: np.ndarray, box: np.ndarray,
                step: float, scale: float) -> Curves | None:
    """The pieces of the flat-cell lines where the other cell assembles (None: a cell flat at
    every length of the box, whose critical set is then not curves)."""
    r0, l0, r1, l1, r2 = rows
    out: Curves = []
    for k in range(2):
        cell = np.array([r0, l0, r1]) if k == 0 else np.array([r1, l1, r2])
        e = (pins[k + 1] - pins[k]) / spacing[k]
        # the other cell: its pin, rotor and coupler
        pin, rot, cpl = (pins[2], r2, l1) if k == 0 else (pins[0], r0, l0)
        for s in SIGNS:
            normal = s @ cell  # (3,): normal . (1, X, Y) = a_k
            if not np.any(normal[1:] != 0.0) and \
                    abs(spacing[k] - normal[0]) <= DEGENERATE_RTOL * scale:
                return None
            seg = _line(normal[1:], spacing[k] - normal[0], box)
            if seg is None:
                continue
            p0, d, t_lo, t_hi = seg
            # T_1 = V0 + t V1 along the line (r_1 affine in t)
            r1_0, r1_1 = r1 @ np.r_[1.0, p0], r1[1:] @ d
            sign = -s[2] if k == 0 else s[0]
            v0, v1 = pins[1] + sign * r1_0 * e, sign * r1_1 * e
            pieces = _assembles(v0 - pin, v1, _along(rot, p0, d), _along(cpl, p0, d),
                                t_lo, t_hi)
            for a, b in pieces:
                t = np.linspace(a, b, int(np.ceil((b - a) / step)) + 1)
                out.append(np.clip(p0[None, :] + t[:, None] * d[None, :], box[:, 0], box[:, 1]))
    return out


def _along(row: np.ndarray, p0: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """An affine length ``row`` over ``(1, X, Y)`` on the line ``p0 + t d``: ``(c, slope)``."""
    return float(row @ np.r_[1.0, p0]), float(row[1:] @ d)


def _line(n: np.ndarray, c: float, box: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """The line ``n . p = c`` cut to the box, as ``p0 + t d`` (``|d| = 1``) for ``t`` in
    ``[t_lo, t_hi]``; None when it misses the box or ``n = 0``."""
    nn = float(n @ n)
    if nn == 0.0:
        return None
    p0 = n * c / nn
    d = np.array([-n[1], n[0]]) / np.sqrt(nn)
    t_lo, t_hi = -np.inf, np.inf
    for m in range(2):
        if d[m] == 0.0:
            if not box[m, 0] <= p0[m] <= box[m, 1]:
                return None
            continue
        ta, tb = sorted(((box[m, 0] - p0[m]) / d[m], (box[m, 1] - p0[m]) / d[m]))
        t_lo, t_hi = max(t_lo, ta), min(t_hi, tb)
    return (p0, d, t_lo, t_hi) if t_hi > t_lo else None


def _assembles(w0: np.ndarray, w1: np.ndarray, rot: tuple[float, float],
               cpl: tuple[float, float], t_lo: float, t_hi: float) -> list[tuple[float, float]]:
    """The intervals of ``[t_lo, t_hi]`` where ``|r - l| <= |w0 + t w1| <= r + l`` (``r``,
    ``l`` affine in ``t``): cut at the real roots of the two quadratics ``|w|^2 - (r -+ l)^2``,
    each piece kept when the conditions hold at its middle."""
    q = np.array([w1 @ w1, 2.0 * (w0 @ w1), w0 @ w0])  # |w|^2, highest power first
    cuts = [t_lo, t_hi]
    for sign in (1.0, -1.0):
        c, slope = rot[0] + sign * cpl[0], rot[1] + sign * cpl[1]
        poly = q - np.array([slope * slope, 2.0 * c * slope, c * c])
        roots = np.roots(poly) if np.any(poly[:2] != 0.0) else np.zeros(0)
        cuts += [float(t.real) for t in roots if abs(t.imag) <= 1e-12 * (1.0 + abs(t))
                 and t_lo < t.real < t_hi]
    cuts = sorted(cuts)
    out: list[tuple[float, float]] = []
    for a, b in itertools.pairwise(cuts):
        if b <= a:
            continue
        t = 0.5 * (a + b)
        dist = float(np.linalg.norm(w0 + t * w1))
        r, ell = rot[0] + t * rot[1], cpl[0] + t * cpl[1]
        if abs(r - ell) <= dist <= r + ell:
            if out and out[-1][1] == a:
                out[-1] = (out[-1][0], b)
            else:
                out.append((a, b))
    return out


def _both_straight(pins: np.ndarray, rows: np.ndarray, box: np.ndarray, step: float,
                   scale: float) -> Curves | None:
    """The pieces in the box of the curves where both dyads are straight (None: a curve would
    need more than ``MAX_SAMPLES`` samples)."""
    r0, l0, r1, l1, r2 = rows
    out: Curves = []
    for s0, t0, s2, t2 in itertools.product((1.0, -1.0), repeat=4):
        radii = np.array([t0 * (r0 + s0 * l0), r1, t2 * (r2 + s2 * l1)])  # (3, 3)
        moving = np.any(radii[:, 1:] != 0.0, axis=1)
        if moving.all():
            return None  # (an axis off the chain's bars: excluded by the caller)
        f = int(np.flatnonzero(~moving)[0])
        rho = float(radii[f, 0])
        if rho <= DEGENERATE_RTOL * scale:
            # a fixed radius negative: no circle (its sign twin draws it); zero: T_1 = P_f, the
            # rotor of that dyad spins on its pin, on a flat-cell line already
            continue
        others = [k for k in range(3) if k != f]
        amat = radii[others, 1:]  # (2, 2)
        if abs(np.linalg.det(amat)) > DEGENERATE_RTOL:
            piece = _loop(pins, radii, f, others, rho, box, step)
            if piece is None:
                return None
            out += piece
        else:
            out += _fixed_point_lines(pins, radii, f, others, rho, box, step)
    return out


def _loop(pins: np.ndarray, radii: np.ndarray, f: int, others: list[int], rho: float,
          box: np.ndarray, step: float) -> Curves | None:
    """The closed curve ``(X(t), Y(t))`` (two radii moving), its pieces in the box."""
    try:
        inv = np.linalg.inv(radii[others, 1:])
    except np.linalg.LinAlgError:  # (its determinant was checked: a safety net)
        return None
    speed = float(np.linalg.norm(inv, 2)) * np.sqrt(2.0) * rho
    n = int(np.ceil(2.0 * np.pi * speed / step)) + 1
    if n > MAX_SAMPLES:
        return None

    def at(t: np.ndarray) -> np.ndarray:
        tip = pins[f] + rho * np.column_stack([np.cos(t), np.sin(t)])  # (n, 2) T_1
        dist = np.linalg.norm(tip[:, None, :] - pins[others][None], axis=2)  # (n, 2)
        return np.asarray((dist - radii[others, 0][None, :]) @ inv.T)  # (n, 2)

    return _inside_pieces(at, np.linspace(0.0, 2.0 * np.pi, max(n, LOOP_SAMPLES)), box)


def _fixed_point_lines(pins: np.ndarray, radii: np.ndarray, f: int, others: list[int],
                       rho: float, box: np.ndarray, step: float) -> Curves:
    """Both axes in one radius: the other fixed radius ``c`` puts ``T_1`` at the points of the
    circle about ``P_f`` at distance ``c`` from its pin; the moving radius equals the distance
    from there, a line in ``(X, Y)``."""
    fixed = [k for k in others if not np.any(radii[k, 1:] != 0.0)]
    if len(fixed) != 1:
        return []  # (two moving radii of one axis each, parallel: none in a three-rotor)
    j = fixed[0]
    k = others[0] if others[1] == j else others[1]
    c = float(radii[j, 0])
    w = pins[f] - pins[j]
    omega = float(np.linalg.norm(w))
    if c < 0.0 or omega == 0.0:
        return []
    h = (c * c - omega * omega - rho * rho) / (2.0 * rho * omega)  # cos(t - phi)
    if abs(h) > 1.0:
        return []
    phi = float(np.arctan2(w[1], w[0]))
    out: Curves = []
    for t in {phi + np.arccos(h), phi - np.arccos(h)}:
        tip = pins[f] + rho * np.array([np.cos(t), np.sin(t)])
        seg = _line(radii[k, 1:], float(np.linalg.norm(tip - pins[k])) - radii[k, 0], box)
        if seg is None:
            continue
        p0, d, t_lo, t_hi = seg
        s = np.linspace(t_lo, t_hi, int(np.ceil((t_hi - t_lo) / step)) + 1)
        out.append(np.clip(p0[None, :] + s[:, None] * d[None, :], box[:, 0], box[:, 1]))
    return out


def _inside_pieces(at: Callable[[np.ndarray], np.ndarray], t: np.ndarray, box: np.ndarray
                   ) -> Curves:
    """The runs inside the box of the closed curve ``at(t)`` sampled at ``t`` (n,; ``at`` of the
    first and last the same point), each ended where the curve crosses the box's edge (the
    crossing's parameter bisected between the samples around it)."""
    lo, hi = box[:, 0], box[:, 1]
    xy = at(t)

    def inside(q: np.ndarray) -> np.ndarray:
        return np.asarray(np.all((q >= lo) & (q <= hi), axis=-1))

    flags = inside(xy)
    if flags.all():
        return [xy]
    if not flags.any():
        return []
    start = int(np.flatnonzero(~flags)[0])  # the ring starts and ends outside
    period = t[-1] - t[0]
    ring_t = np.concatenate([t[start:-1], t[:start + 1] + period])
    ring, ring_in = np.concatenate([xy[start:-1], xy[:start + 1]]), \
        np.concatenate([flags[start:-1], flags[:start + 1]])
    out: Curves = []
    k = 0
    while k < len(ring):
        if not ring_in[k]:
            k += 1
            continue
        e = k
        while e + 1 < len(ring) and ring_in[e + 1]:
            e += 1
        first = _edge(at, ring_t[k], ring_t[k - 1], inside)
        last = _edge(at, ring_t[e], ring_t[e + 1], inside)
        out.append(np.clip(np.vstack([first, ring[k:e + 1], last]), lo, hi))
        k = e + 1
    return out


def _edge(at: Callable[[np.ndarray], np.ndarray], t_in: float, t_out: float,
          inside: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """The point of ``at`` where it leaves the box between ``t_in`` (inside) and ``t_out``:
    ``EDGE_BISECTIONS`` halvings of the parameter, the last inside point (on the edge to
    rounding)."""
    a, b = t_in, t_out
    for _ in range(EDGE_BISECTIONS):
        mid = 0.5 * (a + b)
        if inside(at(np.array([mid]))[0]):
            a = mid
        else:
            b = mid
    return np.asarray(at(np.array([a]))[0])
