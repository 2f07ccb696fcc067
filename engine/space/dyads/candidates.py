"""Candidates for every critical point of a planar dyad chain, in closed form: the places where
the certificate of :mod:`engine.space.dyads.closed_form` is in doubt (extrema of a dyad's ``nu``
near
zero, doubtful folds, dyads whose centres coincide), refined by the caller."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from engine.model.linkage import Linkage
from engine.model.tolerances import SAME_POINT_REL, Tolerances
from engine.space.dyads.chain import (
    DETECT_SAMPLES,
    Chain,
    Decline,
    Folds,
    Sampled,
    bisect_folds,
    chain_of,
    discrete_extrema,
    golden_arg,
    locate_folds,
    place,
    sample_sheets,
)

#: More distinct candidates than this (e.g. a dyad collinear along a whole interval: a
#: non-isolated critical set) are left to the general search.
MAX_CANDIDATES = 64
#: Samples of the vertex's circle where a dyad's centres coincide.
CIRCLE_SAMPLES = 2048


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
    (:func:`engine.local.critical.refine_critical`).

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


#: Candidates as (angles, sheets, flat dyad or -1).
_Starts = tuple[np.ndarray, np.ndarray, np.ndarray]


def _candidates(linkage: Linkage, ch: Chain, tol: Tolerances, samples: int) -> CriticalCandidates:
    sm = sample_sheets(linkage, ch, tol, samples)
    report = sm.report
    try:
        if sm.problem is not None:
            raise Decline(sm.problem)
        starts = [_extremum_starts(ch, sm), *_fold_starts(sm, locate_folds(ch, sm))]
        theta = np.concatenate([s[0] for s in starts])
        sheet = np.concatenate([s[1] for s in starts]).astype(int)
        flat_dyad = np.concatenate([s[2] for s in starts]).astype(int)
        free = ~np.asarray(linkage.fixed)
        if not len(theta):
            report["candidates"] = 0
            return CriticalCandidates(np.zeros((0, int(free.sum()))), report)
        u = _distinct(_configurations(linkage, ch, sm, tol, theta, sheet, flat_dyad, free),
                      sm.scale)
    except Decline as exc:
        report["closed_form"] = f"declined: {exc}"
        return CriticalCandidates(None, report)
    report["candidates"] = len(u)
    return CriticalCandidates(u, report)


def _none() -> _Starts:
    return np.zeros(0), np.zeros(0, int), np.zeros(0, int)


def _extremum_starts(ch: Chain, sm: Sampled) -> _Starts:
    """Extrema of ``nu_j`` (the same detection as the closed form) that come within ``tau`` of
    zero, at their refined angles."""
    nu = sm.nu
    ext = discrete_extrema(nu, sm.prefix, axis=1)
    # exact zeros on the grid are extrema of |nu| for this purpose (a double zero hit exactly)
    cand = sm.prefix & (ext.mask | (nu == 0))
    # Only an extremum that can come within tau is refined: near its minimum a smooth nu
    # differs from a neighbouring sample by at least its depth below the nearest one (about a
    # quarter of that is the bound for a parabola; 16 times it leaves a wide margin). A sheet
    # where a dyad keeps its angle (a parallelogram) has thousands of rounding-level "extrema"
    # far from zero, all skipped here.
    spread = np.maximum(np.where(ext.prev_ok, np.abs(nu - ext.prev_nu), 0.0),
                        np.where(ext.next_ok, np.abs(nu - ext.next_nu), 0.0))
    cand &= np.abs(nu) - 16.0 * spread <= sm.tau
    si, ii, jj = np.nonzero(cand)
    if not len(si):
        return _none()
    sgn = np.where(nu[si, ii, jj] >= 0, 1.0, -1.0)
    lo = sm.grid[ii] - np.where(ext.prev_ok[si, ii, jj], sm.dth, 0.0)
    hi = sm.grid[ii] + np.where(ext.next_ok[si, ii, jj], sm.dth, 0.0)
    cand_signs = sm.sheets[si]

    def signed_nu(t: np.ndarray) -> np.ndarray:
        _, v, _ = place(ch, t, cand_signs)
        return sgn * v[np.arange(len(t)), jj]

    # 40 steps shrink the bracket to 1e-8 of its width, below the sqrt(eps) to which a
    # minimum's place is defined anyway
    extreme, where = golden_arg(signed_nu, lo, hi, iters=40)
    near = extreme <= sm.tau
    # where a later dyad does not assemble there is no configuration at that angle
    _, v_at, _ = place(ch, where, cand_signs)
    later = np.arange(ch.k)[None, :] > jj[:, None]
    near &= ~np.any(later & (v_at < -sm.tau), axis=1)
    sm.report["extrema_within_margin"] = int(near.sum())
    return where[near], si[near], np.full(int(near.sum()), -1)


def _fold_starts(sm: Sampled, folds: Folds | None) -> list[_Starts]:
    """Doubtful folds (nearly tangent, or another dyad within ``tau`` across the fold's cell):
    at the fold itself (its dyad flat), and where another dyad comes closest to collinear in
    the fold's cell."""
    if folds is None:
        sm.report["doubtful_folds"] = 0
        return []
    rows = np.arange(len(folds.sheet))
    tangent = folds.slope <= np.sqrt(sm.tau)
    cell_nu = folds.cell_nu.copy()
    cell_nu[rows, :, folds.dyad] = np.inf  # the fold's own dyad
    others = cell_nu.min(axis=2)  # (F, cells)
    crowded = (others <= sm.tau).any(axis=1)
    doubtful = tangent | crowded
    sm.report["doubtful_folds"] = int(doubtful.sum())
    at = np.argmin(others, axis=1)
    inner = crowded & (at > 0)
    return [(folds.star[doubtful], folds.sheet[doubtful], folds.dyad[doubtful]),
            (folds.cell[rows, at][inner], folds.sheet[inner], np.full(int(inner.sum()), -1))]


def _configurations(
    linkage: Linkage, ch: Chain, sm: Sampled, tol: Tolerances, theta: np.ndarray,
    sheet: np.ndarray, flat_dyad: np.ndarray, free: np.ndarray,
) -> np.ndarray:
    """The free coordinates (n, M) of the starts, with the points of a coincident dyad's
    circle where its centres coincide."""
    flat = np.zeros((len(theta), ch.k), bool)
    flat[np.flatnonzero(flat_dyad >= 0), flat_dyad[flat_dyad >= 0]] = True
    pos, _, dd = place(ch, theta, sm.sheets[sheet], flat)
    # A dyad whose centres coincide (at an isolated angle: nu_j, a product with d^2, has a
    # double zero there) leaves its vertex free on a circle, every point of which has the two
    # bars on one line. A self-stress on the pair (+w, -w) puts opposite forces +-w e on the
    # two centres (e the unit vector from them to the vertex); it is balanced by the rest
    # exactly when e is orthogonal to the centres' relative velocity d(a - b)/d theta: the two
    # points of the circle at +-90 degrees from it are the candidates there.
    coincide = dd <= (SAME_POINT_REL * sm.scale) ** 2
    u_parts = [pos[~coincide.any(axis=1)][:, free]]
    ci, cj = np.nonzero(coincide)
    if len(ci):
        u_parts += _coincident_starts(linkage, ch, sm, tol, theta[ci], sm.sheets[sheet[ci]],
                                      cj, pos[np.arange(len(ci)), ch.a[cj]], free)
    u = np.concatenate(u_parts)
    if not np.all(np.isfinite(u)):
        raise Decline("non-finite candidate")
    return u


def _coincident_starts(
    linkage: Linkage, ch: Chain, sm: Sampled, tol: Tolerances, theta: np.ndarray,
    signs: np.ndarray, cj: np.ndarray, centre: np.ndarray, free: np.ndarray,
) -> list[np.ndarray]:
    """Starts where dyad ``cj`` has its centres coincide at ``theta`` (on sheets ``signs``):
    the two points of its circle at +-90 degrees from the centres' relative velocity, and the
    candidates of the later dyads along the circle (:func:`_circle_candidates`)."""
    if np.any(np.abs(ch.ra[cj] - ch.rb[cj]) > SAME_POINT_REL * sm.scale):
        raise Decline("a dyad's centres coincide where its radii differ")
    h = 1e-6
    n = np.arange(len(cj))
    pp, _, _ = place(ch, theta + h, signs)
    pm, _, _ = place(ch, theta - h, signs)
    rel = (pp[n, ch.a[cj]] - pp[n, ch.b[cj]]) - (pm[n, ch.a[cj]] - pm[n, ch.b[cj]])
    out: list[np.ndarray] = []
    for turn in (0.5 * np.pi, -0.5 * np.pi):
        psi = np.arctan2(rel[:, 1], rel[:, 0]) + turn
        for j in np.unique(cj):
            sel = cj == j
            vtx = centre[sel] + ch.ra[j] * np.column_stack([np.cos(psi[sel]), np.sin(psi[sel])])
            pc, _, _ = place(ch, theta[sel], signs[sel], None, {int(j): vtx})
            out.append(pc[:, free])
    # Along the circle the later dyads move with the vertex: where one of them is collinear
    # as well (a double zero of its nu along the circle, or a fold along it where the
    # rigidity matrix is singular) there may be critical points too.
    ends = linkage.ends[linkage.active]
    seen: list[tuple[int, tuple[int, ...], float]] = []
    for r in range(len(cj)):
        # sheets that differ only in this dyad's own root give the same circle
        key_signs = tuple(int(x) for i, x in enumerate(signs[r]) if i != int(cj[r]))
        t0 = float(theta[r])
        if any(j0 == int(cj[r]) and s0 == key_signs and abs(t1 - t0) <= 1e-6
               for j0, s0, t1 in seen):
            continue
        seen.append((int(cj[r]), key_signs, t0))
        out += _circle_candidates(ch, t0, signs[r], int(cj[r]), centre[r], sm.tau, sm.scale,
                                  free, ends, tol)
    return out


def _distinct(u: np.ndarray, scale: float) -> np.ndarray:
    """The starts once each (the same start found on several sheets: a collinear dyad's two
    roots coincide); too many is a non-isolated critical set, left to the general search."""
    keep: list[int] = []
    for i in range(len(u)):
        if not keep or np.min(np.linalg.norm(u[keep] - u[i], axis=1)) > SAME_POINT_REL * scale:
            keep.append(i)
            if len(keep) > MAX_CANDIDATES:
                raise Decline(f"more than {MAX_CANDIDATES} candidates for critical points "
                              "(a non-isolated critical set?)")
    return u[keep]


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
    if np.any(prefix & (d2 <= (SAME_POINT_REL * scale) ** 2)):
        raise Decline("centres coincide twice (on the circle of a dyad's vertex)")
    out: list[np.ndarray] = []
    ext = discrete_extrema(nu, prefix, axis=0)
    prev_ok, next_ok = ext.prev_ok, ext.next_ok
    ii, jj = np.nonzero(prefix & (ext.mask | (nu == 0)))
    if len(ii):
        sgn = np.where(nu[ii, jj] >= 0, 1.0, -1.0)
        lo = grid[ii] - np.where(prev_ok[ii, jj], dps, 0.0)
        hi = grid[ii] + np.where(next_ok[ii, jj], dps, 0.0)

        def signed_nu(t: np.ndarray) -> np.ndarray:
            _, v, _ = at(t)
            return sgn * v[np.arange(len(t)), jj]

        extreme, where = golden_arg(signed_nu, lo, hi, iters=40)
        near = extreme <= tau
        if near.any():
            p, _, dd = at(where[near])
            jn = jj[near]
            nested = dd[np.arange(len(jn)), jn] <= (SAME_POINT_REL * scale) ** 2
            out.append(p[~nested][:, free])
            # a later dyad's centres coincide too (its vertex on a circle of its own): the same
            # rule, with the motion along this circle; deeper nesting declines
            for r in np.flatnonzero(nested):
                i = int(jn[r])
                if i != k - 1 or abs(ch.ra[i] - ch.rb[i]) > SAME_POINT_REL * scale:
                    raise Decline("centres coincide twice (on the circle of a dyad's vertex)")
                h = 1e-6
                pp, _, _ = at(where[near][r:r + 1] + h)
                pm, _, _ = at(where[near][r:r + 1] - h)
                rel = (pp[0, ch.a[i]] - pp[0, ch.b[i]]) - (pm[0, ch.a[i]] - pm[0, ch.b[i]])
                for turn in (0.5 * np.pi, -0.5 * np.pi):
                    phi = np.arctan2(rel[1], rel[0]) + turn
                    vtx = p[r, ch.a[i]] + ch.ra[i] * np.array([np.cos(phi), np.sin(phi)])
                    pc, _, _ = at(where[near][r:r + 1], None, {i: vtx[None, :]})
                    out.append(pc[:, free])
    return out + _circle_folds(at, grid, dps, pos_nu, k, free, ends, tol)


def _circle_folds(
    at: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]], grid: np.ndarray,
    dps: float, pos_nu: np.ndarray, k: int, free: np.ndarray, ends: np.ndarray,
    tol: Tolerances,
) -> list[np.ndarray]:
    """Folds of the later dyads along the circle (``at(psi, flat)`` places the chain there):
    ``J`` decides at the fold point itself (a gap between ``rank_rtol`` and ``1e-3``
    declines)."""
    n = len(grid)
    out: list[np.ndarray] = []
    valid = np.all(pos_nu, axis=1)
    up = np.flatnonzero(valid & ~np.roll(valid, 1))
    down = np.flatnonzero(valid & ~np.roll(valid, -1))
    ein = np.concatenate([up, down]).astype(int)
    edir = np.concatenate([-np.ones(len(up), int), np.ones(len(down), int)])
    if len(ein):
        jf = np.argmax(~pos_nu[(ein + edir) % n], axis=1)
        lo = bisect_folds(lambda t: at(t)[1], grid[ein], grid[ein] + edir * dps, jf)
        rows = np.arange(len(ein))
        flat = np.zeros((len(ein), k), bool)
        flat[rows, jf] = True
        p, _, _ = at(lo, flat)
        for f in range(len(ein)):
            g = _gap(p[f], ends, free)
            if g <= 1e3 * tol.rank_rtol:
                out.append(p[f][None, free])
            elif g < 1e-3:
                raise Decline("a fold on the circle of a dyad's vertex is nearly singular")
    return out
