"""Every isolated solution of a square polynomial system, by homotopy continuation.

The target ``F(X) = 0`` is ``n`` homogeneous polynomials of degrees ``d_e`` in ``X = (x_0, x)``
(``n + 1`` unknowns, ``x_0`` the homogenising coordinate). The start system
``G_e(X) = x_e^{d_e} - x_0^{d_e}`` has exactly ``prod d_e`` solutions (roots of unity), all
nonsingular. The homotopy (the "gamma trick")::

    H(X, t) = (1 - t) F(X) + t gamma G(X),      t from 1 to 0,

with a random complex ``gamma`` has, with probability one, smooth paths for ``t`` in ``(0, 1]``
starting at the start solutions, and every isolated solution of ``F`` (finite or at infinity)
is the end of at least one path (Bezout's theorem; Sommese and Wampler, *The Numerical Solution
of Systems of Polynomials*, 2005, Thm. 8.4.1). The paths are tracked on a random affine patch
``a . X = 1`` of projective space, so paths to solutions at infinity stay bounded (their
``x_0`` goes to 0) instead of diverging.

Tracking (all paths at once, vectorised): a fourth-order Runge-Kutta predictor on
``dX/dt = -[H_X; a]^{-1} [H_t; 0]`` and up to three Newton corrections at the new ``t``; a step
is taken when Newton converges (update below ``newton_tol``) without leaving the trust region,
halved otherwise and doubled after three successes. A path whose Newton at ``t = 0`` converges
ends *regular* (a nonsingular solution, polished); a path that cannot step to ``t = 0`` goes on
geometrically (its step halves towards the end) and, once ``t <= t_end``, ends *singular*: a
solution of multiplicity ``w > 1`` is approached as ``t^{1/w}``, so the end point is within
about ``t_end^{1/w}`` of it (callers refine singular ends with a method of their own). A path
whose step falls below ``h_min`` at ``t > t_end`` *failed*: a failed path voids the claim that
every solution was found.

Regular ends that coincide are a sign that one path jumped onto another; :func:`track` reports
them (``jumped``) so that a caller does not claim completeness.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from engine.model.budget import NEVER, Deadline
from engine.model.errors import NumericalFailure
from engine.space.linear_product import NAME as LINEAR_PRODUCT
from engine.space.linear_product import LinearProduct

#: Path end states: a nonsingular solution, a singular one (or one approached too slowly), a
#: failure, stopped while running (deadline), and gone far (towards infinity, see ``track``).
REGULAR, SINGULAR, FAILED, RUNNING, FAR = 0, 1, 2, 3, 4

#: Newton's update (relative to ``|X|``) below which a corrector has converged.
NEWTON_TOL = 1e-9
#: A looser floor for Newton where its updates still contract (near singular ends).
NEWTON_LOOSE = 1e-7
#: A first Newton update larger than this (relative to ``|X|``) rejects the step (trust region).
TRUST = 0.1
#: ``t`` below which a path that cannot reach 0 ends as singular.
T_END = 1e-10
#: ``t`` below which a path whose affine point lies beyond the caller's ``far`` bound ends as
#: ``FAR`` (its end is at or towards infinity): the endgame zone, where a path follows the
#: Puiseux series of its end. Bertini's default truncates such paths from ``t = 0.1`` with a
#: norm bound of ``1e5`` (SecurityLevel 0, SecurityMaxNorm; Bates, Hauenstein, Sommese and
#: Wampler, *Numerically Solving Polynomial Systems with Bertini*, 2013, Sec. 2.3): this is
#: ten times deeper, and callers pass a bound far beyond where their solutions lie.
T_FAR = 1e-2
#: Smallest step in ``t`` for a path still above ``T_END``: below it the path failed.
H_MIN = 1e-13
#: Where a step to ``t = 0`` failed, the next tries ``t * ENDGAME_RATIO``.
ENDGAME_RATIO = 0.1
#: Largest step in ``t`` and the first one.
H_MAX = 0.05
#: Reciprocal condition of ``[F_X; a]`` below which an end counts as singular.
SINGULAR_RCOND = 1e-8
#: Largest factor a row of the Jacobian is scaled up by (relative to the median row) in the
#: conditioning test of regular ends.
ROW_SCALE_MAX = 1e3
#: Relative distance below which two regular ends are the same point (a path jumped).
SAME_END = 1e-7

#: Name of the default start system in reports.
TOTAL_DEGREE = "total degree"

#: ``system(X) -> (F, F_X)``: values (N, n) and Jacobians (N, n, n + 1) at N points (N, n + 1).
System = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Tracked:
    """The ends of every path.

    Attributes
    ----------
    ends : (P, n + 1) complex
        Each path's last point on the patch (homogeneous coordinates).
    state : (P,) int
        ``REGULAR``, ``SINGULAR``, ``FAR`` or ``FAILED`` (``RUNNING``: stopped by the
        deadline).
    t : (P,) float
        The ``t`` each path reached (0 for regular ends).
    steps : int
        Predictor-corrector steps taken (the largest over the paths).
    jumped : int
        Regular ends that coincide with another regular end.
    success : bool
        Every path ended regular, singular or far, none jumped, the deadline did not stop them.
    message : str
        Why not, when ``success`` is False.
    start : str
        The start system: ``"total degree"`` or ``"linear product"``.
    """

    ends: np.ndarray
    state: np.ndarray
    t: np.ndarray
    steps: int
    jumped: int
    success: bool
    message: str
    start: str = TOTAL_DEGREE

    @property
    def paths(self) -> int:
        return len(self.ends)


def start_solutions(degrees: np.ndarray) -> np.ndarray:
    """Every solution ``(1, x)`` of ``x_e^{d_e} = 1`` (prod d_e, n + 1), in a fixed order."""
    roots = [np.exp(2j * np.pi * np.arange(d) / d) for d in degrees]
    grid = np.meshgrid(*roots, indexing="ij")
    x = np.stack([g.ravel() for g in grid], axis=1)
    return np.hstack([np.ones((len(x), 1), dtype=complex), x])


def _start(x: np.ndarray, degrees: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``G`` (N, n) and ``G_X`` (N, n, n + 1) of the start system."""
    n = len(degrees)
    x0 = x[:, :1]
    xe = x[:, 1:]
    g = xe ** degrees - x0 ** degrees
    jac = np.zeros((len(x), n, n + 1), dtype=complex)
    idx = np.arange(n)
    jac[:, idx, idx + 1] = degrees * xe ** (degrees - 1)
    jac[:, :, 0] = -degrees * x0 ** (degrees - 1)
    return g, jac


