"""Independent references for the slice tests: closed-form critical sets of the three-rotor and
of the gated chain's gate, and their configuration spaces by dense sampling of the driving rotor
with closed-form circle intersections (nothing from the engine)."""

from __future__ import annotations

import itertools

import numpy as np
from scipy import ndimage
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


# -- any three-rotor: its critical set from circle intersections, scanned along lines ---------


class ThreeRotor:
    """A three-rotor as the preset builds it: pins ``P1 = (0, 0)``, ``P2 = (a, 0)``, ``P3 = P2 +
    a (cos phi, sin phi)``; rotors ``r1, r2, r3`` to tips ``A, B, C``; couplers ``L1`` (A-B) and
    ``L2`` (B-C); ``lengths`` by name (the preset's defaults: all 1)."""

    NAMES = ("r1", "r2", "r3", "L1", "L2")

    def __init__(self, a: float = 1.0, phi: float = np.pi / 2, **lengths: float) -> None:
        self.a, self.phi = a, phi
        self.lengths = {k: float(lengths.get(k, 1.0)) for k in self.NAMES}
        self.p1, self.p2 = np.array([0.0, 0.0]), np.array([a, 0.0])
        self.p3 = self.p2 + a * np.array([np.cos(phi), np.sin(phi)])

    def components(self, changed: dict[str, float], samples: int = 20000) -> int:
        """Components at the lengths with ``changed`` ones: the middle rotor sampled densely,
        dyads A (from P1) and C (from P3)."""
        ln = {**self.lengths, **changed}
        t = np.linspace(0.0, 2 * np.pi, samples, endpoint=False)
        b = self.p2 + ln["r2"] * np.column_stack([np.cos(t), np.sin(t)])
        return components_by_sampling([_dyad(self.p1, ln["r1"], b, ln["L1"]),
                                       _dyad(self.p3, ln["r3"], b, ln["L2"])])

    def terms(self, ln: dict[str, np.ndarray], tol: float = 1e-9) -> dict[tuple, np.ndarray]:
        """Signed functions of the lengths (arrays of one shape) that vanish exactly where they
        are critical, NaN where the configuration they describe does not exist:

        - a cell flat: ``P1 A B P2`` on a line (``B = P2 +- r2 e``, ``|B - P1| = r1 + L1`` or
          ``|r1 - L1|``) with dyad C assembling at ``B``; or ``P2 B C P3`` alike with dyad A
          assembling;
        - both dyads straight: ``B`` at distance ``r1 + L1`` or ``|r1 - L1|`` from ``P1`` on the
          middle rotor's circle (circle intersections), ``|B - P3| = r3 + L2`` or
          ``|r3 - L2|``."""
        r1, r2, r3, l1, l2 = (np.asarray(ln[k], dtype=float) for k in self.NAMES)
        out: dict[tuple, np.ndarray] = {}

        def reach(b: np.ndarray, pin: np.ndarray, r: np.ndarray, cpl: np.ndarray) -> np.ndarray:
            d = np.linalg.norm(b - pin, axis=-1)
            return (d >= np.abs(r - cpl) - tol) & (d <= r + cpl + tol)

        e12 = (self.p2 - self.p1) / np.linalg.norm(self.p2 - self.p1)
        e23 = (self.p3 - self.p2) / np.linalg.norm(self.p3 - self.p2)
        for s in (1.0, -1.0):
            b = self.p2 + s * r2[..., None] * e12
            d = np.linalg.norm(b - self.p1, axis=-1)
            ok = reach(b, self.p3, r3, l2)
            out["flat1", s, "+"] = np.where(ok, d - (r1 + l1), np.nan)
            out["flat1", s, "-"] = np.where(ok, d - np.abs(r1 - l1), np.nan)
            b = self.p2 + s * r2[..., None] * e23
            d = np.linalg.norm(b - self.p3, axis=-1)
            ok = reach(b, self.p1, r1, l1)
            out["flat2", s, "+"] = np.where(ok, d - (r3 + l2), np.nan)
            out["flat2", s, "-"] = np.where(ok, d - np.abs(r3 - l2), np.nan)
        for name, rho in (("+", r1 + l1), ("-", np.abs(r1 - l1))):
            for side in (1.0, -1.0):
                b = _circle_point(self.p1, rho, self.p2, r2, side)
                d = np.linalg.norm(b - self.p3, axis=-1)
                out["both", name, side, "+"] = d - (r3 + l2)
                out["both", name, side, "-"] = d - np.abs(r3 - l2)
        return out

    def residual(self, changed: dict[str, float]) -> float:
        """The smallest ``|term|`` at the lengths with ``changed`` ones (0 on the critical set,
        in length)."""
        axes = tuple(changed)
        return float(self.residuals(axes, np.array([list(changed.values())]))[0])

    def residuals(self, axes: tuple[str, ...], points: np.ndarray) -> np.ndarray:
        """The smallest ``|term|`` (n,) at each row of ``points`` (n, len(axes)), the lengths of
        ``axes``."""
        ln = {k: np.full(len(points), v) for k, v in self.lengths.items()}
        for j, name in enumerate(axes):
            ln[name] = points[:, j].astype(float)
        values = np.abs(np.array(list(self.terms(ln).values())))  # (terms, n)
        return np.asarray(np.nanmin(np.where(np.isfinite(values), values, np.inf), axis=0))

    def scanned(self, axes: tuple[str, str], box: np.ndarray, lines: int = 41,
                samples: int = 2001) -> np.ndarray:
        """Points (n, 2) of the critical set in the box: on ``lines`` scanlines of each axis,
        every sign change of a term between ``samples`` points along the line, bisected (all
        brackets at once)."""
        found = []
        for held in range(2):
            v = np.linspace(*box[held], lines)[:, None]  # (lines, 1)
            w = np.linspace(*box[1 - held], samples)[None, :]  # (1, samples)
            g = np.array(list(self._along(axes, held, v + 0 * w, w + 0 * v).values()))
            t, i, k = np.nonzero(np.isfinite(g[:, :, :-1]) & np.isfinite(g[:, :, 1:])
                                 & (np.sign(g[:, :, :-1]) * np.sign(g[:, :, 1:]) < 0))
            if not len(t):
                continue
            vi, lo, hi, sign = v[i, 0], w[0, k], w[0, k + 1], np.sign(g[t, i, k])
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                gm = np.array(list(self._along(axes, held, vi, mid).values()))[t, np.arange(len(t))]
                same = np.sign(gm) == sign
                lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
            p = np.empty((len(vi), 2))
            p[:, held], p[:, 1 - held] = vi, 0.5 * (lo + hi)
            found.append(p)
        return np.concatenate(found) if found else np.zeros((0, 2))

    def _along(self, axes: tuple[str, str], held: int, v: np.ndarray, w: np.ndarray
               ) -> dict[tuple, np.ndarray]:
        """The terms with the held axis at ``v`` and the other at ``w`` (one shape)."""
        ln = {k: np.full(np.shape(w), val) for k, val in self.lengths.items()}
        ln[axes[held]] = np.asarray(v, dtype=float)
        ln[axes[1 - held]] = np.asarray(w, dtype=float)
        return self.terms(ln)


