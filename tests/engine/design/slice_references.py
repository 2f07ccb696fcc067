"""Independent references for the slice tests: closed-form critical sets of the three-rotor and
of the gated chain's gate, and their configuration spaces by dense sampling of the driving rotor
with closed-form circle intersections (nothing from the engine)."""

from __future__ import annotations

import itertools

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

# the default three-rotor: pins P1 = (0, 0), P2 = (1, 0), P3 = P2 + (cos phi, sin phi), phi = pi/2
P1, P2, P3 = np.array([0.0, 0.0]), np.array([1.0, 0.0]), np.array([1.0, 1.0])
R1 = R2 = R3 = 1.0


def three_rotor_lines() -> tuple[list[float], list[float]]:
    """One dyad collinear with the middle rotor (a four-bar P1 A B P2 or P2 B C P3 straight):
    ``L1 = |+-|P1P2| +- r1 +- r2|`` (vertical lines), ``L2`` likewise with ``|P2P3|``."""
    a12, a23 = float(np.linalg.norm(P2 - P1)), float(np.linalg.norm(P3 - P2))
    signs = list(itertools.product((1, -1), repeat=2))
    vertical = sorted({round(abs(a12 + s1 * R1 + s2 * R2), 12) for s1, s2 in signs} - {0.0})
    horizontal = sorted({round(abs(a23 + s1 * R2 + s2 * R3), 12) for s1, s2 in signs} - {0.0})
    return vertical, horizontal


def three_rotor_arcs(samples: int = 20001) -> list[np.ndarray]:
    """Both dyads collinear (A on the line P1 B, C on the line P3 B, B on its circle): with
    ``d1 = |P1 B|``, ``d3 = |P3 B|``, ``L1`` is ``d1 - r1``, ``r1 - d1`` or ``d1 + r1`` and ``L2``
    likewise: nine curves ``(L1(t), L2(t))`` over the middle rotor's angle ``t`` (L > 0)."""
    t = np.linspace(0.0, 2 * np.pi, samples)
    b = P2 + R2 * np.column_stack([np.cos(t), np.sin(t)])
    d1, d3 = np.linalg.norm(b - P1, axis=1), np.linalg.norm(b - P3, axis=1)
    out = []
    for l1 in (d1 - R1, R1 - d1, d1 + R1):
        for l2 in (d3 - R3, R3 - d3, d3 + R3):
            ok = (l1 > 0) & (l2 > 0)
            out.append(np.column_stack([l1, l2])[ok])
    return out


def three_rotor_residual(l1: float, l2: float) -> float:
    """Distance (in length) of ``(L1, L2)`` from the closed-form critical set: the nearest line,
    or for the arcs ``| |P3 B| - (r3 +- L2) |`` over the points ``B`` of the middle rotor's circle
    at distance ``r1 + L1`` or ``|r1 - L1|`` from ``P1`` (circle intersections)."""
    vertical, horizontal = three_rotor_lines()
    best = min([abs(l1 - v) for v in vertical] + [abs(l2 - h) for h in horizontal])
    for rho in (R1 + l1, abs(R1 - l1)):
        for b in circle_points(P1, rho, P2, R2):
            d3 = float(np.linalg.norm(b - P3))
            best = min(best, abs(d3 - (R3 + l2)), abs(d3 - abs(R3 - l2)))
    return best


def circle_points(c0: np.ndarray, r0: float, c1: np.ndarray, r1: float) -> list[np.ndarray]:
    """The (up to two) points at distance ``r0`` from ``c0`` and ``r1`` from ``c1``."""
    d = float(np.linalg.norm(c1 - c0))
    along = (d * d + r0 * r0 - r1 * r1) / (2 * d)
    h2 = r0 * r0 - along * along
    if h2 < 0:
        return []
    e = (c1 - c0) / d
    n = np.array([-e[1], e[0]])
    return [c0 + along * e + s * np.sqrt(h2) * n for s in (1.0, -1.0)]


