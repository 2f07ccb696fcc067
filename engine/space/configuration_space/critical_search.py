"""Critical points along the traced curves: candidates (sign changes and deep minima of the
augmented determinant, closest approaches, a seeded multistart), refined, deduplicated,
classified and merged where not isolated.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from engine.local import critical_batched
from engine.local.critical import (
    CriticalPoint,
    NearMiss,
    Refined,
    classify,
    refine_critical,
    singular_gap,
)
from engine.model.tolerances import SAME_POINT_REL
from engine.space.assembly import projected_random_starts
from engine.space.configuration_space.explorer import Explorer

#: Above this many free coordinates the critical-point search uses only candidates along the
#: traced curves (no random multistart on the augmented system).
MULTISTART_MAX_FREE = 64


def candidates(ex: Explorer) -> list[np.ndarray]:
    """Starts of the refinement: sign changes and deep minima of ``|det([t; J])|`` along each
    curve, each curve's closest approach, and (small linkages) random projected starts."""
    starts: list[np.ndarray] = []
    for curve in ex.curves:
        pts = curve.array("points")
        signs = curve.array("signs")
        flips = np.flatnonzero(signs[1:] * signs[:-1] < 0)
        starts += [0.5 * (pts[i] + pts[i + 1]) for i in flips]
        logd = curve.array("logdets")
        if len(logd) >= 3:
            deep = np.median(logd) - np.log(30.0)
            mins = np.flatnonzero(
                (logd[1:-1] <= logd[:-2]) & (logd[1:-1] <= logd[2:]) & (logd[1:-1] < deep)
            ) + 1
            starts += [pts[i] for i in mins]
        if len(logd):  # the closest approach of every curve, however shallow
            starts.append(pts[int(np.argmin(logd))])
    # Seeded multistart from random points projected onto the constraints (close to where
    # critical points live); only for small linkages, where it is cheap: larger ones rely on
    # the candidates along the traced curves.
    starts_used = ex.opt.random_starts if ex.cons.n_free <= MULTISTART_MAX_FREE else 0
    rng = np.random.default_rng(ex.opt.seed + 1)
    starts += projected_random_starts(ex.linkage, ex.tol, starts_used, rng, ex.deadline)
    ex.report["critical_multistart"] = starts_used
    return starts


def critical_points(ex: Explorer, extra: np.ndarray | None = None
                    ) -> tuple[list[CriticalPoint], list[NearMiss], bool]:
    """The critical points, near misses and degeneracy found from :func:`candidates` and the
    ``extra`` starts (K, M) (e.g. the singular witness points of a proof)."""
    starts = candidates(ex) + ([] if extra is None else list(extra))
    ex.report["critical_candidates"] = len(starts)
    exact, misses, degenerate, _ = resolve(ex, starts)
    return exact, misses, degenerate


def resolve(
    ex: Explorer, candidates: Iterable[np.ndarray]
) -> tuple[list[CriticalPoint], list[NearMiss], bool, int]:
    """Refine every candidate on the augmented system; deduplicate, classify and merge the
    critical points (near misses only against traced curves): ``(critical points, near
    misses, degenerate, how many candidates did not refine to a critical point)``. Once the
    deadline has passed the candidates left are neither classified nor measured (the search
    is then timed out)."""
    exact: list[CriticalPoint] = []
    misses: list[NearMiss] = []
    failed = 0
    found = list(refined(ex, candidates))
    # the traced point nearest to every start that refined to no critical point, at once
    off = [ref.u for ref in found if not ref.critical]
    nearest = iter(ex.nearest_points(np.array(off)) or []) if off else iter([])
    for ref in found:
        if ex.out_of_time():  # (one classification is a second-order analysis: O(M^3))
            break
        failed += not ref.critical
        if ref.critical:
            if any(np.linalg.norm(ref.u - c.u) <= SAME_POINT_REL * ex.scale for c in exact):
                continue
            analysis = classify(ex.linkage, ref.u, ex.tol)
            exact.append(CriticalPoint(ref.u, analysis, ref.length_residual,
                                       ref.stress_residual))
        elif (point := next(nearest, None)) is not None:
            curve, offset = point
            on = curve.points[offset]
            misses.append(NearMiss(on, singular_gap(ex.cons, on),
                                   float(np.linalg.norm(on - ref.u)),
                                   ref.length_residual, ref.u, ref.sigma))
    exact, degenerate = merge_non_isolated(exact)
    # One canonical order, whichever path found them (closed-form candidates, traced
    # curves, multistart): every endpoint numbers the critical points alike, so a
    # branch_point index from one answer means the same point in another.
    exact.sort(key=lambda c: tuple(np.round(c.u / ex.scale, 5)))
    misses = dedupe_misses(misses, ex.scale)
    return exact, misses, degenerate, failed


def refined(ex: Explorer, candidates: Iterable[np.ndarray]) -> Iterator[Refined]:
    """:func:`engine.local.critical.refine_critical` from every candidate, in order, until the
    deadline: small linkages (up to :data:`engine.local.critical_batched.REFINE_BATCH_MAX_FREE` free
    coordinates) refine all of them at once
    (:func:`engine.local.critical_batched.refine_critical_batch`: the same answers, the tests
    compare
    the two), larger ones one at a time."""
    if ex.cons.n_free > critical_batched.REFINE_BATCH_MAX_FREE:
        for u0 in candidates:
            if ex.out_of_time():
                return
            yield refine_critical(ex.cons, u0, ex.tol)
        return
    starts = [np.asarray(u0, dtype=float) for u0 in candidates]
    if not starts or ex.out_of_time():
        return
    batch = critical_batched.refine_critical_batch(ex.cons, np.array(starts), ex.tol,
                                                   deadline=ex.deadline)
    for ref in batch:
        if ref is None:  # the deadline stopped it before it finished
            ex.timed_out = True
            continue
        yield ref


def merge_non_isolated(points: list[CriticalPoint]) -> tuple[list[CriticalPoint], bool]:
    """Keep isolated critical points; merge points of non-isolated sets into one entry per
    stress support (the set is a continuum: any count of its points would be wrong)."""
    kept: list[CriticalPoint] = []
    supports: set[tuple[int, ...]] = set()
    degenerate = False
    for cp in points:
        reason = cp.analysis.reason or ""
        if cp.kind == "degenerate" and "non-isolated" in reason:
            degenerate = True
            stress = cp.analysis.self_stress
            support = tuple(np.flatnonzero(np.abs(stress) > 1e-6).tolist()) if stress is not None \
                else ()
            if support in supports:
                continue
            supports.add(support)
        elif cp.kind == "degenerate":
            degenerate = True
        kept.append(cp)
    return kept, degenerate


def dedupe_misses(misses: list[NearMiss], scale: float) -> list[NearMiss]:
    misses = sorted(misses, key=lambda m: m.length_gap)
    out: list[NearMiss] = []
    for m in misses:
        if all(np.linalg.norm(m.critical_u - o.critical_u) > 1e-4 * scale for o in out):
            out.append(m)
    return out