def _circle_point(c0: np.ndarray, r0: np.ndarray, c1: np.ndarray, r1: np.ndarray,
                  side: float) -> np.ndarray:
    """The point (..., 2) at distance ``r0`` from ``c0`` and ``r1`` from ``c1`` on ``side`` of
    the line from ``c0`` to ``c1`` (NaN where the circles do not meet)."""
    d = float(np.linalg.norm(c1 - c0))
    along = (d * d + r0 * r0 - r1 * r1) / (2 * d)
    h2 = r0 * r0 - along * along
    e = (c1 - c0) / d
    n = np.array([-e[1], e[0]])
    h = np.sqrt(np.where(h2 >= 0, h2, np.nan))
    return c0 + along[..., None] * e + side * h[..., None] * n


def distance_to_curves(points: np.ndarray, curves: list[np.ndarray]) -> np.ndarray:
    """Each point's (n, 2) distance to the nearest segment of the polylines (each (m, 2))."""
    best = np.full(len(points), np.inf)
    for c in curves:
        a, b = c[:-1], c[1:]
        ab = b - a
        denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
        s = np.clip(np.einsum("kij,ij->ki", points[:, None, :] - a[None], ab) / denom, 0, 1)
        foot = a[None] + s[:, :, None] * ab[None]
        best = np.minimum(best, np.min(np.linalg.norm(points[:, None, :] - foot, axis=2), axis=1))
    return best


def points_inside(curves: list[np.ndarray], box: np.ndarray, n: int, point: np.ndarray,
                  count: int = 4) -> list[np.ndarray]:
    """Up to ``count`` points of the region of the map holding ``point`` at least two raster
    cells (of ``n`` a side) from every curve: the cells the curves cross (each segment sampled
    at a tenth of a cell) split the raster into 4-connected pieces; the piece of ``point``'s
    cell (none when it is blocked: a region thinner than a cell)."""
    span = box[:, 1] - box[:, 0]
    blocked = np.zeros((n, n), dtype=bool)
    for c in curves:
        for a, b in zip(c[:-1], c[1:], strict=True):
            steps = int(np.ceil(10 * np.max(np.abs(b - a) / span) * n)) + 1
            q = a + np.linspace(0, 1, steps + 1)[:, None] * (b - a)
            ij = np.clip(((q - box[:, 0]) / span * n).astype(int), 0, n - 1)
            blocked[ij[:, 0], ij[:, 1]] = True
    labels, _ = ndimage.label(~blocked)
    cell = tuple(np.clip(((point - box[:, 0]) / span * n).astype(int), 0, n - 1))
    if labels[cell] == 0:
        return []
    dist = ndimage.distance_transform_edt(~blocked)
    inner = np.argwhere((labels == labels[cell]) & (dist >= 2))
    picked = inner[np.linspace(0, len(inner) - 1, min(count, len(inner))).astype(int)]
    return [box[:, 0] + span * (np.array(ij) + 0.5) / n for ij in picked]
