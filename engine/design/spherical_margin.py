"""Exact robustness margins of spherical four-bars in the lengths of one or two of their chords.

Notation of :mod:`.spherical_curves`. With the radii ``OA``, ``OB`` and the other chords fixed,
the critical lengths of the adjustable chords are the flat equalities ``s . alpha = gamma +
2 pi k`` and the flat triangles ``L_i = |p_i - q_i|`` or ``p_i + q_i`` where the rest assembles.

- One adjustable chord: each equality fixes its arc, hence its length, in closed form; the
  margin is the nearest.
- Two: an equality is a segment in the two arcs, mapped to lengths by ``L = c(alpha)``
  (``|dL/dalpha| <= min(p, q)``), so along its parameter ``t`` the distance ``d(t)`` to the
  design has a known Lipschitz bound ``V``. A branch and bound over ``t`` (an interval is
  dropped once ``d(mid) - V w / 2`` is above the best value found less ``CERTIFY_RTOL`` times
  the lengths' scale) proves that no point of the segment is nearer than the best found by more
  than that: the minimum over every segment is the margin, exact to that tolerance.
- A flat triangle: its piece is the line ``L_i = e`` where the rest assembles; the nearest point
  of the line, the design's other length kept, is its distance if the rest assembles there;
  otherwise the nearest point of the piece is an end of it, where the assembly changes: on a
  flat equality (counted above) or on another triangle's line (the corner, counted too).

Three adjustable chords, or a radius among them, are left to the multistart.
"""

from __future__ import annotations

import itertools

import numpy as np

from engine.design.dyad_margin import ExactMargin
from engine.design.spherical_curves import (
    SphericalFourBar,
    _clip_segment,
    assembles,
    chord,
    spherical_four_bar,
)
from engine.model.budget import NEVER, Deadline
from engine.model.linkage import Linkage

#: The margin is certified to this times the largest length (the branch and bound's gap).
CERTIFY_RTOL = 1e-10
#: Distance evaluations of the branch and bounds of one margin at most (beyond: declined).
MAX_EVALUATIONS = 4_000_000
#: Intervals each segment starts with.
START_INTERVALS = 256
#: What the pieces are, in a margin's answer.
SPHERICAL_PIECES = (f"critical pieces of a spherical four-bar's chords (arc equalities and flat "
                    f"triangles; certified to {CERTIFY_RTOL:g} of its longest bar)")


def _segment_min(p: np.ndarray, q: np.ndarray, pq: np.ndarray, target: np.ndarray,
                 tol: float, budget: list[int], deadline: Deadline
                 ) -> tuple[float, np.ndarray] | None:
    """The least distance from ``target`` (2,) of ``c(p + t (q - p))``, t in [0, 1], to within
    ``tol`` (branch and bound, see the module docstring), and the arcs there; None once the
    evaluations left (``budget[0]``, spent here) run out or the deadline passes."""
    slope = pq.min(axis=1)  # (2,)
    speed = float(np.hypot(*(slope * np.abs(q - p))))

    def dist(t: np.ndarray) -> np.ndarray:
        arcs = p[None, :] + t[:, None] * (q - p)[None, :]
        xy = np.column_stack([chord(pq[m, 0], pq[m, 1], arcs[:, m]) for m in range(2)])
        return np.asarray(np.linalg.norm(xy - target[None, :], axis=1))

    ends = np.array([0.0, 1.0])
    d_ends = dist(ends)
    k = int(np.argmin(d_ends))
    best, best_t = float(d_ends[k]), float(ends[k])
    lo = np.linspace(0.0, 1.0, START_INTERVALS + 1)[:-1]
    width = 1.0 / START_INTERVALS
    while len(lo):
        budget[0] -= len(lo)
        if budget[0] < 0 or deadline.expired():
            return None
        mid = lo + width / 2
        d = dist(mid)
        k = int(np.argmin(d))
        if d[k] < best:
            best, best_t = float(d[k]), float(mid[k])
        keep = d - speed * width / 2 < best - tol
        width /= 2
        lo = np.concatenate([lo[keep], lo[keep] + width])
    return best, p + best_t * (q - p)


def _meet(r0: float, p1: np.ndarray, d1: float, p2: np.ndarray, d2: float) -> np.ndarray | None:
    """A point at ``r0`` from the origin, ``d1`` from ``p1`` and ``d2`` from ``p2`` (3D)."""
    normal = np.cross(p1, p2)
    gram = np.array([[p1 @ p1, p1 @ p2], [p1 @ p2, p2 @ p2]])
    rhs = np.array([r0**2 + p1 @ p1 - d1**2, r0**2 + p2 @ p2 - d2**2]) / 2
    try:
        s, t = np.linalg.solve(gram, rhs)
    except np.linalg.LinAlgError:
        return None
    base = s * p1 + t * p2  # (gram nonsingular: normal is not zero)
    h2 = (r0**2 - float(base @ base)) / float(normal @ normal)
    return base + np.sqrt(max(h2, 0.0)) * normal