class _Homotopy:
    def __init__(self, system: System, start: System, gamma: complex,
                 patch: np.ndarray) -> None:
        self.system, self.start, self.gamma, self.patch = system, start, gamma, patch

    def parts(self, x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``H`` with the patch row (N, n + 1), ``[H_X; a]`` (N, n + 1, n + 1), ``H_t`` (N, n)."""
        f, fx = self.system(x)
        g, gx = self.start(x)
        s = t[:, None]
        h = (1 - s) * f + s * self.gamma * g
        hx = (1 - s[:, :, None]) * fx + s[:, :, None] * self.gamma * gx
        full = np.concatenate([hx, np.broadcast_to(self.patch, (len(x), 1, len(self.patch)))],
                              axis=1)
        value = np.concatenate([h, (x @ self.patch - 1.0)[:, None]], axis=1)
        return value, full, self.gamma * g - f

    def velocity(self, x: np.ndarray, t: np.ndarray) -> np.ndarray:
        _, full, ht = self.parts(x, t)
        rhs = np.concatenate([ht, np.zeros((len(x), 1))], axis=1)
        return -_solve(full, rhs)

    def newton(self, x: np.ndarray, t: np.ndarray, iterations: int = 3
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Up to ``iterations`` Newton steps at fixed ``t``: (points, converged, first update).

        Converged: the last update is below ``NEWTON_TOL``, or below ``NEWTON_LOOSE`` while
        the updates contract at least fourfold (near a singular end the Jacobian's condition
        grows, and Newton reaches a looser floor there)."""
        first = np.zeros(len(x))
        done = np.zeros(len(x), dtype=bool)
        before = np.full(len(x), np.inf)
        for k in range(iterations):
            value, full, _ = self.parts(x, t)
            dx = -_solve(full, value)
            size = np.linalg.norm(dx, axis=1) / np.maximum(np.linalg.norm(x, axis=1), 1.0)
            if k == 0:
                first = size
            x = x + dx
            done = (size <= NEWTON_TOL) | ((size <= NEWTON_LOOSE) & (size <= 0.25 * before))
            before = size
            if done.all():
                break
        return x, done, first


def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^{-1} b`` for a stack; a singular matrix gives NaN rows (the step is then refused)."""
    try:
        return np.linalg.solve(a, b[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.nan, dtype=complex)
        for k in range(len(a)):
            try:
                out[k] = np.linalg.solve(a[k], b[k])
            except np.linalg.LinAlgError:
                pass
        return out


def track(system: System, degrees: np.ndarray | list[int], rng: np.random.Generator,
          deadline: Deadline = NEVER, max_steps: int = 4000,
          far: float = np.inf, start: LinearProduct | None = None) -> Tracked:
    """Track every path of the homotopy of ``system`` from ``t = 1`` to 0: from the
    total-degree start, or from ``start`` (a linear product of the system's multihomogeneous
    structure, :mod:`engine.space.linear_product`; its total degrees must be ``degrees``).

    Parameters
    ----------
    system : callable
        ``X (N, n + 1) -> (F (N, n), F_X (N, n, n + 1))``, homogeneous of ``degrees``.
    degrees : (n,) int
    rng : numpy Generator
        Draws ``gamma`` and the patch.
    deadline : Deadline
        Checked at every step; paths still running when it expires are ``RUNNING``.
    far : float
        Once ``t <= T_FAR``, a path whose affine point ``x / x_0`` is longer than this stops as
        ``FAR`` (solutions at infinity are often not isolated, and paths towards them end in
        ill-conditioned Newton steps; a caller that knows where its solutions lie says so).
    start : LinearProduct, optional
        Drawn by the caller (its random factors from the caller's generator).

    Examples
    --------
    The circle ``x^2 + y^2 = 1`` met with the line ``x = y``: two solutions.

    >>> def circle_line(X):
    ...     x0, x, y = X.T
    ...     f = np.stack([x**2 + y**2 - x0**2, x - y], axis=1)
    ...     jac = np.zeros((len(X), 2, 3), dtype=complex)
    ...     jac[:, 0] = np.stack([-2 * x0, 2 * x, 2 * y], axis=1)
    ...     jac[:, 1, 1], jac[:, 1, 2] = 1, -1
    ...     return f, jac
    >>> res = track(circle_line, [2, 1], np.random.default_rng(0))
    >>> xs = res.ends[:, 1] / res.ends[:, 0]
    >>> bool(res.success), sorted(np.round(xs.real, 6).tolist())
    (True, [-0.707107, 0.707107])
    """
    degrees = np.asarray(degrees, dtype=int)
    n = len(degrees)
    gamma = complex(np.exp(2j * np.pi * rng.random()))
    patch = rng.normal(size=n + 1) + 1j * rng.normal(size=n + 1)
    patch /= np.linalg.norm(patch)
    if start is not None and not np.array_equal(start.total, degrees):
        raise NumericalFailure("the linear product's total degrees differ from the system's")
    hom = _Homotopy(system, start if start is not None else (lambda x: _start(x, degrees)),
                    gamma, patch)
    x = start.solutions() if start is not None else start_solutions(degrees)
    x = x / (x @ patch)[:, None]
    p = len(x)
    t = np.ones(p)
    h = np.full(p, H_MAX)
    wins = np.zeros(p, dtype=int)
    state = np.full(p, RUNNING)
    endgame = np.zeros(p, dtype=bool)
    steps = 0
    while (state == RUNNING).any() and steps < max_steps:
        if deadline.expired():
            break
        steps += 1
        act = np.flatnonzero(state == RUNNING)
        xa, ta = x[act], t[act]
        ha = np.minimum(h[act], ta)
        t1 = ta - ha
        new, ok, first = hom.newton(_rk4(hom, xa, ta, ha), t1)
        ok &= (first <= TRUST) & np.isfinite(new).all(axis=1)
        good = act[ok]
        x[good], t[good] = new[ok], t1[ok]
        _adapt(act, ok, ta, ha, t, h, wins, endgame, state, H_MAX)
        if np.isfinite(far):
            zone = act[(t[act] <= T_FAR) & np.isin(state[act], (RUNNING, SINGULAR, FAILED))]
            gone = np.linalg.norm(x[zone, 1:], axis=1) > far * np.abs(x[zone, 0])
            state[zone[gone]] = FAR
    _finish_at_zero(hom, x, t, state)
    _demote_ill_conditioned(hom, x, state)
    jumped = _jumped(x[state == REGULAR])
    running = int((state == RUNNING).sum())
    failed = int((state == FAILED).sum())
    message = "; ".join(m for m in (
        f"{running} of {p} paths stopped by the deadline or the step limit" if running else "",
        f"{failed} of {p} paths failed (step below {H_MIN:g} at t > {T_END:g})" if failed else "",
        f"{jumped} regular ends coincide (a path jumped)" if jumped else "",
    ) if m)
    return Tracked(x, state, t, steps, jumped, not message, message or "every path ended",
                   LINEAR_PRODUCT if start is not None else TOTAL_DEGREE)


def _adapt(act: np.ndarray, ok: np.ndarray, ta: np.ndarray, ha: np.ndarray, t: np.ndarray,
           h: np.ndarray, wins: np.ndarray, endgame: np.ndarray, state: np.ndarray,
           h_max: float) -> None:
    """After one step ``ha`` from ``ta`` of the paths ``act`` (``ok``: corrected): their step
    sizes, endgame flags and states, in place (``t`` already moved where ``ok``). Three
    steps in a row double a step (up to ``h_max``); in the endgame ``t`` falls tenfold per
    step; a failed step halves it, and a failed step to ``t = 0`` (a singular end, or one at
    infinity) puts the path in its endgame."""
    good, bad = act[ok], act[~ok]
    wins[good] += 1
    grow = good[(wins[good] >= 3) & ~endgame[good]]
    h[grow] = np.minimum(2.0 * h[grow], h_max)
    wins[grow] = 0
    late = good[endgame[good]]
    h[late] = (1.0 - ENDGAME_RATIO) * t[late]
    state[good[t[good] == 0.0]] = REGULAR
    to_zero = ha[~ok] >= ta[~ok]
    endgame[bad[to_zero]] = True
    h[bad] = np.where(to_zero, (1.0 - ENDGAME_RATIO) * ta[~ok], 0.5 * ha[~ok])
    wins[bad] = 0
    state[act[(t[act] <= T_END) & (state[act] == RUNNING)]] = SINGULAR
    state[bad[(h[bad] < H_MIN) & (t[bad] > T_END)]] = FAILED


def _rk4(hom: _Homotopy, xa: np.ndarray, ta: np.ndarray, ha: np.ndarray) -> np.ndarray:
    """The RK4 predictor in ``t``: each path's point a step ``-ha`` further."""
    k1 = hom.velocity(xa, ta)
    k2 = hom.velocity(xa - 0.5 * ha[:, None] * k1, ta - 0.5 * ha)
    k3 = hom.velocity(xa - 0.5 * ha[:, None] * k2, ta - 0.5 * ha)
    k4 = hom.velocity(xa - ha[:, None] * k3, ta - ha)
    return xa - (ha / 6.0)[:, None] * (k1 + 2 * k2 + 2 * k3 + k4)


def _finish_at_zero(hom: _Homotopy, x: np.ndarray, t: np.ndarray, state: np.ndarray) -> None:
    """Paths stopped at ``t <= T_END`` try Newton at ``t = 0``: where it converges they end
    regular (the conditioning test that follows demotes the ill-conditioned ones)."""
    ends = np.flatnonzero(state == SINGULAR)
    if not len(ends):
        return
    new, ok, _ = hom.newton(x[ends], np.zeros(len(ends)), iterations=5)
    ok &= np.isfinite(new).all(axis=1)
    x[ends[ok]], t[ends[ok]] = new[ok], 0.0
    state[ends[ok]] = REGULAR


def _demote_ill_conditioned(hom: _Homotopy, x: np.ndarray, state: np.ndarray) -> None:
    """Regular ends whose Jacobian ``[F_X; a]`` is nearly singular are singular ends (Newton may
    creep onto a multiple solution within its tolerance)."""
    reg = np.flatnonzero(state == REGULAR)
    if not len(reg):
        return
    _, full, _ = hom.parts(x[reg], np.zeros(len(reg)))
    # rows scaled to unit length (an equation's scale, a determinant's say, is not its
    # conditioning), but none by more than ROW_SCALE_MAX over the median row: a row that
    # vanishes at the end (a multiple root) stays small
    norms = np.linalg.norm(full, axis=2, keepdims=True)
    floor = np.median(norms, axis=1, keepdims=True) / ROW_SCALE_MAX
    full = full / np.maximum(norms, np.maximum(floor, 1e-300))
    s = np.linalg.svd(full, compute_uv=False)
    state[reg[s[:, -1] < SINGULAR_RCOND * s[:, 0]]] = SINGULAR


def _jumped(ends: np.ndarray) -> int:
    """How many regular ends repeat another (a nonsingular solution is the end of exactly one
    path: a repeat means a path jumped)."""
    if len(ends) < 2:
        return 0
    pts = np.hstack([ends.real, ends.imag])
    scale = max(float(np.abs(pts).max()), 1.0)
    pairs = cKDTree(pts).query_pairs(SAME_END * scale, output_type="ndarray")
    return len(np.unique(pairs.ravel()))
