"""Every component of a planar dyad chain in closed form, with the certificate that it has no
critical point (see :mod:`engine.space.dyads`): sheets sampled, extrema and folds checked, arcs cut
at
the folds and joined into walks, each sampled to the step bound."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.dyads import kernel
from engine.space.dyads.chain import (
    DETECT_SAMPLES,
    GOLDEN_RATIO,
    Chain,
    Decline,
    Folds,
    Sampled,
    chains_of,
    discrete_extrema,
    golden,
    locate_folds,
    place,
    place_free,
    sample_sheets,
)

#: Points of the first pass along an arc (before resampling to the step bound).
ARC_PILOT = 512
#: Golden-section steps of the extrema check.
GOLDEN_ITERS = 60
#: Driving rotors tried, in bar order, before the closed form declines: the certificate needs
#: the zeros of the dyads' ``nu`` apart, and two dyads may straighten together under one
#: driver without a critical point (a three-rotor driven by its first rotor: the first coupler
#: in line with the middle rotor while the second is in line with the last rotor) while under
#: another (the middle rotor, both dyads on its tip) that is exactly a critical point.
ROTORS_TRIED = 3

FoldKey = tuple[int, int, int]  # (sheet, inside grid index, -1 at a run's start / +1 at its end)
Arc = tuple[int, float, float, FoldKey | None, FoldKey | None]  # sheet, theta range, end folds


@dataclass(frozen=True)
class ClosedForm:
    """Components (each a closed walk (n, M) of the free coordinates, as
    ``positions[:, ~linkage.fixed]``, the first point repeated at the end) and what was
    checked; or why the closed form declined (``components`` is None)."""

    components: list[np.ndarray] | None
    report: dict[str, object]


def closed_form_space(
    linkage: Linkage, tol: Tolerances, step_max: float, max_points: int,
    samples: int = DETECT_SAMPLES,
) -> ClosedForm:
    """Every component of a planar dyad chain in closed form, with the certificate that the
    configuration space holds no critical point; see the module docstring.

    Parameters
    ----------
    linkage : Linkage
        One degree of freedom, something fixed (as for
    :func:`engine.space.configuration_space.explore`).
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
    first: ClosedForm | None = None
    for k, ch in enumerate(chains_of(linkage)):
        if k >= ROTORS_TRIED:
            break
        # Overflow (coordinates up to 1e100 are accepted) shows up as non-finite values,
        # which decline below; no warning is worth raising for it.
        with np.errstate(all="ignore"):
            found = _closed_form(linkage, ch, tol, step_max, max_points, samples)
        if found.components is not None:
            return found
        first = first or found
    if first is None:
        return ClosedForm(None, {"closed_form": "declined: not a planar dyad chain"})
    return first


def _closed_form(
    linkage: Linkage, ch: Chain, tol: Tolerances, step_max: float, max_points: int,
    samples: int,
) -> ClosedForm:
    sm = sample_sheets(linkage, ch, tol, samples)
    try:
        if sm.problem is not None:
            raise Decline(sm.problem)
        _check_extrema(ch, sm)
        folds = locate_folds(ch, sm)
        fold_at = _check_folds(sm, folds)
        arcs, partner, dyad_of = _arcs(sm, folds, fold_at)
        sm.report["folds"] = len(partner) // 2
        sampler = _ArcSampler(ch, sm.sheets, dyad_of, step_max, max_points)
        components = _walks(arcs, [sampler.points(a) for a in arcs], partner)
        _check_lengths(linkage, ch, components, tol, max_points)
    except Decline as exc:
        sm.report["closed_form"] = f"declined: {exc}"
        return ClosedForm(None, sm.report)
    sm.report["closed_form"] = "used"
    return ClosedForm(components, sm.report)


