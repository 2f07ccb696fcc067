"""Seeds on every component of a five-bar chain's surface, derived from its two crank angles.

A *five-bar chain* (planar or spherical) is a ``D = 2`` linkage with three moving vertices: two
cranks ``A`` and ``C``, each held on a circle by bars to pins (one in 2D, two in 3D: the circle
about the axis through them), and a middle vertex ``B`` joined to ``A`` and ``C`` by bars of
lengths ``l2``, ``l3`` and, in 3D, to one pin ``P`` lying on both cranks' axes (the spherical
five-bar: ``P = O``, the centre of the sphere; then ``|A - P| = r_A`` and ``|C - P| = r_C`` are
constant). The Lagrange homotopy of a height (:mod:`.morse`) needs ``2^E C(M, E)`` paths: 240 for
the planar five-bar, but 4,608 for the spherical one, past the default bound of 512.

**The argument** (``search.argument = "derived"``). Write ``A(theta)``, ``C(phi)`` for the
cranks and ``s = |A - C|^2``, a function on the torus ``T`` of crank angles. For given ``A``,
``C``, the point ``B`` lies where the circles (2D) or the spheres about ``P``, ``A``, ``C`` (3D)
meet: ``B = base(A, C) + t n`` with ``n`` normal to the line ``AC`` (to the plane ``PAC``) and
``t^2`` a function of ``s`` alone (in 3D, ``t^2 det G = g(q)``, ``q = (A - P) . (C - P) =
(r_A^2 + r_C^2 - s) / 2``, with ``g(q) = r_B^2 (r_A^2 r_C^2 - q^2) - h^T adj(G) h`` concave in
``q``; in 2D the triangle inequality). So ``B`` is real exactly on the band ``R = {s_lo <= s <=
s_hi}`` of ``T``, two points over its inside, one over its boundary: the surface ``S`` is a
double cover of ``R`` folded along ``dR``, and the projection ``pi: S -> R`` is open and closed
onto ``R`` where the boundary is regular. Hence every component ``K`` of ``S`` covers a whole
component ``R_K`` of ``R``, and a point of ``R_K`` with both its lifts seeds ``K``. A point on
every component of ``R``: ``s`` takes its maximum and minimum on ``R_K``; if either lies inside,
it is a critical point of ``s`` on ``T`` (system 1 below); otherwise ``R_K`` reaches the level
curves ``s = s_lo`` or ``s = s_hi``. On a component ``L`` of such a level curve, the angle
``theta`` either covers the whole circle (then ``L`` meets the fibre ``theta = theta*``: a sine
equation in ``phi``, solved in closed form) or takes an extremum, where ``ds/dphi = 0`` (system
2). Both systems are four equations in ``(cos theta, sin theta, cos phi, sin phi)``::

    1: x^2 + y^2 = 1,  z^2 + w^2 = 1,  ds/dtheta = 0,  ds/dphi = 0
    2: x^2 + y^2 = 1,  z^2 + w^2 = 1,  s = s_b,       ds/dphi = 0

with ``s = k + alpha . (x, y) + beta . (z, w) + (x, y) K (z, w)^T`` bilinear in the two circles:
bihomogeneous of degrees ``(2, 0), (0, 2), (1, 1), (1, 1)``, whose linear-product start
(:mod:`engine.space.linear_product`) has ``2 * 2 * C(2, 1) = 8`` paths, tracked by
:func:`engine.space.homotopy.track`: every isolated solution is the end of a path. Three systems
(1 and 2 at both levels): 24 paths, against 4,608. The answer is derived when every path ended
and no real end is singular (a singular real end is a degenerate critical point of ``s`` or a
tangency of a level curve: lengths at a transition). A chain whose band reaches ``A = C``
(2D: ``l2 = l3``; 3D: the triangle ``PAC`` in a line, ``q = +-r_A r_C``) is left to the other
methods: there ``B`` runs on a whole circle over one point and the double cover breaks down.

**The linkage's critical points** follow: off the boundary (``t != 0``) the bars at ``B`` have
independent directions and ``J`` is block triangular with full-rank blocks (the cranks' circles
are regular, checked); on it ``S`` is locally ``t^2 = G(theta, phi)``, ``G`` a function of ``s``
with ``G' != 0`` at the simple roots ``s_lo < s_hi``, so ``J`` loses rank exactly where ``ds =
0`` on the boundary: the real solutions of system 1 with ``s = s_lo`` or ``s_hi``
(:attr:`ChainSeeds.critical`), each a cone or an isolated point.

References: the planar five-bar's workspace as the band of the distance ``|A - C|`` is classical
(Gosselin and Angeles, *Singularity analysis of closed-loop kinematic chains*, IEEE Trans.
Robot. Autom. 6, 1990); the torus of crank angles as the base of the double cover is the
fibration of Kapovich and Millson's polygon spaces (*On the moduli space of spherical polygonal
linkages*, Canad. Math. Bull. 42, 1999).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.budget import NEVER, Deadline
from engine.model.constraints import Constraints
from engine.model.linkage import Linkage
from engine.space.homotopy import REGULAR, SINGULAR, track
from engine.space.linear_product import LinearProduct, Structure, bezout
from engine.space.surfaces.geometry import Surface
from engine.space.witnesses import REAL_TOL, SINGULAR_IMAG_TOL

#: A pin within this distance (relative to the longest bar) of a crank's axis is on it.
AXIS_RTOL = 1e-9
#: ``t^2`` above ``-LIFT_RTOL`` times the squared bar scale is clipped to 0 when lifting a point
#: of the band's boundary (where ``t = 0``).
LIFT_RTOL = 1e-9
#: A critical value of ``s`` within this (relative to ``s_hi - s_lo``) of a boundary value is a
#: critical point of the linkage.
CRITICAL_RTOL = 1e-7
#: A singular end of system 2 within this of a critical point of ``s`` on the band's edge
#: (in ``(x, y, z, w)``; a singular end is within about ``sqrt(T_END) = 1e-5`` of its point)
#: is that point.
SAME_END_TOL = 1e-3
#: Ends of the crank-angle systems beyond this (the real ones have ``|(x, y, z, w)| = sqrt 2``)
#: stop as far away.
FAR_BOUND = 1e3
#: The fibre ``theta = THETA_STAR`` (any angle serves the argument).
THETA_STAR = 0.0
#: The crank-angle systems' bihomogeneous structure (module docstring).
STRUCTURE = Structure((np.array([1, 2]), np.array([3, 4])),
                      np.array([[2, 0], [0, 2], [1, 1], [1, 1]]))


@dataclass(frozen=True)
class Crank:
    """A moving ``vertex`` on the circle ``centre + radius (cos a, sin a) @ frame``;
    ``frame`` (2, d) orthonormal."""

    vertex: int
    centre: np.ndarray
    frame: np.ndarray
    radius: float

    def at(self, cs: np.ndarray) -> np.ndarray:
        """Points (N, d) at the unit vectors ``cs`` (N, 2) = (cos a, sin a)."""
        return self.centre + self.radius * np.asarray(cs, dtype=float) @ self.frame


@dataclass(frozen=True)
class FiveBarChain:
    """A recognised five-bar chain (module docstring): the cranks, the middle vertex with its
    bars' lengths ``l2`` (to ``A``), ``l3`` (to ``C``) and (3D) its pin and bar ``r_pin``; the
    band ``s_range`` of ``s = |A - C|^2`` where ``B`` is real (None: nowhere); ``s`` on the
    torus as ``k + alpha . p + beta . q + p K q`` (``p``, ``q`` the cranks' unit vectors)."""

    crank_a: Crank
    crank_c: Crank
    middle: int
    l2: float
    l3: float
    pin: np.ndarray | None
    r_pin: float
    s_range: tuple[float, float] | None
    k: float
    alpha: np.ndarray
    beta: np.ndarray
    kmat: np.ndarray

    def s(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """``s`` at unit vectors ``p``, ``q`` (N, 2)."""
        return (self.k + p @ self.alpha + q @ self.beta
                + np.einsum("ni,ij,nj->n", p, self.kmat, q))


@dataclass(frozen=True)
class ChainSeeds:
    """Outcome of :func:`chain_seeds`: ``seeds`` (K, M) on the surface, ``critical`` (C, M)
    the linkage's critical points (module docstring), the homotopy's path count, whether the
    argument holds (``success``), why not (``message``) and the argument in a sentence."""

    seeds: np.ndarray
    critical: np.ndarray
    paths: int
    success: bool
    message: str
    detail: str


def five_bar_chain(linkage: Linkage, cons: Constraints) -> FiveBarChain | None:
    """The five-bar chain ``linkage`` is (module docstring), or None when it is none: three
    moving vertices, two on circles of pinned bars joined through the third, in 3D the third's
    pin on both cranks' axes, no slider."""
    d, fixed = linkage.dimension, np.asarray(linkage.fixed, dtype=bool)
    pinned = np.asarray(fixed.all(axis=1), dtype=bool)
    if (fixed.any(axis=1) & ~pinned).any() or int((~pinned).sum()) != 3:
        return None
    ends, lengths = linkage.ends[cons.bars], linkage.lengths[cons.bars]
    pins: dict[int, list[tuple[int, float]]] = {int(v): [] for v in np.flatnonzero(~pinned)}
    nbrs: dict[int, list[tuple[int, float]]] = {v: [] for v in pins}
    for (i, j), length in zip(ends.tolist(), lengths.tolist(), strict=True):
        for v, w in ((i, j), (j, i)):
            if v in pins:
                (pins[v] if pinned[w] else nbrs[v]).append((w, length))
    middle = [v for v in pins if len(nbrs[v]) == 2 and len(pins[v]) == d - 2]
    tips = [v for v in pins if len(nbrs[v]) == 1 and len(pins[v]) == d - 1]
    if len(middle) != 1 or len(tips) != 2 or {w for v in tips for w, _ in nbrs[v]} != set(middle):
        return None
    pos = np.asarray(linkage.positions, dtype=float)
    scale = float(lengths.max())
    cranks = [_crank(v, pos, pins[v], scale) for v in tips]
    if cranks[0] is None or cranks[1] is None:
        return None
    crank_a, crank_c = cranks[0], cranks[1]
    b = middle[0]
    l2, l3 = (dict(nbrs[b])[v] for v in tips)
    pin, r_pin = (pos[pins[b][0][0]], pins[b][0][1]) if d == 3 else (None, 0.0)
    if pin is not None and not all(_on_axis(pin, pos, pins[v], scale) for v in tips):
        return None
    generic, band = _band(crank_a, crank_c, l2, l3, pin, r_pin)
    if not generic:
        return None
    gap = crank_a.centre - crank_c.centre
    ra, rc, fa, fc = crank_a.radius, crank_c.radius, crank_a.frame, crank_c.frame
    return FiveBarChain(crank_a, crank_c, b, l2, l3, pin, r_pin, band,
                        float(gap @ gap + ra**2 + rc**2), 2 * ra * (fa @ gap),
                        -2 * rc * (fc @ gap), -2 * ra * rc * (fa @ fc.T))


def _crank(v: int, pos: np.ndarray, bars: list[tuple[int, float]], scale: float
           ) -> Crank | None:
    """The circle the bars ``bars`` (pin, length) hold ``v`` on; None where it is degenerate
    (two pins at one place, a circle of radius near zero or none)."""
    d = pos.shape[1]
    if d == 2:
        (p, r), = bars
        return Crank(v, pos[p].copy(), np.eye(2), r)
    (p1, r1), (p2, r2) = bars
    axis = pos[p2] - pos[p1]
    dist = float(np.linalg.norm(axis))
    if dist <= AXIS_RTOL * scale:
        return None
    axis /= dist
    along = (r1**2 - r2**2 + dist**2) / (2 * dist)
    rho2 = r1**2 - along**2
    if rho2 <= (AXIS_RTOL * scale) ** 2:
        return None
    frame = np.linalg.svd(axis[None])[2][1:]  # (2, 3): orthonormal, normal to the axis
    return Crank(v, pos[p1] + along * axis, frame, float(np.sqrt(rho2)))


def _on_axis(pin: np.ndarray, pos: np.ndarray, bars: list[tuple[int, float]],
             scale: float) -> bool:
    """Whether ``pin`` lies on the line through the two pins of ``bars``."""
    a, b = pos[bars[0][0]], pos[bars[1][0]]
    axis = (b - a) / np.linalg.norm(b - a)
    off = (pin - a) - ((pin - a) @ axis) * axis
    return float(np.linalg.norm(off)) <= AXIS_RTOL * scale * 1e3


def _band(ca: Crank, cc: Crank, l2: float, l3: float, pin: np.ndarray | None,
          r_pin: float) -> tuple[bool, tuple[float, float] | None]:
    """Whether the band is generic (its ends touch no triangle ``PAC`` in a line: in 2D,
    ``l2 != l3``, else over ``A = C`` a whole circle of ``B``) and ``(s_lo, s_hi)``, where ``B``
    is real (None: nowhere)."""
    if pin is None:
        return abs(l2 - l3) > AXIS_RTOL * max(l2, l3), ((l2 - l3) ** 2, (l2 + l3) ** 2)
    ra2 = float(np.sum((ca.centre - pin) ** 2)) + ca.radius**2
    rc2 = float(np.sum((cc.centre - pin) ** 2)) + cc.radius**2
    h1, h2 = (r_pin**2 + ra2 - l2**2) / 2, (r_pin**2 + rc2 - l3**2) / 2
    # g(q) = -r^2 q^2 + 2 h1 h2 q + r^2 ra2 rc2 - h1^2 rc2 - h2^2 ra2 >= 0
    a, b, c = -r_pin**2, 2 * h1 * h2, r_pin**2 * ra2 * rc2 - h1**2 * rc2 - h2**2 * ra2
    disc = b * b - 4 * a * c
    if disc <= 0:
        return True, None
    q_lo, q_hi = sorted(((-b + np.sqrt(disc)) / (2 * a), (-b - np.sqrt(disc)) / (2 * a)))
    edge = np.sqrt(ra2 * rc2) * (1 - 1e-9)
    if q_hi >= edge or q_lo <= -edge:
        return False, None
    return True, (ra2 + rc2 - 2 * q_hi, ra2 + rc2 - 2 * q_lo)


def _quadrics(ch: FiveBarChain, level: float | None) -> np.ndarray:
    """The four equations of system 1 (``level`` None) or 2 (``s = level``) as symmetric
    forms (4, 5, 5) in ``X = (x0, x, y, z, w)``."""
    quad = np.zeros((4, 5, 5))
    quad[0, 0, 0], quad[0, 1, 1], quad[0, 2, 2] = -1.0, 1.0, 1.0
    quad[1, 0, 0], quad[1, 3, 3], quad[1, 4, 4] = -1.0, 1.0, 1.0
    a, b, km = ch.alpha, ch.beta, ch.kmat
    terms3 = ([(1, 3, km[0, 0]), (1, 4, km[0, 1]), (2, 3, km[1, 0]), (2, 4, km[1, 1]),
               (0, 1, a[0]), (0, 2, a[1]), (0, 3, b[0]), (0, 4, b[1]), (0, 0, ch.k - level)]
              if level is not None else
              # ds/dtheta = x (a1 x0 + K[1] . q) - y (a0 x0 + K[0] . q)
              [(1, 0, a[1]), (1, 3, km[1, 0]), (1, 4, km[1, 1]),
               (2, 0, -a[0]), (2, 3, -km[0, 0]), (2, 4, -km[0, 1])])
    # ds/dphi = z (b1 x0 + K[:, 1] . p) - w (b0 x0 + K[:, 0] . p)
    terms4 = [(3, 0, b[1]), (3, 1, km[0, 1]), (3, 2, km[1, 1]),
              (4, 0, -b[0]), (4, 1, -km[0, 0]), (4, 2, -km[1, 0])]
    for e, terms in ((2, terms3), (3, terms4)):
        for i, j, c in terms:
            quad[e, i, j] += c / 2
            quad[e, j, i] += c / 2
    return quad


def _solve(ch: FiveBarChain, level: float | None, rng: np.random.Generator,
           deadline: Deadline) -> tuple[np.ndarray, np.ndarray, str]:
    """The real regular solutions (N, 2, 2) of system 1 or 2 as unit vectors ``(p, q)``, the
    singular ends near real points (K, 2, 2) (within about ``sqrt(T_END)`` of a multiple
    solution), and what voids the argument ('' when every path ended)."""
    quad = _quadrics(ch, level)

    def system(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = np.einsum("eij,nj->nei", quad, x)  # (N, 4, 5)
        return np.einsum("nei,ni->ne", g, x), 2 * g

    total = np.full(4, 2)
    res = track(system, total, rng, deadline, far=FAR_BOUND,
                start=LinearProduct(STRUCTURE, total, rng))
    x0 = res.ends[:, 0]
    y = res.ends[:, 1:] / np.where(np.abs(x0) > 0, x0, np.inf)[:, None]
    size = np.linalg.norm(y, axis=1)
    near = np.isfinite(size) & (size <= FAR_BOUND)
    imag = np.linalg.norm(y.imag, axis=1) / np.maximum(size, 1.0)
    keep = near & (imag <= REAL_TOL) & (res.state == REGULAR)
    odd = near & (imag <= SINGULAR_IMAG_TOL) & (res.state == SINGULAR)
    pq, sing = (y[k].real.reshape(-1, 2, 2) for k in (keep, odd))
    pq /= np.linalg.norm(pq, axis=2, keepdims=True)
    return pq, sing, "" if res.success else res.message


def _fibre(ch: FiveBarChain, level: float) -> np.ndarray:
    """The points (N, 2, 2) of the level curve ``s = level`` on the fibre
    ``theta = THETA_STAR`` (a sine equation in ``phi``)."""
    p = np.array([np.cos(THETA_STAR), np.sin(THETA_STAR)])
    coef = ch.beta + ch.kmat.T @ p
    rho = float(np.linalg.norm(coef))
    rhs = level - ch.k - float(ch.alpha @ p)
    if rho == 0.0 or abs(rhs) > rho:
        return np.zeros((0, 2, 2))
    base, half = np.arctan2(coef[1], coef[0]), np.arccos(np.clip(rhs / rho, -1.0, 1.0))
    phis = np.array([base - half, base + half])
    return np.stack([np.broadcast_to(p, (2, 2)),
                     np.stack([np.cos(phis), np.sin(phis)], axis=1)], axis=1)


def lift(ch: FiveBarChain, linkage: Linkage, pq: np.ndarray) -> np.ndarray:
    """Both configurations ``u`` (2N, M) over the crank points ``pq`` (N, 2, 2) (``B`` on either
    side; one point twice on the band's boundary); points outside the band are left out."""
    a, c = ch.crank_a.at(pq[:, 0]), ch.crank_c.at(pq[:, 1])
    if ch.pin is None:  # two circles: B = A + along e + t e^perp
        e = c - a
        dist = np.linalg.norm(e, axis=1)
        along = (ch.l2**2 - ch.l3**2 + dist**2) / (2 * dist)
        base, normal = a + along[:, None] * e / dist[:, None], e[:, ::-1] * [-1.0, 1.0]
        t2 = (ch.l2**2 - along**2) / dist**2
    else:  # three spheres: B - P = x a' + y c' + t (a' x c')
        ap, cp = a - ch.pin, c - ch.pin
        aa, cc, ac = np.sum(ap * ap, 1), np.sum(cp * cp, 1), np.sum(ap * cp, 1)
        h1, h2 = (ch.r_pin**2 + aa - ch.l2**2) / 2, (ch.r_pin**2 + cc - ch.l3**2) / 2
        normal = np.cross(ap, cp)
        det = np.sum(normal**2, 1)  # the Gram determinant: > 0 in a generic band
        with np.errstate(divide="ignore", invalid="ignore"):  # (P, A, C in a line: no lift)
            inplane = ((cc * h1 - ac * h2) / det)[:, None] * ap \
                + ((aa * h2 - ac * h1) / det)[:, None] * cp
            t2 = (ch.r_pin**2 - np.sum(inplane**2, 1)) / det
        base = ch.pin + inplane
    scale2 = max(ch.l2, ch.l3) ** 2
    ok = t2 * np.sum(normal**2, 1) >= -LIFT_RTOL * scale2
    t = np.sqrt(np.maximum(t2[ok], 0.0))[:, None]
    out = []
    for side in (1.0, -1.0):
        pos = np.broadcast_to(np.asarray(linkage.positions, dtype=float),
                              (int(ok.sum()),) + linkage.positions.shape).copy()
        pos[:, ch.crank_a.vertex], pos[:, ch.crank_c.vertex] = a[ok], c[ok]
        pos[:, ch.middle] = base[ok] + side * t * normal[ok]
        out.append(pos[:, ~np.asarray(linkage.fixed, dtype=bool)])
    return np.concatenate(out).reshape(-1, linkage.n_free)


def chain_seeds(surface: Surface, ch: FiveBarChain, rng: np.random.Generator,
                deadline: Deadline = NEVER) -> ChainSeeds:
    """Seeds on every compact component of the chain's surface and its critical points, by the
    argument of the module docstring.

    Examples
    --------
    A planar five-bar (pins 1 apart, cranks 1, couplers 1.3 and 1.2): 24 paths.

    >>> from engine.catalogue.presets import build_preset
    >>> lk = build_preset("five-bar")
    >>> s = Surface(lk)
    >>> got = chain_seeds(s, five_bar_chain(lk, s.cons), np.random.default_rng(0))
    >>> got.success, got.paths, len(got.critical), len(got.seeds) > 0
    (True, 24, 0, True)
    """
    m = surface.n
    if ch.s_range is None:
        return ChainSeeds(np.zeros((0, m)), np.zeros((0, m)), 0, True, "no configuration",
                          "the middle vertex is real nowhere: the space is empty")
    s_lo, s_hi = ch.s_range
    crit, sing, why = _solve(ch, None, rng, deadline)
    values = ch.s(crit[:, 0], crit[:, 1])
    tol = CRITICAL_RTOL * (s_hi - s_lo)
    inside = crit[(values >= s_lo - tol) & (values <= s_hi + tol)]
    on_edge = crit[(np.abs(values - s_lo) <= tol) | (np.abs(values - s_hi) <= tol)]
    parts, whys = [inside], [why, "a degenerate critical point of |A - C|^2" if len(sing) else ""]
    for level in (s_lo, s_hi):
        folds, sing, why = _solve(ch, level, rng, deadline)
        # a critical point of s on the edge solves system 2 twice over (a singular end): it is
        # system 1's; any other singular end is a tangency of theta to the edge
        dist = np.linalg.norm((sing[:, None] - on_edge[None]).reshape(len(sing), len(on_edge), 4),
                              axis=2)
        if len(sing) and not (len(on_edge) and (dist.min(axis=1) <= SAME_END_TOL).all()):
            why += "; a degenerate extremum of theta on the band's edge"
        parts += [folds, _fibre(ch, level)]
        whys.append(why.strip("; "))
    seeds = lift(ch, surface.linkage, np.concatenate(parts))
    projected = [surface.project(u) for u in seeds]
    if not all(ok for _, ok in projected):
        whys.append("a lifted seed did not project onto the lengths")
    message = "; ".join(w for w in whys if w)
    paths = 3 * bezout(STRUCTURE)
    detail = (f"a five-bar chain: the surface is a double cover of the band {s_lo:.6g} <= "
              f"|A - C|^2 <= {s_hi:.6g} of the torus of crank angles, folded along its edge; "
              f"every component of the band holds a critical point of |A - C|^2 "
              f"({len(inside)} inside), a point of its edge on the fibre theta = "
              f"{THETA_STAR:g} or an extremum of theta on its edge, all found by {paths} "
              "paths of three bihomogeneous systems (every path ended), and both lifts of "
              f"each seed every component; the linkage is critical only at the "
              f"{len(on_edge)} critical points of |A - C|^2 on the edge")
    return ChainSeeds(np.array([u for u, ok in projected if ok]).reshape(-1, m),
                      lift(ch, surface.linkage, on_edge)[:len(on_edge)], paths,
                      not message, message or "every path ended", detail)