def _dyad(pin: np.ndarray, r: float, tips: np.ndarray, length: float) -> np.ndarray:
    """Discriminant (N,) of the dyad from ``pin`` (bar ``r``) and the moving ``tips`` (N, 2) (bar
    ``length``): non-negative where it assembles."""
    d = np.linalg.norm(tips - pin, axis=1)
    return np.minimum(d - abs(r - length), r + length - d)


def components_by_sampling(discs: list[np.ndarray]) -> int:
    """Components of a configuration space sampled over a driving rotor's angle (N samples on
    the circle), with one dyad per discriminant (N,) in ``discs``, each with two assemblies that
    join where its discriminant changes sign between samples: nodes are (sample, choice of
    assemblies) where every dyad assembles, joined along the angle, and the two assemblies of a
    dyad joined at the last sample before it stops assembling."""
    n, k = len(discs[0]), len(discs)
    ok = np.all([d >= 0 for d in discs], axis=0)  # (N,)
    choices = list(itertools.product((0, 1), repeat=k))
    index = {c: i for i, c in enumerate(choices)}
    node = np.arange(n)[:, None] * len(choices) + np.arange(len(choices))[None, :]
    rows, cols = [], []
    nxt = np.roll(np.arange(n), -1)
    both = ok & ok[nxt]
    for c in choices:
        rows.append(node[both, index[c]])
        cols.append(node[nxt[both], index[c]])
    for j, d in enumerate(discs):  # a dyad's assemblies meet where it stops assembling
        edge = ok & ((d[nxt] < 0) | (np.roll(d, 1) < 0))
        for c in choices:
            flip = list(c)
            flip[j] = 1 - flip[j]
            rows.append(node[edge, index[c]])
            cols.append(node[edge, index[tuple(flip)]])
    r, c = np.concatenate(rows), np.concatenate(cols)
    size = n * len(choices)
    graph = coo_matrix((np.ones(len(r)), (r, c)), shape=(size, size))
    count, label = connected_components(graph, directed=False)
    used = np.unique(label[node[ok].ravel()])
    return len(used)


def three_rotor_components(l1: float, l2: float, samples: int = 20000) -> int:
    """Components of the default three-rotor at ``(L1, L2)``: the middle rotor sampled densely,
    dyads A (from P1) and C (from P3)."""
    t = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    b = P2 + R2 * np.column_stack([np.cos(t), np.sin(t)])
    return components_by_sampling([_dyad(P1, R1, b, l1), _dyad(P3, R3, b, l2)])


def gate_lines(r: float = 1.5, l1: float = 2.0) -> list[tuple[float, float]]:
    """The gate's four-bar (ground D from the gate pin to the slider, crank r, coupler L2,
    rocker L1) is critical where it can be straight: ``D = s0 r + s1 L2 + s2 L1`` for signs
    ``s``; as lines ``D = slope L2 + offset`` with ``D > 0``. Where the largest of the four is
    the sum of the others (one of these lines) the space becomes empty."""
    out = set()
    for s0, s1, s2 in itertools.product((1, -1), repeat=3):
        out.add((float(s1), s0 * r + s2 * l1))
    return sorted(out)


def gate_rotor_turns(l2: float, d: float, r: float = 1.5, l1: float = 2.0,
                     samples: int = 20000) -> int | None:
    """1 when the gate rotor turns fully, 0 when it does not, None where the gate does not
    assemble: the rotor's tip sampled densely, the rocker's joint R (circle intersection of L2
    about the tip and L1 about the slider at distance D below the pin) must exist at every
    angle. (The chain's dyads never straighten: a tip at distance r = 1.5 from its pin is 0.5
    to 2.5 from the next pin, never 0 or r + l = 3.)"""
    t = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
    tips = r * np.column_stack([np.cos(t), np.sin(t)])
    disc = _dyad(np.array([0.0, -d]), l1, tips, l2)
    if not (disc >= 0).any():
        return None
    return int((disc >= 0).all())