def _check_extrema(ch: Chain, sm: Sampled) -> None:
    """Every discrete extremum of ``nu_j`` that does not change sign, refined on its bracket,
    stays beyond the margin."""
    ext = discrete_extrema(sm.nu, sm.prefix, axis=1)
    si, ii, jj = np.nonzero(sm.prefix & ext.mask)
    if not len(si):
        return
    sgn = np.where(sm.nu[si, ii, jj] > 0, 1.0, -1.0)
    lo = sm.grid[ii] - np.where(ext.prev_ok[si, ii, jj], sm.dth, 0.0)
    hi = sm.grid[ii] + np.where(ext.next_ok[si, ii, jj], sm.dth, 0.0)
    if np.any(extremum_minima(ch, lo, hi, sgn, jj, sm.sheets[si]) <= sm.tau):
        raise Decline("a dyad is (nearly) collinear at an extremum of its angle: at or near "
                      "critical lengths")


def extremum_minima(ch: Chain, lo: np.ndarray, hi: np.ndarray, sgn: np.ndarray,
                    dyad: np.ndarray, signs: np.ndarray) -> np.ndarray:
    """The smallest ``sgn * nu`` of ``dyad`` on sheet ``signs`` (m, k) seen by the golden
    search (:func:`engine.space.dyads.chain.golden`) on each ``[lo, hi]`` (m,). Compiled: the same
    search in one call (sixty placements of a few angles cost more in numpy's overhead than
    in arithmetic), equal to rounding (math's trigonometry instead of numpy's)."""
    compiled = kernel.kernels()
    if compiled is not None:
        best = np.empty(len(lo))
        compiled.golden_signed_nu(
            np.ascontiguousarray(lo, dtype=float), np.ascontiguousarray(hi, dtype=float),
            np.ascontiguousarray(sgn, dtype=float), np.ascontiguousarray(dyad, dtype=np.int64),
            np.ascontiguousarray(signs, dtype=float), GOLDEN_ITERS, GOLDEN_RATIO, ch.vertex,
            ch.a, ch.b, ch.consts, ch.base, ch.pin, ch.tip, ch.radius, best)
        return best
    rows = np.arange(len(lo))

    def signed_nu(t: np.ndarray) -> np.ndarray:
        _, v, _ = place(ch, t, signs)
        return sgn * v[rows, dyad]

    return golden(signed_nu, lo, hi, GOLDEN_ITERS)


def _check_folds(sm: Sampled, folds: Folds | None) -> dict[FoldKey, float]:
    """Every fold transversal, simple, with the other dyads beyond the margin across its cell:
    the fold angle by fold key."""
    if folds is None:
        return {}
    if np.any(folds.slope <= np.sqrt(sm.tau)):
        raise Decline("a fold is nearly tangent: at or near critical lengths")
    rows = np.arange(len(folds.sheet))
    others = np.ones((len(rows), sm.k), bool)
    others[rows, folds.dyad] = False
    if np.any((folds.cell_nu <= sm.tau) & others[:, None, :]):
        raise Decline("two dyads are (nearly) collinear together: at or near critical lengths")
    if np.any(folds.cell_nu[rows, 1:, folds.dyad] <= 0):
        raise Decline("a fold is not simple")
    return {(int(s), int(i), int(d)): float(t) for s, i, d, t
            in zip(folds.sheet, folds.inside, folds.direction, folds.star, strict=True)}


