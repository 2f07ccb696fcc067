"""Closed-form configuration spaces of planar dyad chains, vectorised over the driving angle.

A planar one-degree-of-freedom linkage whose free vertices are placed one by one from a rotor's
tip, each from two placed neighbours (a *dyad*: circle-circle intersection, see
:func:`engine.assembly.dyad_plan`), has every configuration on a *sheet*: a choice of root
``s_j = +-1`` for each of its ``k`` dyads, over the rotor angle ``theta``. Dyad ``j`` at
``theta`` on sheet ``s`` has its vertex where ``nu_j = sin^2`` of the angle between its two bars
is positive (``nu_j`` depends on ``s_1 .. s_{j-1}`` only); where ``nu_j`` crosses zero the rotor
reaches a limit (a *fold*) and the sheets ``s`` and ``s`` with ``s_j`` flipped join. Sheets cut
at folds are *arcs*; joined end to end at their folds they are the components.

**Certificate of no critical point.** At a configuration where no dyad is collinear
(``nu_j != 0``) ``J`` has full rank (block triangular with invertible 2 x 2 blocks and the rotor
row). Where exactly one dyad is collinear, the dyad's self-stress is balanced by the rest only if
its generalised force on ``theta`` vanishes, i.e. ``d nu_j / d theta = 0``. So a linkage whose
every zero of every ``nu_j`` along every sheet is simple and away from the zeros of the other
dyads, and whose dyad centres never coincide, has no critical point at all. This module proves
that on a dense angle grid (sign changes bracketed and bisected; every discrete extremum of every
``nu_j`` refined on its bracket; every fold checked for transversality and for the other dyads'
margin, also densely inside its grid cell) and returns ``None`` whenever any check is within the
margin ``tau``: near or at critical lengths the general tracer answers instead
(:func:`engine.configuration_space.explore`). Never a confident wrong answer.

The margin ``tau`` (on ``nu = sin^2``) is ``1e4 * residual_atol / median bar length`` (clipped
to ``[1e-10, 1e-3]``): lengths that close to a critical value are left to the general engine,
which decides within ``residual_atol`` whether they are critical.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from engine.assembly import dyad_plan, rotors
from engine.linkage import Linkage
from engine.tolerances import Tolerances

#: More dyads than this (2^k sheets) are left to the general tracer.
MAX_DYADS = 6
#: Angle samples of the detection grid (per sheet).
DETECT_SAMPLES = 4096
#: Samples of the dense check inside a fold's grid cell.
FOLD_CELL_SAMPLES = 33
#: Points of the first pass along an arc (before resampling to the step bound).
ARC_PILOT = 512


@dataclass(frozen=True)
class Chain:
    """A rotor and the dyads that place every other free vertex (arrays over the ``k`` dyads)."""

    rotor: int
    pin: int
    tip: int
    radius: float
    vertex: np.ndarray
    a: np.ndarray
    b: np.ndarray
    ra: np.ndarray
    rb: np.ndarray
    base: np.ndarray  # (V, 2) positions of the pins (free vertices overwritten)

    @property
    def k(self) -> int:
        return len(self.vertex)


def chain_of(linkage: Linkage) -> Chain | None:
    """The first rotor whose dyad plan places every free vertex with exactly the active bars
    (circle-circle steps only, no sliders, at most :data:`MAX_DYADS` dyads), or None."""
    if linkage.dimension != 2:
        return None
    fixed = np.asarray(linkage.fixed)
    full: np.ndarray = np.asarray(fixed.all(axis=1), dtype=bool)
    if not np.all(full | ~fixed.any(axis=1)):
        return None  # sliders: left to the general engine
    active = Counter(tuple(sorted((int(i), int(j)))) for i, j in linkage.ends[linkage.active])
    for rotor in rotors(linkage):
        plan = dyad_plan(linkage, rotor)
        if plan is None or len(plan) > MAX_DYADS or any(s.axis >= 0 or s.b < 0 for s in plan):
            continue
        pin, tip = (int(x) for x in linkage.ends[rotor])
        if not full[pin]:
            pin, tip = tip, pin
        used = Counter([tuple(sorted((pin, tip)))])
        for s in plan:
            used[tuple(sorted((s.vertex, s.a)))] += 1
            used[tuple(sorted((s.vertex, s.b)))] += 1
        if used != active:
            continue  # an extra or missing bar: not a plain dyad chain
        return Chain(
            rotor=rotor, pin=pin, tip=tip, radius=float(linkage.lengths[rotor]),
            vertex=np.array([s.vertex for s in plan], dtype=int),
            a=np.array([s.a for s in plan], dtype=int),
            b=np.array([s.b for s in plan], dtype=int),
            ra=np.array([s.ra for s in plan]), rb=np.array([s.rb for s in plan]),
            base=np.array(linkage.positions, dtype=float),
        )
    return None


def place(
    ch: Chain, theta: np.ndarray, signs: np.ndarray, flat: np.ndarray | None = None,
    given: dict[int, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, V, 2), ``nu`` (n, k) and squared centre distances (n, k) at angles
    ``theta`` (n,) on sheets ``signs`` (n, k) of +-1.

    ``flat`` (n, k) bool forces a dyad's vertex onto its centres' line (its fold point, so that
    the two sheets that meet there give bitwise the same configuration). ``given = {j: v}``
    puts dyad ``j``'s vertex at ``v`` (n, 2) instead (a point of the circle it is free on where
    its centres coincide). Where ``nu < 0`` the
    vertex is put on the line too; the caller masks those samples (the loop runs over the ``k``
    dyads, at most :data:`MAX_DYADS`, each vectorised over all samples).
    """
    n = len(theta)
    pos = np.empty((n, *ch.base.shape))
    pos[:] = ch.base
    pos[:, ch.tip, 0] = ch.base[ch.pin, 0] + ch.radius * np.cos(theta)
    pos[:, ch.tip, 1] = ch.base[ch.pin, 1] + ch.radius * np.sin(theta)
    nu = np.empty((n, ch.k))
    d2 = np.empty((n, ch.k))
    for j in range(ch.k):
        ra, rb = ch.ra[j], ch.rb[j]
        c0 = pos[:, ch.a[j]]
        delta = pos[:, ch.b[j]] - c0
        dd = delta[:, 0] ** 2 + delta[:, 1] ** 2
        # 4 d^2 h^2 = ((ra + rb)^2 - d^2)(d^2 - (ra - rb)^2) = 4 ra^2 rb^2 sin^2(angle at v):
        # a product of differences (no cancellation in the quartic) and no division.
        quad = ((ra + rb) ** 2 - dd) * (dd - (ra - rb) ** 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 0.5 / dd
            along = (dd + ra * ra - rb * rb) * inv
            hh = np.sqrt(np.maximum(quad, 0.0)) * inv * signs[:, j]
        if flat is not None:
            hh = np.where(flat[:, j], 0.0, hh)
        if given is not None and j in given:
            pos[:, ch.vertex[j]] = given[j]
        else:
            pos[:, ch.vertex[j], 0] = c0[:, 0] + along * delta[:, 0] - hh * delta[:, 1]
            pos[:, ch.vertex[j], 1] = c0[:, 1] + along * delta[:, 1] + hh * delta[:, 0]
        nu[:, j] = quad / (4.0 * ra * ra * rb * rb)
        d2[:, j] = dd
    return pos, nu, d2


FoldKey = tuple[int, int, int]  # (sheet, inside grid index, -1 at a run's start / +1 at its end)
Arc = tuple[int, float, float, FoldKey | None, FoldKey | None]  # sheet, theta range, end folds


@dataclass(frozen=True)
class ClosedForm:
    """Components (each a closed walk of positions (n, V, 2), the first point repeated at the
    end) and what was checked; or why the closed form declined (``components`` is None)."""

    components: list[np.ndarray] | None
    report: dict[str, object]


def _sheets(k: int) -> np.ndarray:
    """All ``2^k`` sign vectors (S, k), ``+1`` first (the first root of
    :func:`engine.assembly.assemblies_at`)."""
    s = np.arange(2**k)[:, None] >> np.arange(k)[None, :]
    return 1 - 2 * (s & 1)


def _golden(
    f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, iters: int = 60
) -> np.ndarray:
    """Vectorised golden-section minimisation of ``f`` (arrays in, arrays out) on each
    ``[lo, hi]``; returns the smallest value seen per bracket (ends included)."""
    return _golden_arg(f, lo, hi, iters)[0]


def _golden_arg(
    f: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, iters: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_golden` with the argument of the smallest value seen: ``(value, argument)``."""
    g = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = lo.copy(), hi.copy()
    c, d = b - g * (b - a), a + g * (b - a)
    fa, fb, fc, fd = f(a), f(b), f(c), f(d)
    best = np.minimum(fa, fb)
    arg = np.where(fa <= fb, a, b)

    def keep(x: np.ndarray, fx: np.ndarray) -> None:
        nonlocal best, arg
        better = fx < best
        best, arg = np.where(better, fx, best), np.where(better, x, arg)

    keep(c, fc)
    keep(d, fd)
    for _ in range(iters):
        left = fc < fd
        b = np.where(left, d, b)
        a = np.where(left, a, c)
        c_new = b - g * (b - a)
        d_new = a + g * (b - a)
        c, d = np.where(left, c_new, d), np.where(left, c, d_new)
        x_new = np.where(left, c, d)
        fc_new = f(x_new)
        fc, fd = np.where(left, fc_new, fd), np.where(left, fc, fc_new)
        keep(x_new, fc_new)
    return best, arg


def closed_form_space(
    linkage: Linkage, tol: Tolerances, step_max: float, max_points: int,
    samples: int = DETECT_SAMPLES,
) -> ClosedForm:
    """Every component of a planar dyad chain in closed form, with the certificate that the
    configuration space holds no critical point; see the module docstring.

    Parameters
    ----------
    linkage : Linkage
        One degree of freedom, something fixed (as for :func:`engine.configuration_space.explore`).
    tol : Tolerances
        Every returned point has every bar within ``residual_atol`` of its length.
    step_max : float
        Consecutive points are never farther apart than this (free coordinates).
    max_points : int
        Budget of points per component; a component that needs more declines the closed form.
    samples : int
        Angle samples of the detection grid.

    Returns
    -------
    ClosedForm
        ``components`` None (with ``report["closed_form"]`` saying why) when the linkage is not a
        plain dyad chain or any check is within its margin.
    """
    ch = chain_of(linkage)
    if ch is None:
        return ClosedForm(None, {"closed_form": "declined: not a planar dyad chain"})
    # Overflow (coordinates up to 1e100 are accepted) shows up as non-finite values, which
    # decline below; no warning is worth raising for it.
    with np.errstate(all="ignore"):
        return _closed_form(linkage, ch, tol, step_max, max_points, samples)


class _Extrema(NamedTuple):
    mask: np.ndarray
    prev_nu: np.ndarray
    next_nu: np.ndarray
    prev_ok: np.ndarray
    next_ok: np.ndarray


def _discrete_extrema(nu: np.ndarray, prefix: np.ndarray, axis: int) -> _Extrema:
    """Samples (along the periodic ``axis`` of the angle grid) where ``nu`` is a discrete
    minimum of a positive run or a maximum of a negative run, with the neighbours' values and
    whether they are defined (``prefix``); at the end of a prefix run only one neighbour exists,
    so one-sided extrema count too."""
    prev_nu, next_nu = np.roll(nu, 1, axis=axis), np.roll(nu, -1, axis=axis)
    prev_ok, next_ok = np.roll(prefix, 1, axis=axis), np.roll(prefix, -1, axis=axis)
    pos_min = (nu > 0) & (nu <= prev_nu) & (nu <= next_nu)
    neg_max = (nu < 0) & (nu >= prev_nu) & (nu >= next_nu)
    pos_min |= (nu > 0) & ((~prev_ok & (nu <= next_nu)) | (~next_ok & (nu <= prev_nu)))
    neg_max |= (nu < 0) & ((~prev_ok & (nu >= next_nu)) | (~next_ok & (nu >= prev_nu)))
    return _Extrema(pos_min | neg_max, prev_nu, next_nu, prev_ok, next_ok)


@dataclass(frozen=True)
class _Sampled:
    """Every sheet of a dyad chain on the detection grid (shared by the closed form and the
    critical-point candidates, so both see the same grid): ``nu`` and ``d2`` (sheets, n, k),
    ``prefix[s, i, j]`` (dyads before ``j`` assembled, so ``nu_j`` is defined there), the margin
    ``tau`` and the report so far; ``problem`` says why the closed form cannot be used."""

    k: int
    scale: float
    tau: float
    n: int
    dth: float
    grid: np.ndarray
    sheets: np.ndarray
    nu: np.ndarray
    d2: np.ndarray
    pos_nu: np.ndarray
    prefix: np.ndarray
    report: dict[str, object]
    problem: str | None


def _sample_sheets(linkage: Linkage, ch: Chain, tol: Tolerances, samples: int) -> _Sampled:
    k = ch.k
    scale = float(np.median(linkage.lengths[linkage.active]))
    tau = float(np.clip(1e4 * tol.residual_atol / scale, 1e-10, 1e-3))
    n = int(samples)
    dth = 2 * np.pi / n
    offset = (np.sqrt(5) - 1) / 2  # irrational offset: symmetric angles are often special
    grid = dth * (np.arange(n) + offset)
    sheets = _sheets(k)
    n_sheets = len(sheets)
    report: dict[str, object] = {
        "rotor": linkage.bar_ids[ch.rotor], "dyads": k, "sheets": n_sheets,
        "samples": n, "margin": tau,
    }
    _, nu, d2 = place(ch, np.tile(grid, n_sheets), np.repeat(sheets, n, axis=0))
    nu = nu.reshape(n_sheets, n, k)
    d2 = d2.reshape(n_sheets, n, k)
    pos_nu = nu > 0
    prefix = np.concatenate(
        [np.ones((n_sheets, n, 1), bool), np.cumprod(pos_nu, axis=2)[:, :, :-1].astype(bool)],
        axis=2,
    )
    problem = None
    if not (np.isfinite(scale) and np.all(np.isfinite(nu)) and np.all(np.isfinite(d2))):
        problem = "non-finite values (coordinates or lengths too large)"
    elif np.any(prefix & (d2 <= (1e-6 * scale) ** 2)):
        # centres that coincide make a dyad's vertex free on a circle
        problem = "a dyad's centres (nearly) coincide"
    return _Sampled(k, scale, tau, n, dth, grid, sheets, nu, d2, pos_nu, prefix, report, problem)


def _closed_form(
    linkage: Linkage, ch: Chain, tol: Tolerances, step_max: float, max_points: int,
    samples: int,
) -> ClosedForm:
    sm = _sample_sheets(linkage, ch, tol, samples)
    k, tau, n, dth, grid, sheets = sm.k, sm.tau, sm.n, sm.dth, sm.grid, sm.sheets
    n_sheets, nu, pos_nu, prefix, report = len(sheets), sm.nu, sm.pos_nu, sm.prefix, sm.report

    def decline(why: str) -> ClosedForm:
        report["closed_form"] = f"declined: {why}"
        return ClosedForm(None, report)

    if sm.problem is not None:
        return decline(sm.problem)

    # -- every discrete extremum of nu_j that does not change sign: refine on its bracket --
    ext = _discrete_extrema(nu, prefix, axis=1)
    prev_ok, next_ok = ext.prev_ok, ext.next_ok
    cand = prefix & ext.mask
    si, ii, jj = np.nonzero(cand)
    if len(si):
        sgn = np.where(nu[si, ii, jj] > 0, 1.0, -1.0)
        lo = grid[ii] - np.where(prev_ok[si, ii, jj], dth, 0.0)
        hi = grid[ii] + np.where(next_ok[si, ii, jj], dth, 0.0)
        cand_signs = sheets[si]

        def signed_nu(t: np.ndarray) -> np.ndarray:
            _, v, _ = place(ch, t, cand_signs)
            return sgn * v[np.arange(len(t)), jj]

        extreme = _golden(signed_nu, lo, hi)
        if np.any(extreme <= tau):
            return decline("a dyad is (nearly) collinear at an extremum of its angle: at or "
                           "near critical lengths")

    # -- folds: where a sheet stops being assembled --
    valid: np.ndarray = np.asarray(pos_nu.all(axis=2), dtype=bool)  # (S, n)
    ends: list[tuple[int, int, int, int]] = []  # (sheet, inside index, outside index, +-1)
    for s in range(n_sheets):
        v = valid[s]
        up = np.flatnonzero(v & ~np.roll(v, 1))  # run starts: outside is i - 1
        down = np.flatnonzero(v & ~np.roll(v, -1))  # run ends: outside is i + 1
        ends += [(s, int(i), (int(i) - 1) % n, -1) for i in up]
        ends += [(s, int(i), (int(i) + 1) % n, +1) for i in down]
    folds: dict[tuple[int, int, int], float] = {}
    fold_j: list[int] = []
    if ends:
        e = np.array(ends)
        es, ein, eout, edir = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
        bad = ~pos_nu[es, eout]  # (F, k)
        jf = np.argmax(bad, axis=1)  # the first dyad that fails outside
        fold_j = jf.tolist()
        f_signs = sheets[es]
        lo = grid[ein].copy()
        hi = grid[ein] + edir * dth  # the outside angle, unwrapped next to the inside one
        rows = np.arange(len(es))
        for _ in range(64):  # bisection to the last bit: nu_j(lo) > 0 >= nu_j(hi)
            mid = 0.5 * (lo + hi)
            _, v, _ = place(ch, mid, f_signs)
            inside = v[rows, jf] > 0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        star = lo
        flat = np.zeros((len(es), k), bool)
        flat[rows, jf] = True
        # transversality: nu_j (defined on both sides) crosses zero with a slope
        h = 1e-3 * dth
        _, vp, _ = place(ch, star + h, f_signs)
        _, vm, _ = place(ch, star - h, f_signs)
        slope = np.abs(vp[rows, jf] - vm[rows, jf]) / (2 * h)
        if np.any(slope <= np.sqrt(tau)):
            return decline("a fold is nearly tangent: at or near critical lengths")
        # the other dyads keep their margin densely across the fold's grid cell (the vertex
        # moves like sqrt(theta - theta*) there, faster than the grid resolves)
        sig = np.linspace(0.0, 1.0, FOLD_CELL_SAMPLES)
        tt = star[:, None] + (grid[ein] - star)[:, None] * sig[None, :] ** 2
        rep_signs = np.repeat(f_signs, FOLD_CELL_SAMPLES, axis=0)
        rep_flat = np.zeros((tt.size, k), bool)
        rep_flat[::FOLD_CELL_SAMPLES] = flat  # sigma = 0 is the fold itself
        _, vv, _ = place(ch, tt.ravel(), rep_signs, rep_flat)
        vv = vv.reshape(len(es), FOLD_CELL_SAMPLES, k)
        others = np.ones((len(es), k), bool)
        others[rows, jf] = False
        if np.any((vv <= tau) & others[:, None, :]):
            return decline("two dyads are (nearly) collinear together: at or near critical "
                           "lengths")
        if np.any(vv[rows, 1:, jf] <= 0):
            return decline("a fold is not simple")
        for f in range(len(es)):
            folds[(int(es[f]), int(ein[f]), int(edir[f]))] = float(star[f])

    # -- arcs and their joins --
    # an arc: (sheet, start theta, end theta, start fold key, end fold key) or a full turn
    arcs: list[Arc] = []
    by_end: dict[tuple[int, int, int], tuple[int, int]] = {}
    jmap = {(int(s), int(i), int(d)): j for (s, i, _, d), j in zip(ends, fold_j, strict=True)}
    for s in range(n_sheets):
        v = valid[s]
        if v.all():
            arcs.append((s, grid[0], grid[0] + 2 * np.pi, None, None))
            continue
        up = np.flatnonzero(v & ~np.roll(v, 1))
        down = np.flatnonzero(v & ~np.roll(v, -1))
        for i0 in up:
            i1 = int(down[np.searchsorted(down, i0) % len(down)])
            t0 = folds[(s, int(i0), -1)]
            t1 = folds[(s, i1, +1)]
            t1 = t1 + 2 * np.pi * np.ceil((t0 - t1) / (2 * np.pi) - 1e-12) if t1 < t0 else t1
            a = len(arcs)
            arcs.append((s, t0, t1, (s, int(i0), -1), (s, i1, +1)))
            by_end[(s, int(i0), -1)] = (a, 0)
            by_end[(s, i1, +1)] = (a, 1)
    # the partner of an end: the sheet with the fold dyad's root flipped, same cell and side
    partner: dict[tuple[int, int], tuple[int, int]] = {}
    for key, (a, side) in by_end.items():
        s, i, d = key
        j = jmap[key]
        other = (s ^ (1 << j), i, d)
        if other not in by_end or jmap[other] != j:
            return decline("a fold without its partner sheet")
        partner[(a, side)] = by_end[other]
    report["folds"] = len(by_end) // 2

    # -- sample each arc to the step bound, walk the components --
    free = ~np.asarray(linkage.fixed)

    def arc_points(arc: Arc) -> np.ndarray:
        s, t0, t1, k0, k1 = arc
        full_turn = k0 is None

        def angle(sig: np.ndarray) -> np.ndarray:
            if full_turn:
                return t0 + (t1 - t0) * sig
            # theta - theta* ~ sig^2 at both ends: the vertex moves like sqrt there
            return t0 + (t1 - t0) * 0.5 * (1.0 - np.cos(np.pi * sig))

        def evaluate(sig: np.ndarray) -> np.ndarray:
            th = angle(sig)
            fl = np.zeros((len(sig), k), bool)
            if k0 is not None and k1 is not None:
                th = np.where(sig == 0.0, t0, np.where(sig == 1.0, t1, th))
                fl[sig == 0.0, jmap[k0]] = True
                fl[sig == 1.0, jmap[k1]] = True
            p, _, _ = place(ch, th, np.repeat(sheets[s][None, :], len(sig), axis=0), fl)
            if full_turn:
                p[-1] = p[0] if sig[-1] == 1.0 and sig[0] == 0.0 else p[-1]
            return p

        sig = np.linspace(0.0, 1.0, ARC_PILOT)
        p = evaluate(sig)
        u = p[:, free]
        chord = np.linalg.norm(np.diff(u, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(chord)])
        need = cum[-1] / (0.95 * step_max)
        if not np.isfinite(need) or need >= max_points:  # bounded before any allocation
            raise _Decline(f"a component needs more than max_points = {max_points} points")
        m = max(2, int(np.ceil(need)) + 1)
        sig = np.interp(np.linspace(0.0, cum[-1], m), cum, sig)
        sig[0], sig[-1] = 0.0, 1.0
        p = evaluate(sig)
        for _ in range(60):
            gaps = np.linalg.norm(np.diff(p[:, free], axis=0), axis=1)
            long = np.flatnonzero(gaps > step_max)
            if not len(long):
                return p
            if len(sig) + len(long) > max_points:
                raise _Decline(f"a component needs more than max_points = {max_points} points")
            mid = 0.5 * (sig[long] + sig[long + 1])
            order = np.argsort(np.concatenate([sig, mid]), kind="stable")
            sig = np.concatenate([sig, mid])[order]
            p = np.concatenate([p, evaluate(mid)])[order]
        raise _Decline("the step bound is not reached by bisection")

    components: list[np.ndarray] = []
    seen = [False] * len(arcs)
    try:
        pieces_of = [arc_points(a) for a in arcs]
    except _Decline as exc:
        return decline(str(exc))
    for a0 in range(len(arcs)):
        if seen[a0]:
            continue
        if arcs[a0][3] is None:
            seen[a0] = True
            components.append(pieces_of[a0])
            continue
        walk = [pieces_of[a0]]
        seen[a0] = True
        a, side = partner[(a0, 1)]
        while a != a0:
            if seen[a]:
                return decline("the arcs do not close into walks")
            seen[a] = True
            pts = pieces_of[a] if side == 0 else pieces_of[a][::-1]
            walk.append(pts[1:])
            a, side = partner[(a, 1 - side)]
        if side != 0:
            return decline("the arcs do not close into walks")
        # the last piece ends on a0's first fold point: the walk is closed as it stands
        components.append(np.concatenate(walk))
    if any(len(c) > max_points for c in components):
        return decline(f"a component needs more than max_points = {max_points} points")
    # -- every point keeps every bar within residual_atol (an independent check) --
    ends_ = linkage.ends[linkage.active]
    lengths = linkage.lengths[linkage.active]
    for c in components:
        diff = c[:, ends_[:, 0]] - c[:, ends_[:, 1]]
        res = np.abs(np.sqrt(np.einsum("nbd,nbd->nb", diff, diff)) - lengths)
        if res.size and float(res.max()) > tol.residual_atol:
            return decline("a point misses the lengths by more than residual_atol")
    report["closed_form"] = "used"
    return ClosedForm(components, report)


class _Decline(Exception):
    pass


# -- candidates for critical points ---------------------------------------------------------

#: More distinct candidates than this (e.g. a dyad collinear along a whole interval: a
#: non-isolated critical set) are left to the general search.
MAX_CANDIDATES = 64


@dataclass(frozen=True)
class CriticalCandidates:
    """Starting points (n, M free coordinates) for the refinement of critical points of a
    planar dyad chain: every place where the certificate of :func:`closed_form_space` is in
    doubt; or why there are none to give (``points`` is None)."""

    points: np.ndarray | None
    report: dict[str, object]


def critical_candidates(
    linkage: Linkage, tol: Tolerances, samples: int = DETECT_SAMPLES
) -> CriticalCandidates:
    """Candidates for every critical point of a planar dyad chain, in closed form.

    The certificate of the module docstring turned round: away from the places where one of its
    checks is within the margin ``tau`` there is no critical point, so starting points at those
    places (on every sheet: every extremum of a ``nu_j`` that comes within ``tau`` of zero, at
    its refined angle; every fold that is nearly tangent or where another dyad comes within
    ``tau``, at the fold and at that dyad's smallest ``nu`` in the fold's cell) contain a start
    next to every critical point. The caller refines them on the augmented system
    (:func:`engine.critical.refine_critical`).

    Returns
    -------
    CriticalCandidates
        ``points`` (n, M), possibly empty (then the certificate holds: no critical point); None
        (with ``report["closed_form"]`` saying why) when the linkage is not a plain dyad chain,
        dyad centres (nearly) coincide, values are not finite, or there are more than
        :data:`MAX_CANDIDATES` distinct candidates.
    """
    ch = chain_of(linkage)
    if ch is None:
        return CriticalCandidates(None, {"closed_form": "declined: not a planar dyad chain"})
    with np.errstate(all="ignore"):
        return _candidates(linkage, ch, tol, samples)


def _candidates(linkage: Linkage, ch: Chain, tol: Tolerances, samples: int) -> CriticalCandidates:
    sm = _sample_sheets(linkage, ch, tol, samples)
    k, scale, tau, n, dth, grid, sheets = sm.k, sm.scale, sm.tau, sm.n, sm.dth, sm.grid, sm.sheets
    n_sheets, nu, pos_nu, prefix, report = len(sheets), sm.nu, sm.pos_nu, sm.prefix, sm.report

    def decline(why: str) -> CriticalCandidates:
        report["closed_form"] = f"declined: {why}"
        return CriticalCandidates(None, report)

    if sm.problem is not None:
        return decline(sm.problem)

    # candidates as (angle, sheet, flat dyad or -1)
    c_theta: list[np.ndarray] = []
    c_sheet: list[np.ndarray] = []
    c_flat: list[np.ndarray] = []

    # -- extrema of nu_j (the same detection as closed_form_space) within tau of zero --
    ext = _discrete_extrema(nu, prefix, axis=1)
    prev_nu, next_nu, prev_ok, next_ok = ext.prev_nu, ext.next_nu, ext.prev_ok, ext.next_ok
    # exact zeros on the grid are extrema of |nu| for this purpose (a double zero hit exactly)
    cand = prefix & (ext.mask | (nu == 0))
    # Only an extremum that can come within tau is refined: near its minimum a smooth nu
    # differs from a neighbouring sample by at least its depth below the nearest one (about a
    # quarter of that is the bound for a parabola; 16 times it leaves a wide margin). A sheet
    # where a dyad keeps its angle (a parallelogram) has thousands of rounding-level "extrema"
    # far from zero, all skipped here.
    spread = np.maximum(np.where(prev_ok, np.abs(nu - prev_nu), 0.0),
                        np.where(next_ok, np.abs(nu - next_nu), 0.0))
    cand &= np.abs(nu) - 16.0 * spread <= tau
    si, ii, jj = np.nonzero(cand)
    if len(si):
        sgn = np.where(nu[si, ii, jj] >= 0, 1.0, -1.0)
        lo = grid[ii] - np.where(prev_ok[si, ii, jj], dth, 0.0)
        hi = grid[ii] + np.where(next_ok[si, ii, jj], dth, 0.0)
        cand_signs = sheets[si]

        def signed_nu(t: np.ndarray) -> np.ndarray:
            _, v, _ = place(ch, t, cand_signs)
            return sgn * v[np.arange(len(t)), jj]

        # 40 steps shrink the bracket to 1e-8 of its width, below the sqrt(eps) to which a
        # minimum's place is defined anyway
        extreme, where = _golden_arg(signed_nu, lo, hi, iters=40)
        near = extreme <= tau
        # where a later dyad does not assemble there is no configuration at that angle
        _, v_at, _ = place(ch, where, cand_signs)
        later = np.arange(k)[None, :] > jj[:, None]
        near &= ~np.any(later & (v_at < -tau), axis=1)
        report["extrema_within_margin"] = int(near.sum())
        c_theta.append(where[near])
        c_sheet.append(si[near])
        c_flat.append(np.full(int(near.sum()), -1))

    # -- folds: nearly tangent, or another dyad within tau across the fold's cell --
    valid: np.ndarray = np.asarray(pos_nu.all(axis=2), dtype=bool)
    ends: list[tuple[int, int, int, int]] = []
    for s in range(n_sheets):
        v = valid[s]
        up = np.flatnonzero(v & ~np.roll(v, 1))
        down = np.flatnonzero(v & ~np.roll(v, -1))
        ends += [(s, int(i), (int(i) - 1) % n, -1) for i in up]
        ends += [(s, int(i), (int(i) + 1) % n, +1) for i in down]
    n_doubtful_folds = 0
    if ends:
        e = np.array(ends)
        es, ein, eout, edir = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
        jf = np.argmax(~pos_nu[es, eout], axis=1)
        f_signs = sheets[es]
        lo = grid[ein].copy()
        hi = grid[ein] + edir * dth
        rows = np.arange(len(es))
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            _, v, _ = place(ch, mid, f_signs)
            inside = v[rows, jf] > 0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        star = lo
        h = 1e-3 * dth
        _, vp, _ = place(ch, star + h, f_signs)
        _, vm, _ = place(ch, star - h, f_signs)
        tangent = np.abs(vp[rows, jf] - vm[rows, jf]) / (2 * h) <= np.sqrt(tau)
        sig = np.linspace(0.0, 1.0, FOLD_CELL_SAMPLES)
        tt = star[:, None] + (grid[ein] - star)[:, None] * sig[None, :] ** 2
        rep_signs = np.repeat(f_signs, FOLD_CELL_SAMPLES, axis=0)
        rep_flat = np.zeros((tt.size, k), bool)
        rep_flat[::FOLD_CELL_SAMPLES][rows, jf] = True
        _, vv, _ = place(ch, tt.ravel(), rep_signs, rep_flat)
        vv = vv.reshape(len(es), FOLD_CELL_SAMPLES, k)
        vv[rows, :, jf] = np.inf  # the fold's own dyad
        others = vv.min(axis=2)  # (F, cells)
        crowded = (others <= tau).any(axis=1)
        doubtful = tangent | crowded
        n_doubtful_folds = int(doubtful.sum())
        # at the fold itself (its dyad flat) ...
        c_theta.append(star[doubtful])
        c_sheet.append(es[doubtful])
        c_flat.append(jf[doubtful])
        # ... and where another dyad comes closest to collinear in the fold's cell
        at = np.argmin(others, axis=1)
        inner = crowded & (at > 0)
        c_theta.append(tt[rows, at][inner])
        c_sheet.append(es[inner])
        c_flat.append(np.full(int(inner.sum()), -1))

    report["doubtful_folds"] = n_doubtful_folds
    t_all = np.concatenate(c_theta) if c_theta else np.zeros(0)
    s_all = np.concatenate(c_sheet).astype(int) if c_sheet else np.zeros(0, int)
    f_all = np.concatenate(c_flat).astype(int) if c_flat else np.zeros(0, int)
    free = ~np.asarray(linkage.fixed)
    if not len(t_all):
        report["candidates"] = 0
        return CriticalCandidates(np.zeros((0, int(free.sum()))), report)
    flat = np.zeros((len(t_all), k), bool)
    flat[np.flatnonzero(f_all >= 0), f_all[f_all >= 0]] = True
    pos, _, dd = place(ch, t_all, sheets[s_all], flat)
    # A dyad whose centres coincide (at an isolated angle: nu_j, a product with d^2, has a
    # double zero there) leaves its vertex free on a circle, every point of which has the two
    # bars on one line. A self-stress on the pair (+w, -w) puts opposite forces +-w e on the
    # two centres (e the unit vector from them to the vertex); it is balanced by the rest
    # exactly when e is orthogonal to the centres' relative velocity d(a - b)/d theta: the two
    # points of the circle at +-90 degrees from it are the candidates there.
    coincide = dd <= (1e-6 * scale) ** 2
    keep_rows = ~coincide.any(axis=1)
    u_parts = [pos[keep_rows][:, free]]
    ci, cj = np.nonzero(coincide)
    if len(ci):
        h = 1e-6
        s_c = sheets[s_all[ci]]
        pp, _, _ = place(ch, t_all[ci] + h, s_c)
        pm, _, _ = place(ch, t_all[ci] - h, s_c)
        rel = (pp[np.arange(len(ci)), ch.a[cj]] - pp[np.arange(len(ci)), ch.b[cj]]) - (
            pm[np.arange(len(ci)), ch.a[cj]] - pm[np.arange(len(ci)), ch.b[cj]])
        centre = pos[np.arange(len(ci)), ch.a[cj]]
        if np.any(np.abs(ch.ra[cj] - ch.rb[cj]) > 1e-6 * scale):
            return decline("a dyad's centres coincide where its radii differ")
        for turn in (0.5 * np.pi, -0.5 * np.pi):
            psi = np.arctan2(rel[:, 1], rel[:, 0]) + turn
            for jj_ in np.unique(cj):
                sel = cj == jj_
                vtx = centre[sel] + ch.ra[jj_] * np.column_stack([np.cos(psi[sel]),
                                                                 np.sin(psi[sel])])
                pc, _, _ = place(ch, t_all[ci[sel]], s_c[sel], None, {int(jj_): vtx})
                u_parts.append(pc[:, free])
        # Along the circle the later dyads move with the vertex: where one of them is collinear
        # as well (a double zero of its nu along the circle, or a fold along it where the
        # rigidity matrix is singular) there may be critical points too.
        ends_ = linkage.ends[linkage.active]
        seen: list[tuple[int, tuple[int, ...], float]] = []
        for r in range(len(ci)):
            # sheets that differ only in this dyad's own root give the same circle
            key_signs = tuple(int(x) for i, x in enumerate(s_c[r]) if i != int(cj[r]))
            t0 = float(t_all[ci[r]])
            if any(j0 == int(cj[r]) and s0 == key_signs and abs(t1 - t0) <= 1e-6
                   for j0, s0, t1 in seen):
                continue
            seen.append((int(cj[r]), key_signs, t0))
            try:
                u_parts += _circle_candidates(
                    ch, float(t_all[ci[r]]), s_c[r], int(cj[r]), centre[r], tau, scale, free,
                    ends_, tol)
            except _Decline as exc:
                return decline(str(exc))
    u = np.concatenate(u_parts)
    if not np.all(np.isfinite(u)):
        return decline("non-finite candidate")
    # the same start found on several sheets (a collinear dyad's two roots coincide): once
    keep: list[int] = []
    for i in range(len(u)):
        if not keep or np.min(np.linalg.norm(u[keep] - u[i], axis=1)) > 1e-6 * scale:
            keep.append(i)
            if len(keep) > MAX_CANDIDATES:
                return decline(f"more than {MAX_CANDIDATES} candidates for critical points "
                               "(a non-isolated critical set?)")
    report["candidates"] = len(keep)
    return CriticalCandidates(u[keep], report)


#: Samples of the vertex's circle where a dyad's centres coincide.
CIRCLE_SAMPLES = 2048


def _gap(pos: np.ndarray, ends: np.ndarray, free: np.ndarray) -> float:
    """``s_min / s_max`` of the rigidity matrix at positions ``pos`` (V, 2)."""
    diff = pos[ends[:, 0]] - pos[ends[:, 1]]
    jac = np.zeros((len(ends), *pos.shape))
    rows = np.arange(len(ends))
    jac[rows, ends[:, 0]] = 2 * diff
    jac[rows, ends[:, 1]] = -2 * diff
    sv = np.linalg.svd(jac[:, free].reshape(len(ends), -1), compute_uv=False)
    return float(sv[-1] / sv[0]) if sv.size and sv[0] > 0 else 0.0


def _circle_candidates(
    ch: Chain, theta0: float, signs: np.ndarray, j: int, centre: np.ndarray, tau: float,
    scale: float, free: np.ndarray, ends: np.ndarray, tol: Tolerances,
) -> list[np.ndarray]:
    """Candidates on the circle of dyad ``j``'s vertex (its centres coincide at ``theta0``)
    from the later dyads on sheet ``signs``: every extremum of their ``nu`` along the circle
    within ``tau`` of zero, and every fold along it where ``J`` is singular (decided exactly at
    the fold; a gap between ``rank_rtol`` and ``1e-3`` declines)."""
    k = ch.k
    if j == k - 1:
        return []
    n = CIRCLE_SAMPLES
    dps = 2 * np.pi / n
    grid = dps * (np.arange(n) + (np.sqrt(5) - 1) / 2)
    radius = float(ch.ra[j])

    def at(psi: np.ndarray, flat: np.ndarray | None = None,
           extra: dict[int, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray,
                                                                np.ndarray]:
        vtx = centre + radius * np.column_stack([np.cos(psi), np.sin(psi)])
        return place(ch, np.full(len(psi), theta0), np.repeat(signs[None, :], len(psi), axis=0),
                     flat, {j: vtx, **(extra or {})})

    _, nu, d2 = at(grid)
    later = np.arange(k) > j
    pos_nu = (nu > 0) | ~later
    prefix = np.concatenate([np.ones((n, 1), bool),
                             np.cumprod(pos_nu, axis=1)[:, :-1].astype(bool)], axis=1) & later
    if np.any(prefix & (d2 <= (1e-6 * scale) ** 2)):
        raise _Decline("centres coincide twice (on the circle of a dyad's vertex)")
    out: list[np.ndarray] = []
    ext = _discrete_extrema(nu, prefix, axis=0)
    prev_ok, next_ok = ext.prev_ok, ext.next_ok
    ii, jj = np.nonzero(prefix & (ext.mask | (nu == 0)))
    if len(ii):
        sgn = np.where(nu[ii, jj] >= 0, 1.0, -1.0)
        lo = grid[ii] - np.where(prev_ok[ii, jj], dps, 0.0)
        hi = grid[ii] + np.where(next_ok[ii, jj], dps, 0.0)

        def signed_nu(t: np.ndarray) -> np.ndarray:
            _, v, _ = at(t)
            return sgn * v[np.arange(len(t)), jj]

        extreme, where = _golden_arg(signed_nu, lo, hi, iters=40)
        near = extreme <= tau
        if near.any():
            p, _, dd = at(where[near])
            jn = jj[near]
            nested = dd[np.arange(len(jn)), jn] <= (1e-6 * scale) ** 2
            out.append(p[~nested][:, free])
            # a later dyad's centres coincide too (its vertex on a circle of its own): the same
            # rule, with the motion along this circle; deeper nesting declines
            for r in np.flatnonzero(nested):
                i = int(jn[r])
                if i != k - 1 or abs(ch.ra[i] - ch.rb[i]) > 1e-6 * scale:
                    raise _Decline("centres coincide twice (on the circle of a dyad's vertex)")
                h = 1e-6
                pp, _, _ = at(where[near][r:r + 1] + h)
                pm, _, _ = at(where[near][r:r + 1] - h)
                rel = (pp[0, ch.a[i]] - pp[0, ch.b[i]]) - (pm[0, ch.a[i]] - pm[0, ch.b[i]])
                for turn in (0.5 * np.pi, -0.5 * np.pi):
                    phi = np.arctan2(rel[1], rel[0]) + turn
                    vtx = p[r, ch.a[i]] + ch.ra[i] * np.array([np.cos(phi), np.sin(phi)])
                    pc, _, _ = at(where[near][r:r + 1], None, {i: vtx[None, :]})
                    out.append(pc[:, free])
    # folds of the later dyads along the circle: J decides at the fold point itself
    valid = np.all(pos_nu, axis=1)
    up = np.flatnonzero(valid & ~np.roll(valid, 1))
    down = np.flatnonzero(valid & ~np.roll(valid, -1))
    ein = np.concatenate([up, down]).astype(int)
    edir = np.concatenate([-np.ones(len(up), int), np.ones(len(down), int)])
    if len(ein):
        jf = np.argmax(~pos_nu[(ein + edir) % n], axis=1)
        lo, hi = grid[ein].copy(), grid[ein] + edir * dps
        rows = np.arange(len(ein))
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            _, v, _ = at(mid)
            inside = v[rows, jf] > 0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        flat = np.zeros((len(ein), k), bool)
        flat[rows, jf] = True
        p, _, _ = at(lo, flat)
        for f in range(len(ein)):
            g = _gap(p[f], ends, free)
            if g <= 1e3 * tol.rank_rtol:
                out.append(p[f][None, free])
            elif g < 1e-3:
                raise _Decline("a fold on the circle of a dyad's vertex is nearly singular")
    return out
