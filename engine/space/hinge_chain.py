"""Hinged rotor chains in 3D, derived from their cells: every critical point and a point on
every component, in closed form.

A *hinged rotor chain* is a 3D linkage of ``n >= 2`` tips ``T_k`` (free vertices), each held by
two bars to two pins (fully fixed vertices, distinct) so that it moves on a circle (a hinge:
centre ``c_k``, radius ``rho_k``, orthonormal ``e1_k, e2_k`` spanning its plane), consecutive
tips joined by couplers of length ``l_k``, and nothing else (bars between pins are inert). The
``rotor-chain-3d`` preset is one. In the rotor angles ``theta_0 .. theta_(n-1)`` (with
``T_k = c_k + rho_k (cos theta_k e1_k + sin theta_k e2_k)``, a diffeomorphism of the hinge
constraints, so critical points are the same in angles as in coordinates) the chain is ``n - 1``
*cell* equations ``f_k(theta_k, theta_(k+1)) = |T_k - T_(k+1)|^2 - l_k^2 = x(theta_k)^T M_k
x(theta_(k+1)) = 0`` with ``x(t) = (1, cos t, sin t)``: given one angle of a cell the other
solves ``C + A cos t + B sin t = 0``, at most two values in closed form.

The Jacobian in angles is bidiagonal: row ``k`` holds ``a_k = df_k/dtheta_k`` and ``b_k =
df_k/dtheta_(k+1)``. A self-stress ``sigma J = 0`` is supported on a run of cells ``i .. j`` with
``a_i = 0`` and ``b_j = 0`` (the columns at its ends), and a run with the smallest ``j - i``
carries one; so a configuration is **critical exactly when some cell ``i`` has ``a_i = 0`` and
some cell ``j >= i`` has ``b_j = 0``**. The points of a cell with ``a_k = 0`` are its folds in
``theta_k`` (a double root given ``theta_(k+1)``): ``A^2 + B^2 = C^2``, a trigonometric
polynomial of degree 2 in ``theta_(k+1)`` (at most 4 roots, from a companion matrix); those with
``b_k = 0`` likewise in ``theta_k``. Every critical point is then found by walking from each
``a``-fold of each cell ``i`` outwards through cells ``i+1, ...`` (two branches a step) and
testing ``b_j`` at each, and completing each run found through the other cells.

**A point on every component.** Every component is a compact curve. Either ``theta_0`` takes
every value on it, and the fibre ``theta_0 = const`` (all ``2^(n-1)`` sign choices, in closed
form) meets it, or ``theta_0`` has an extremum on it: a critical point, or a regular point whose
tangent has ``t_0 = 0``; the bidiagonal system then forces ``t_0 = .. = t_k = 0 != t_(k+1)`` and
``b_k = 0`` for some cell ``k``: a ``b``-fold of cell ``k``, completed through the other cells.
A fold polynomial that vanishes identically, or a fold where the other tip lies on this
hinge's axis (a whole circle of the cell folds: kites and rhombi built from hinges), makes the
derivation decline as ``degenerate``; the answers then take the general path (the homotopy).

Every enumeration is bounded up front (``points_max`` angles in all, about ``(n + 3) 2^n`` for
a chain whose cells all have two branches) and by the deadline; beyond them the derivation says
which part it did not finish.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.model.budget import NEVER, Deadline
from engine.model.linkage import Linkage

#: A fold polynomial whose coefficients are all below this (relative to ``|M|^2``) vanishes
#: identically: a continuum of folds (the derivation declines as degenerate).
FOLD_ZERO_RTOL = 1e-10
#: A root ``z`` of a fold polynomial lies on the unit circle when ``| |z| - 1 |`` is below this
#: (a double root, at a cell's singular point, is off it by about the square root of rounding).
UNIT_ROOT_TOL = 1e-5
#: Roots this close to the unit circle are taken as folds too, where a wrong claim could follow
#: from missing one (seeds, run starts, the rule's "no fold"): lengths within about its square
#: (relative) of a critical length; a candidate from one that refines to no critical point
#: leaves the answer unresolved rather than guessed.
NEAR_ROOT_TOL = 1e-3
#: At a fold, the amplitude ``hypot(A, B)`` (relative to ``|M|``) below which the other tip is
#: on this hinge's axis: every angle of this rotor closes the cell there (a circle of folds).
AXIS_RTOL = 1e-6
#: ``|b_j|`` (relative to ``|M_j|``) below which a walked run is a critical candidate, refined
#: on the augmented system.
CANDIDATE_RTOL = 1e-4
#: ``|b_j|`` (relative) below which a candidate must refine to a critical point: the walked
#: angles are within about this of exact (closed forms, square-root accuracy at double roots).
CERTAIN_RTOL = 1e-7
#: Angles walked in all by default (fibre, folds, runs): beyond it the derivation stops.
POINTS_MAX = 1 << 20


@dataclass(frozen=True)
class HingeChain:
    """The hinge circles and cells of a hinged rotor chain, tips in chain order.

    ``tips`` (n,) vertex indices; ``centres`` (n, 3); ``radii`` (n,); ``frames`` (n, 2, 3) the
    pairs ``e1, e2``; ``cells`` (n - 1, 3, 3) the matrices ``M_k``."""

    tips: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    frames: np.ndarray
    cells: np.ndarray

    @property
    def n(self) -> int:
        """Number of rotors."""
        return len(self.tips)

    def points(self, theta: np.ndarray) -> np.ndarray:
        """Tips (K, n, 3) at angles ``theta`` (K, n)."""
        c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
        return self.centres + self.radii[:, None] * (c * self.frames[:, 0] + s * self.frames[:, 1])

    def residuals(self, theta: np.ndarray) -> np.ndarray:
        """Cell values ``f_k`` (K, n - 1) at angles (K, n)."""
        x = _x(theta)  # (K, n, 3)
        return np.einsum("kmi,mij,kmj->km", x[:, :-1], self.cells, x[:, 1:])


def _x(t: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(t), np.cos(t), np.sin(t)], axis=-1)


def _dx(t: np.ndarray) -> np.ndarray:
    return np.stack([np.zeros_like(t), -np.sin(t), np.cos(t)], axis=-1)


def _hinge(a: np.ndarray, b: np.ndarray, ra: float, rb: float
           ) -> tuple[np.ndarray, float, np.ndarray] | None:
    """Centre, radius and frame (2, 3) of the circle at distances ``ra``, ``rb`` from pins
    ``a``, ``b``; None where there is no circle."""
    d = float(np.linalg.norm(b - a))
    if d == 0.0:
        return None
    axis = (b - a) / d
    along = (ra**2 - rb**2 + d**2) / (2 * d)
    rho2 = ra**2 - along**2
    if not rho2 > 1e-12 * max(ra, rb) ** 2:
        return None
    e1 = np.cross(axis, np.eye(3)[int(np.argmin(np.abs(axis)))])
    e1 /= np.linalg.norm(e1)
    return a + along * axis, float(np.sqrt(rho2)), np.stack([e1, np.cross(axis, e1)])


def cell_matrix(ck: np.ndarray, rk: float, fk: np.ndarray, cn: np.ndarray, rn: float,
                fn: np.ndarray, length: float) -> np.ndarray:
    """``M`` (3, 3) with ``x(s)^T M x(t) = |p(s) - q(t)|^2 - length^2`` for the circles
    ``p(s) = ck + rk (cos s fk[0] + sin s fk[1])`` and ``q(t)`` likewise."""
    w = ck - cn
    m = np.zeros((3, 3))
    m[0, 0] = w @ w + rk**2 + rn**2 - length**2
    m[1:, 0] = 2 * rk * (fk @ w)
    m[0, 1:] = -2 * rn * (fn @ w)
    m[1:, 1:] = -2 * rk * rn * (fk @ fn.T)
    return m


def _order(linkage: Linkage) -> tuple[list[int], dict[int, list[int]], list[int]] | None:
    """Tips in chain order, each tip's hinge bars, and the couplers in order; None when the
    linkage is not a hinged chain."""
    fixed = np.asarray(linkage.fixed, dtype=bool)
    full: np.ndarray = np.asarray(fixed.all(axis=1), dtype=bool)
    if np.any(fixed.any(axis=1) & ~full):
        return None  # a slider
    tips = [int(v) for v in np.flatnonzero(~full)]
    hinge: dict[int, list[int]] = {t: [] for t in tips}
    links: dict[int, list[tuple[int, int]]] = {t: [] for t in tips}
    for k, (i, j) in enumerate(np.asarray(linkage.ends)):
        i, j = int(i), int(j)
        if full[i] and full[j]:
            continue
        if full[i] != full[j]:
            hinge[j if full[i] else i].append(k)
        else:
            links[i].append((j, k))
            links[j].append((i, k))
    if len(tips) < 2 or any(len(h) != 2 for h in hinge.values()):
        return None
    ends = [t for t, nb in links.items() if len(nb) == 1]
    if len(ends) != 2 or any(len(nb) > 2 for nb in links.values()):
        return None
    order, couplers = [min(ends)], []
    while len(order) < len(tips):
        nxt = [(v, k) for v, k in links[order[-1]] if v not in order[-2:-1]]
        if len(nxt) != 1 or nxt[0][0] in order:
            return None
        order.append(nxt[0][0])
        couplers.append(nxt[0][1])
    return order, hinge, couplers


def hinge_chain(linkage: Linkage) -> HingeChain | None:
    """The hinged rotor chain of ``linkage`` (see the module docstring), or None.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> hinge_chain(build_preset("rotor-chain-3d", {"n": 4})).n
    4
    >>> hinge_chain(build_preset("four-bar")) is None
    True
    """
    if linkage.dimension != 3:
        return None
    found = _order(linkage)
    if found is None:
        return None
    order, hinge, couplers = found
    pos = np.asarray(linkage.positions, dtype=float)
    ends, lengths = np.asarray(linkage.ends), np.asarray(linkage.lengths, dtype=float)
    circles = []
    for t in order:
        pins = [int(ends[k, 0]) if int(ends[k, 1]) == t else int(ends[k, 1]) for k in hinge[t]]
        circle = _hinge(pos[pins[0]], pos[pins[1]], *(float(lengths[k]) for k in hinge[t]))
        if circle is None:
            return None
        circles.append(circle)
    cells = np.array([cell_matrix(*circles[k][:3], *circles[k + 1][:3], float(lengths[b]))
                      for k, b in enumerate(couplers)])
    return HingeChain(np.array(order), np.array([c[0] for c in circles]),
                      np.array([c[1] for c in circles]), np.array([c[2] for c in circles]),
                      cells)


def fold_angles(q: np.ndarray, tol: float = UNIT_ROOT_TOL) -> np.ndarray | None:
    """Real roots of ``x(t)^T q x(t)`` (q (3, 3) symmetric) in ``[-pi, pi)``, or None when it
    vanishes identically. Degree 2 in ``cos t, sin t``: a quartic in ``z = e^(it)``, whose
    roots within ``tol`` of the unit circle are taken (polished by Newton)."""
    a0 = q[0, 0] + 0.5 * (q[1, 1] + q[2, 2])
    a1, b1 = 2 * q[0, 1], 2 * q[0, 2]
    a2, b2 = 0.5 * (q[1, 1] - q[2, 2]), q[1, 2]
    coef = np.array([(a2 - 1j * b2) / 2, (a1 - 1j * b1) / 2, a0, (a1 + 1j * b1) / 2,
                     (a2 + 1j * b2) / 2])
    size = float(np.abs(q).max())
    if np.abs(coef).max() <= FOLD_ZERO_RTOL * max(size, 1e-300):
        return None
    lead = np.flatnonzero(np.abs(coef) > FOLD_ZERO_RTOL * size)[0]
    z = np.roots(coef[lead:]) if lead < 4 else np.zeros(0)
    t = np.angle(z[np.abs(np.abs(z) - 1.0) <= tol])

    def value(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, s, c2, s2 = np.cos(t), np.sin(t), np.cos(2 * t), np.sin(2 * t)
        return (a0 + a1 * c + b1 * s + a2 * c2 + b2 * s2,
                -a1 * s + b1 * c - 2 * a2 * s2 + 2 * b2 * c2)

    for _ in range(4):  # Newton polish (a double root keeps its square-root accuracy)
        v, d = value(t)
        step = np.where(np.abs(d) > 1e-3 * size, v / np.where(d == 0, 1.0, d), 0.0)
        t = t - np.clip(step, -1e-3, 1e-3)
    t = np.sort(np.mod(t + np.pi, 2 * np.pi) - np.pi)
    if len(t) > 1:  # a double root's pair: one point
        keep = np.concatenate([[True], np.diff(t) > 1e-7])
        if keep[-1] and t[-1] - t[0] > 2 * np.pi - 1e-7:
            keep[-1] = False
        t = t[keep]
    return t


_S = np.diag([-1.0, 1.0, 1.0])


def folds(m: np.ndarray, side: str, tol: float = NEAR_ROOT_TOL) -> np.ndarray | None:
    """Points (F, 2) ``(theta_k, theta_(k+1))`` of the cell ``m`` with ``a = 0`` (side "a":
    a double root in ``theta_k``) or ``b = 0`` (side "b"), and near misses within ``tol`` (see
    :data:`NEAR_ROOT_TOL`); None: a continuum of folds (the polynomial vanishes, or at a root
    the other tip lies on this hinge's axis, so a whole circle of the cell folds: kites and
    rhombi built from hinges)."""
    mat = m if side == "a" else m.T  # rows: the angle that has the double root
    roots = fold_angles(mat.T @ _S @ mat, tol)
    if roots is None:
        return None
    coef = mat @ _x(roots).T  # (3, F): C, A, B of the double root's equation
    if np.any(np.hypot(coef[1], coef[2]) <= AXIS_RTOL * np.linalg.norm(m)):
        return None  # a tip on the other hinge's axis: a whole circle of the cell are folds
    base = np.arctan2(coef[2], coef[1]) + np.where(coef[0] > 0, np.pi, 0.0)
    pair = np.column_stack([base, roots])
    return pair if side == "a" else pair[:, ::-1]


def solve_next(m: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Given ``theta_k`` (K,), both ``theta_(k+1)`` (K, 2) of ``x(theta_k)^T m x(.) = 0`` and
    which exist (K, 2) (a tangency counts once, as both)."""
    c, a, b = (_x(t) @ m).T
    amp = np.hypot(a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = -c / amp
    ok = np.abs(ratio) <= 1.0 + 1e-12
    spread = np.arccos(np.clip(np.where(ok, ratio, 0.0), -1.0, 1.0))
    base = np.arctan2(b, a)
    out = np.stack([base + spread, base - spread], axis=1)
    both = np.stack([ok, ok & (spread > 0.0)], axis=1)
    return out, both


class TooMany(Exception):  # noqa: N818 (a control-flow signal, never raised out of the module)
    """The enumeration would pass its size bound or the deadline."""


@dataclass
class _Walker:
    """Bounded enumeration along the chain (one counter of angles walked, the deadline)."""

    chain: HingeChain
    points_max: int
    deadline: Deadline
    walked: int = 0

    def spend(self, k: int) -> None:
        self.walked += k
        if self.walked > self.points_max:
            raise TooMany(f"more than {self.points_max} angles to walk")
        if self.deadline.expired():
            raise TooMany("the deadline passed")

    def outwards(self, theta: np.ndarray, k: int, step: int) -> np.ndarray:
        """Rows (K', ...) extending angle rows ``theta`` (K, w) ending (step 1) or starting
        (step -1) at ``theta_k`` through every cell to that end of the chain."""
        rows = theta
        stop = self.chain.n - 1 if step == 1 else 0
        while k != stop:
            m = self.chain.cells[k] if step == 1 else self.chain.cells[k - 1].T
            nxt, ok = solve_next(m, rows[:, -1] if step == 1 else rows[:, 0])
            self.spend(int(ok.sum()))
            src = np.repeat(np.arange(len(rows)), 2)[ok.ravel()]
            new = nxt.ravel()[ok.ravel()][:, None]
            rows = np.hstack([rows[src], new] if step == 1 else [new, rows[src]])
            k += step
        return rows

    def complete(self, run: np.ndarray, first: int) -> np.ndarray:
        """Full angle rows (K', n) through ``run`` (K, w): angles ``first .. first + w - 1``."""
        rows = self.outwards(run, first + run.shape[1] - 1, 1)
        return self.outwards(rows, first, -1)


@dataclass
class Derivation:
    """What :func:`derive` found: angle rows (K, n), and what stops the argument.

    ``seeds``: on every compact component (the fibre and the ``b``-folds completed);
    ``candidates``: runs ``a_i = 0 .. b_j = 0`` completed, every critical point among them,
    with ``margins`` (K,) the relative ``|b_j|`` of each; ``degenerate``: a continuum of folds
    (cell index) or None; ``stopped``: which part the bound or the deadline cut, or None."""

    chain: HingeChain
    seeds: np.ndarray
    candidates: np.ndarray
    margins: np.ndarray
    fibre_angle: float
    counts: dict[str, int] = field(default_factory=dict)
    degenerate: str | None = None
    stopped: str | None = None

    @property
    def critical_done(self) -> bool:
        """Every critical point is among the candidates (the runs were all walked)."""
        return self.degenerate is None and self.counts.get("runs_done", 0) == 1

    @property
    def seeds_done(self) -> bool:
        """A seed lies on every component (fibre and folds all walked)."""
        return self.degenerate is None and self.stopped is None


def estimate(n: int) -> int:
    """Angles walked at most by :func:`derive` on a chain of ``n`` rotors: runs from 4 folds a
    cell (``4 2^(n-1)``), the fibre (``2^(n-1)``) and the ``b``-folds completed (``4 (n-1)
    2^(n-2)``), before completing the runs found."""
    return int(4 * 2 ** (n - 1) + 2 ** (n - 1) + 4 * (n - 1) * 2 ** (n - 2)) if n < 60 else 1 << 62


def _runs(w: _Walker) -> tuple[np.ndarray, np.ndarray, str | None]:
    """Every run ``a_i = 0 .. |b_j| <= CANDIDATE_RTOL |M_j|``, completed (K, n), with margins."""
    chain = w.chain
    found, margins = [], []
    for i in range(chain.n - 1):
        start = folds(chain.cells[i], "a")
        if start is None:
            return np.zeros((0, chain.n)), np.zeros(0), f"cell {i}: a circle of folds"
        rows = start
        for j in range(i, chain.n - 1):
            if j > i:
                nxt, ok = solve_next(chain.cells[j], rows[:, -1])
                w.spend(int(ok.sum()))
                src = np.repeat(np.arange(len(rows)), 2)[ok.ravel()]
                rows = np.hstack([rows[src], nxt.ravel()[ok.ravel()][:, None]])
            m = chain.cells[j]
            b = np.einsum("ki,ij,kj->k", _x(rows[:, -2]), m, _dx(rows[:, -1]))
            rel = np.abs(b) / np.linalg.norm(m)
            hit = rel <= CANDIDATE_RTOL
            if hit.any():
                full = w.complete(rows[hit], i)
                found.append(full)
                margins.append(_margins_of(rows[hit], i, full, rel[hit]))
    if not found:
        return np.zeros((0, chain.n)), np.zeros(0), None
    rows, rel = np.vstack(found), np.concatenate(margins)
    # one row per configuration (a fold that is a double root is met twice)
    _, first = np.unique(np.round(np.mod(rows, 2 * np.pi), 6), axis=0, return_index=True)
    return rows[np.sort(first)], rel[np.sort(first)], None


def _margins_of(run: np.ndarray, first: int, full: np.ndarray, rel: np.ndarray) -> np.ndarray:
    """Each completed row's margin: that of the run it extends (matched by its angles)."""
    cols = slice(first, first + run.shape[1])
    d = np.abs(np.angle(np.exp(1j * (full[:, None, cols] - run[None]))))  # (K', K, w)
    return rel[np.argmin(d.max(axis=2), axis=1)]


def _fibre(w: _Walker) -> tuple[np.ndarray, float]:
    """The fibre over ``theta_0``, at the trial angle whose walk stays farthest from folds."""
    best: tuple[float, np.ndarray, float] | None = None
    for t0 in np.linspace(-np.pi, np.pi, 7, endpoint=False) + 0.1234:
        rows = np.array([[t0]])
        margin = 1.0
        for k in range(w.chain.n - 1):
            nxt, ok = solve_next(w.chain.cells[k], rows[:, -1])
            c, a, b = (_x(rows[:, -1]) @ w.chain.cells[k]).T
            with np.errstate(invalid="ignore", divide="ignore"):
                gap = 1.0 - np.abs(c) / np.hypot(a, b)
            margin = min(margin, float(np.nanmin(np.abs(gap), initial=1.0)))
            w.spend(int(ok.sum()))
            src = np.repeat(np.arange(len(rows)), 2)[ok.ravel()]
            rows = np.hstack([rows[src], nxt.ravel()[ok.ravel()][:, None]])
        if best is None or margin > best[0]:
            best = (margin, rows, float(t0))
        if margin > 1e-3:
            break
    assert best is not None
    return best[1], best[2]


def derive(chain: HingeChain, deadline: Deadline = NEVER, points_max: int = POINTS_MAX,
           seeds: bool = True) -> Derivation:
    """Critical candidates and (``seeds``) seeds of a hinged rotor chain (see the module
    docstring).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> d = derive(hinge_chain(build_preset("rotor-chain-3d", {"n": 3})))
    >>> d.seeds_done, len(d.candidates)
    (True, 0)
    """
    w = _Walker(chain, points_max, deadline)
    n = chain.n
    empty = np.zeros((0, n))
    counts = {"estimate": estimate(n), "runs_done": 0}
    try:
        crit, margins, degenerate = _runs(w)
    except TooMany as exc:
        counts["walked"] = w.walked
        return Derivation(chain, empty, empty, np.zeros(0), 0.0, counts,
                          stopped=f"critical points: {exc}")
    if degenerate is not None:
        counts["walked"] = w.walked
        return Derivation(chain, empty, crit, margins, 0.0, counts, degenerate=degenerate)
    counts["runs_done"] = 1
    counts["critical_candidates"] = len(crit)
    if not seeds:
        counts["walked"] = w.walked
        return Derivation(chain, empty, crit, margins, 0.0, counts, stopped="seeds: not asked")
    try:
        fibre, t0 = _fibre(w)
        turning = [empty]
        for k in range(n - 1):
            pts = folds(chain.cells[k], "b")
            if pts is None:
                counts["walked"] = w.walked
                return Derivation(chain, empty, crit, margins, t0, counts,
                                  degenerate=f"cell {k}: a circle of folds")
            turning.append(w.complete(pts, k))
    except TooMany as exc:
        counts["walked"] = w.walked
        return Derivation(chain, empty, crit, margins, 0.0, counts,
                          stopped=f"seeds: {exc}")
    counts.update(walked=w.walked, fibre=len(fibre), turning=sum(len(t) for t in turning))
    return Derivation(chain, np.vstack([fibre, *turning]), crit, margins, t0, counts)