def _arcs(
    sm: Sampled, folds: Folds | None, fold_at: dict[FoldKey, float]
) -> tuple[list[Arc], dict[tuple[int, int], tuple[int, int]], dict[FoldKey, int]]:
    """The arcs (sheets cut at their folds, or whole turns), the partner of every arc end (the
    sheet with the fold dyad's root flipped, same cell and side) and the dyad of every fold."""
    valid: np.ndarray = np.asarray(sm.pos_nu.all(axis=2), dtype=bool)
    dyad_of: dict[FoldKey, int] = {} if folds is None else {
        (s, i, d): int(j) for (s, i, _, d), j in zip(folds.ends, folds.dyad, strict=True)}
    arcs: list[Arc] = []
    by_end: dict[FoldKey, tuple[int, int]] = {}
    for s in range(len(sm.sheets)):
        v = valid[s]
        if v.all():
            arcs.append((s, sm.grid[0], sm.grid[0] + 2 * np.pi, None, None))
            continue
        up = np.flatnonzero(v & ~np.roll(v, 1))
        down = np.flatnonzero(v & ~np.roll(v, -1))
        for i0 in up:
            i1 = int(down[np.searchsorted(down, i0) % len(down)])
            t0 = fold_at[(s, int(i0), -1)]
            t1 = fold_at[(s, i1, +1)]
            t1 = t1 + 2 * np.pi * np.ceil((t0 - t1) / (2 * np.pi) - 1e-12) if t1 < t0 else t1
            by_end[(s, int(i0), -1)] = (len(arcs), 0)
            by_end[(s, i1, +1)] = (len(arcs), 1)
            arcs.append((s, t0, t1, (s, int(i0), -1), (s, i1, +1)))
    partner: dict[tuple[int, int], tuple[int, int]] = {}
    for key, end in by_end.items():
        s, i, d = key
        j = dyad_of[key]
        other = (s ^ (1 << j), i, d)
        if other not in by_end or dyad_of[other] != j:
            raise Decline("a fold without its partner sheet")
        partner[end] = by_end[other]
    return arcs, partner, dyad_of


@dataclass(frozen=True)
class _ArcSampler:
    """Samples arcs to the step bound (free coordinates), within the point budget."""

    ch: Chain
    sheets: np.ndarray
    dyad_of: dict[FoldKey, int]
    step_max: float
    max_points: int

    def positions(self, arc: Arc, sig: np.ndarray) -> np.ndarray:
        """Free coordinates (n, M) at arc parameters ``sig`` in [0, 1]; the fold points exactly
        (their dyad flat: the two sheets meeting there give bitwise the same configuration)."""
        s, t0, t1, k0, k1 = arc
        if k0 is None:  # a full turn
            th = t0 + (t1 - t0) * sig
        else:  # theta - theta* ~ sig^2 at both ends: the vertex moves like sqrt there
            th = t0 + (t1 - t0) * 0.5 * (1.0 - np.cos(np.pi * sig))
        fl = None
        if k0 is not None and k1 is not None:
            th = np.where(sig == 0.0, t0, np.where(sig == 1.0, t1, th))
            fl = np.zeros((len(sig), self.ch.k), bool)
            fl[sig == 0.0, self.dyad_of[k0]] = True
            fl[sig == 1.0, self.dyad_of[k1]] = True
        # one sheet along the arc: its signs (1, k) broadcast over the samples
        p = place_free(self.ch, th, self.sheets[s][None, :], fl)
        if k0 is None and sig[-1] == 1.0 and sig[0] == 0.0:
            p[-1] = p[0]
        return p

    def points(self, arc: Arc) -> np.ndarray:
        """The arc sampled so that consecutive points are at most ``step_max`` apart: a pilot
        pass, resampled by arc length, then bisected where a gap is still too long."""
        sig = np.linspace(0.0, 1.0, ARC_PILOT)
        u = self.positions(arc, sig)
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(u, axis=0), axis=1))])
        need = cum[-1] / (0.95 * self.step_max)
        if not np.isfinite(need) or need >= self.max_points:  # bounded before any allocation
            raise Decline(f"a component needs more than max_points = {self.max_points} points")
        sig = np.interp(np.linspace(0.0, cum[-1], max(2, int(np.ceil(need)) + 1)), cum, sig)
        sig[0], sig[-1] = 0.0, 1.0
        p = self.positions(arc, sig)
        for _ in range(60):
            long = long_gaps(p, self.step_max)
            if not len(long):
                return p
            if len(sig) + len(long) > self.max_points:
                raise Decline(
                    f"a component needs more than max_points = {self.max_points} points")
            mid = 0.5 * (sig[long] + sig[long + 1])
            order = np.argsort(np.concatenate([sig, mid]), kind="stable")
            sig = np.concatenate([sig, mid])[order]
            p = np.concatenate([p, self.positions(arc, mid)])[order]
        raise Decline("the step bound is not reached by bisection")