def _configuration(linkage: Linkage, sf: SphericalFourBar, lengths: np.ndarray,
                   arcs: np.ndarray, signs: np.ndarray | None) -> np.ndarray | None:
    """A critical configuration ``u`` (M,) at ``lengths``: flat with the walk ``signs`` (3,),
    or (``signs`` None) with the flat triangle among ``arcs`` (0 or ``pi``) and the rest met
    by three spheres."""
    pos = np.array(linkage.positions, dtype=float)
    ends = np.asarray(linkage.ends)
    full: np.ndarray = np.asarray(np.asarray(linkage.fixed, dtype=bool).all(axis=1))
    tip = [int(e) for b in sf.radii for e in ends[b] if not full[e]]  # A, B
    centre = int(next(e for e in ends[sf.radii[0]] if full[e]))
    g1, g2 = (pos[int(next(e for e in ends[sf.chords[k]] if full[e]))] - pos[centre]
              for k in (0, 2))
    e1 = g1 / np.linalg.norm(g1)
    e2 = g2 - (g2 @ e1) * e1
    e2 /= np.linalg.norm(e2)
    ra, rb = float(lengths[sf.radii[0]]), float(lengths[sf.radii[1]])
    l1, l2, l3 = (float(lengths[b]) for b in sf.chords)
    if signs is not None:
        phi_a = signs[0] * arcs[0]
        phi_b = phi_a + signs[1] * arcs[1]
        a = ra * (np.cos(phi_a) * e1 + np.sin(phi_a) * e2)
        b = rb * (np.cos(phi_b) * e1 + np.sin(phi_b) * e2)
    elif arcs[0] in (0.0, np.pi):
        a = ra * np.cos(arcs[0]) * e1
        b = _meet(rb, g2, l3, a, l2)
    elif arcs[2] in (0.0, np.pi):
        b = rb * np.cos(arcs[2]) * g2 / np.linalg.norm(g2)
        a = _meet(ra, g1, l1, b, l2)
    else:  # O, A, B on one line: a's direction at alpha_1 from g1 and alpha_3 from +-g2
        side = np.cos(arcs[1])
        w = _meet(1.0, e1, 2 * np.sin(arcs[0] / 2), side * g2 / np.linalg.norm(g2),
                  2 * np.sin(arcs[2] / 2))
        a, b = (None, None) if w is None else (ra * w, rb * side * w)
    if a is None or b is None:
        return None
    pos[tip[0]], pos[tip[1]] = pos[centre] + a, pos[centre] + b
    return linkage.coordinates(pos)


def spherical_margin(linkage: Linkage, adjustable: np.ndarray, shortest: float,
                     deadline: Deadline = NEVER) -> ExactMargin | None:
    """The exact margin of a spherical four-bar over one or two adjustable chords (see the
    module docstring), or None: not a spherical four-bar, a radius or all three chords
    adjustable, or a segment's branch and bound past its budget.

    Parameters
    ----------
    linkage : Linkage
    adjustable : (E,) bool
        The bars whose lengths may change (every bar of the linkage).
    shortest : float
        Critical lengths below this are degenerate, not critical.
    deadline : Deadline, optional
        Checked at every level of the branch and bounds.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("spherical-four-bar")
    >>> adj = np.zeros(lk.n_bars, dtype=bool)
    >>> adj[lk.bar_ids.index("L1")] = True
    >>> round(spherical_margin(lk, adj, 1e-9).margin, 6)
    0.287028
    """
    sf = spherical_four_bar(linkage)
    if sf is None or adjustable[list(sf.radii)].any():
        return None
    adj = [i for i in range(3) if adjustable[sf.chords[i]]]
    if not 1 <= len(adj) <= 2:
        return None
    lengths = np.asarray(linkage.lengths, dtype=float)
    arcs0, sides = sf.arcs(lengths), sf.sides(lengths)
    if np.isnan(arcs0).any():
        return None
    target = lengths[[sf.chords[i] for i in adj]]
    tol = CERTIFY_RTOL * float(lengths.max())
    found: list[tuple[float, np.ndarray, np.ndarray | None]] = []  # (d, arcs, signs)
    budget = [MAX_EVALUATIONS]

    def take(arcs: np.ndarray, signs: np.ndarray | None) -> None:
        ln = np.array([chord(sides[i, 0], sides[i, 1], arcs[i]) for i in adj])
        if np.all(ln >= shortest):
            found.append((float(np.linalg.norm(ln - target)), arcs, signs))

    fixed = [i for i in range(3) if i not in adj]
    for s, k in itertools.product(itertools.product((1.0, -1.0), repeat=3), (-1, 0, 1)):
        signs = np.array(s)
        c = sf.gamma + 2 * np.pi * k - float(signs[fixed] @ arcs0[fixed])
        if len(adj) == 1:
            beta = signs[adj[0]] * c
            if 0.0 <= beta <= np.pi:
                arcs = arcs0.copy()
                arcs[adj[0]] = beta
                take(arcs, signs)
            continue
        seg = _clip_segment(signs[adj], c, np.zeros(2), np.full(2, np.pi))
        if seg is None:
            continue
        best = _segment_min(seg[0], seg[1], sides[adj], target, tol, budget, deadline)
        if best is None:
            return None
        arcs = arcs0.copy()
        arcs[adj] = best[1]
        take(arcs, signs)
    # flat triangles of the adjustable chords, and their corners
    edges = [(i, e) for i in adj for e in (0.0, np.pi)]
    for combo in [[x] for x in edges] + [[x, y] for x, y in itertools.combinations(edges, 2)
                                         if x[0] != y[0]]:
        arcs = arcs0.copy()
        for i, e in combo:
            arcs[i] = e
        if bool(assembles(arcs, sf.gamma)):
            take(arcs, None)
    if not found:
        return ExactMargin(np.inf, lengths.copy(), linkage.coordinates(), 0)
    d, at, walk = min(found, key=lambda f: f[0])
    nearest = lengths.copy()
    for i in adj:
        nearest[sf.chords[i]] = chord(sides[i, 0], sides[i, 1], at[i])
    u = _configuration(linkage, sf, nearest, at, walk)
    return ExactMargin(d, nearest, linkage.coordinates() if u is None else u, len(found))