def long_gaps(walk: np.ndarray, limit: float) -> np.ndarray:
    """The ``i`` whose step from sample ``i`` to ``i + 1`` of ``walk`` (n, M) is longer than
    ``limit``: the squares summed column by column, then the square root (the compiled
    kernel's order: both paths give the same bits)."""
    n = max(len(walk) - 1, 0)
    compiled = kernel.kernels()
    if compiled is not None:
        out = np.empty(n, dtype=np.int64)
        count = compiled.long_gaps(np.ascontiguousarray(walk, dtype=float), float(limit), out)
        return out[:count]
    total = np.zeros(n)
    for c in range(walk.shape[1]):
        d = walk[1:, c] - walk[:-1, c]
        total = d * d if c == 0 else total + d * d
    return np.flatnonzero(np.sqrt(total) > limit)


def within_lengths(ch: Chain, walk: np.ndarray, ends: np.ndarray, lengths: np.ndarray,
                   atol: float) -> bool:
    """Every sample of ``walk`` (n, M; free coordinates of ``ch``, its pins where they are)
    with every bar ``ends`` (E, 2) within ``atol`` of its length:
    ``| |p_i - p_j| - L | <= atol  <=>  (L - atol)^2 <= |p_i - p_j|^2 <= (L + atol)^2`` (no
    square root per sample); a non-finite sample fails."""
    low = np.array([max(length - atol, 0.0) ** 2 for length in lengths.tolist()])
    high = np.array([(length + atol) ** 2 for length in lengths.tolist()])
    ends = np.ascontiguousarray(ends, dtype=np.int64)
    cols = ch.columns
    compiled = kernel.kernels()
    if compiled is not None:
        return bool(compiled.within_lengths(np.ascontiguousarray(walk, dtype=float), ch.base,
                                            cols, ends, low, high))

    def coordinate(v: int, axis: int) -> np.ndarray:
        return walk[:, cols[v] + axis] if cols[v] >= 0 else ch.base[v, axis]

    for (i, j), lo, hi in zip(ends.tolist(), low, high, strict=True):
        # one pass per bar over views of the walk; a nan fails the comparison
        dx = coordinate(i, 0) - coordinate(j, 0)
        dy = coordinate(i, 1) - coordinate(j, 1)
        d2 = np.asarray(dx * dx + dy * dy)
        if len(walk) and not (lo <= d2.min() and d2.max() <= hi):
            return False
    return True


def _walks(arcs: list[Arc], pieces: list[np.ndarray],
           partner: dict[tuple[int, int], tuple[int, int]]) -> list[np.ndarray]:
    """The components: whole turns as they are, arcs joined end to end at their folds."""
    components: list[np.ndarray] = []
    seen = [False] * len(arcs)
    for a0 in range(len(arcs)):
        if seen[a0]:
            continue
        seen[a0] = True
        if arcs[a0][3] is None:
            components.append(pieces[a0])
            continue
        walk = [pieces[a0]]
        a, side = partner[(a0, 1)]
        while a != a0:
            if seen[a]:
                raise Decline("the arcs do not close into walks")
            seen[a] = True
            pts = pieces[a] if side == 0 else pieces[a][::-1]
            walk.append(pts[1:])
            a, side = partner[(a, 1 - side)]
        if side != 0:
            raise Decline("the arcs do not close into walks")
        # the last piece ends on a0's first fold point: the walk is closed as it stands
        components.append(np.concatenate(walk))
    return components


def _check_lengths(linkage: Linkage, ch: Chain, components: list[np.ndarray], tol: Tolerances,
                   max_points: int) -> None:
    """Every component within the point budget, every point with every bar within
    ``residual_atol`` (an independent check)."""
    if any(len(c) > max_points for c in components):
        raise Decline(f"a component needs more than max_points = {max_points} points")
    ends = linkage.ends[linkage.active]
    lengths = linkage.lengths[linkage.active]
    if not all(within_lengths(ch, c, ends, lengths, tol.residual_atol) for c in components):
        raise Decline("a point misses the lengths by more than residual_atol")
