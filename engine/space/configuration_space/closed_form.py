"""The closed-form path of planar dyad chains (:mod:`engine.space.dyads`): whole components sampled
in one vectorised pass, or critical points from the closed-form candidates, answered only where
they are beyond doubt.
"""

from __future__ import annotations

import numpy as np

from engine.local.critical import NearMiss
from engine.model.budget import ARGUMENT_DERIVED, granted
from engine.model.constraints import Constraints
from engine.model.report import SearchReport
from engine.model.tolerances import NORM_FLOOR
from engine.space.chain_count import chain_components
from engine.space.configuration_space.critical_search import critical_points, resolve
from engine.space.configuration_space.explorer import Explorer
from engine.space.configuration_space.results import Component, CriticalSearch, SpaceResult
from engine.space.dyads import closed_form_space, critical_candidates
from engine.space.dyads import kernel as dyads_kernel
from engine.space.trace import (
    Curve,
    polyline_distance,
    segments_distance,
)

#: The critical-point search on closed-form walks looks at most this many points per walk
#: (the tracer's own density at the default step bound is far below it).
SEARCH_POINTS = 2000


def walk_curve(cons: Constraints, walk: np.ndarray) -> Curve:
    """A closed walk (n, M; first point repeated) as a traced :class:`Curve`: unit tangents
    along the walk, ``det([t; J])`` signs and ``log|det|``, computed for all points at once.

    The tangent is the generalised cross product of ``J``'s rows, ``c_k = (-1)^k det(J without
    column k)``; then ``det([c; J]) = |c|^2``, so with ``t = o c / |c|`` (``o = +-1`` orienting
    ``t`` along the walk) ``det([t; J]) = o |c|``."""
    pts = walk[:-1]
    stride = max(1, int(np.ceil(len(pts) / SEARCH_POINTS)))
    pts = pts[::stride]
    lk = cons.linkage
    pos = np.empty((len(pts), *lk.positions.shape))
    pos[:] = lk.positions
    pos[:, ~lk.fixed] = pts
    pattern = cons.pattern
    r, c, s, ax = pattern.rows, pattern.cols, pattern.sign, pattern.axes
    bars = cons.linkage.ends[cons.bars]
    diff = pos[:, bars[:, 0]] - pos[:, bars[:, 1]]  # (n, Ea, d)
    jac = np.zeros((len(pts), cons.n_constraints, cons.n_free))
    jac[:, r, c] = 2.0 * s * diff[:, r, ax]
    m = cons.n_free
    cof = np.empty((len(pts), m))
    for k in range(m):  # M small determinants per point, each vectorised over the points
        cols = np.r_[0:k, k + 1:m]
        cof[:, k] = (-1) ** k * np.linalg.det(jac[:, :, cols])
    ahead = np.roll(pts, -1, axis=0) - np.roll(pts, 1, axis=0)
    orient = np.where(np.einsum("ij,ij->i", cof, ahead) >= 0, 1, -1)
    norm = np.linalg.norm(cof, axis=1)
    tangents = orient[:, None] * cof / np.maximum(norm, NORM_FLOOR)[:, None]
    return Curve(points=list(pts), tangents=list(tangents), signs=orient.tolist(),
                 logdets=np.log(np.maximum(norm, NORM_FLOOR)).tolist(), stop="closed")


def walk_distance(walk: np.ndarray, target: np.ndarray, gap: float) -> float:
    """:func:`engine.space.trace.polyline_distance` for a walk (n, M) whose consecutive points are
    at
    most ``gap`` apart (the closed form's step bound), from the segments that can be nearest.

    A point of a segment is within half its length of one of its ends, so no segment whose ends
    are both farther than ``d + gap / 2`` (``d`` the distance to the nearest point, a bound of
    the answer) comes nearer than ``d``: only the others are measured, with the same formula."""
    if len(walk) < 2:
        return polyline_distance(walk, target)
    compiled = dyads_kernel.kernels()
    if compiled is not None:
        seg = np.empty(len(walk) - 1, dtype=np.int64)
        seg = seg[:compiled.near_segments(np.ascontiguousarray(walk, dtype=float),
                                          np.ascontiguousarray(target, dtype=float),
                                          float(gap), seg)]
    else:  # the same arithmetic: squares summed column by column
        d2 = np.zeros(len(walk))
        for c in range(walk.shape[1]):
            d = walk[:, c] - target[c]
            d2 = d * d if c == 0 else d2 + d * d
        reach = (np.sqrt(d2.min()) + 0.5 * gap) * (1.0 + 1e-9)
        near = d2 <= reach * reach
        seg = np.flatnonzero(near[:-1] | near[1:])  # segment k joins points k and k + 1
    return segments_distance(walk[seg], walk[seg + 1], target)


def closed_form_answer(
    ex: Explorer, start: np.ndarray | None, near_misses: bool
) -> SpaceResult | None:
    """The answer of :func:`explore` from :func:`engine.space.dyads.closed_form_space`, or None
    (the general path runs; ``search["closed_form"]`` then says why the closed form declined).

    With ``near_misses`` the usual critical-point search runs on the closed-form walks (for the
    near misses); should it find a critical point the closed form's certificate is contradicted
    and the general path answers instead."""
    lk, opt = ex.linkage, ex.opt
    try:
        cf = closed_form_space(lk, ex.tol, ex.h_max, opt.trace.max_points)
    except (ArithmeticError, ValueError, MemoryError) as exc:  # a safety net: never worse
        ex.report["method"] = "tracer"                          # than the general path
        ex.report["closed_form"] = f"declined: {type(exc).__name__}: {exc}"
        return None
    if cf.components is None:
        ex.report["method"] = "tracer"
        ex.report["closed_form"] = cf.report["closed_form"]
        return None
    walks = cf.components  # free coordinates (n, M)
    allowed = ex.values_in_time()
    values = sum(len(w) + 1 for w in walks) * lk.n_vertices
    if allowed is not None and values > allowed:
        ex.report["method"] = "tracer"  # (which stops at the answer's budget of values)
        ex.report["closed_form"] = (f"declined: {values} values (points x vertices), more "
                                    f"than the {allowed} the time left maps")
        return None
    # distances to the start, once (they order the walks and mark the one through the start)
    dist = [] if start is None else [walk_distance(w, start, ex.h_max) for w in walks]
    if dist:  # as the tracer, which starts there: the given one first (a stable sort)
        order = sorted(range(len(walks)), key=lambda k: dist[k] > ex.h_max)
        walks, dist = [walks[k] for k in order], [dist[k] for k in order]
    truncated = len(walks) > opt.max_components
    walks, dist = walks[: opt.max_components], dist[: opt.max_components]
    report: dict[str, object] = {
        "method": "closed form",
        "closed_form": "used",
        "closed_form_rotor": cf.report["rotor"],
        "closed_form_sheets": cf.report["sheets"],
        "closed_form_folds": cf.report["folds"],
        "closed_form_samples": cf.report["samples"],
        "closed_form_margin": cf.report["margin"],
        "rotor_sweeps": [cf.report["rotor"]],
        "angles_per_rotor": cf.report["samples"],
        "assembly_budget_per_angle": cf.report["sheets"],
        "assemblies_truncated": False,
        "random_starts": 0,
        "random_starts_projected": 0,
        "seeds": 0,
        "curves_traced": 0,
        "component_budget_reached": truncated,
        "open_curves": 0,
    }
    misses: list[NearMiss] = []
    if near_misses:
        ex.curves = [walk_curve(ex.cons, w) for w in walks]
        if ex.curves:
            ex._rebuild_tree()
        crit, misses, degenerate = critical_points(ex)
        if crit or degenerate:
            ex.curves, ex.tree = [], None
            ex.report = {"method": "tracer", "closed_form": "declined: the critical-point "
                         "search found a critical point"}
            return None
        report["critical_multistart"] = ex.report["critical_multistart"]
        report["critical_candidates"] = ex.report["critical_candidates"]
    else:
        report["critical_multistart"] = 0
        report["critical_candidates"] = 0
    # through the start: the nearest walk within h_max (as segments.mark_through_start)
    through = int(np.argmin(dist)) if dist and min(dist) <= ex.h_max else -1
    components = [Component(w, True, k == through, [], []) for k, w in enumerate(walks)]
    count = chain_components(lk)
    if count is not None:  # as in the general path
        report["components_total"] = count.components
        report["components_total_rule"] = count.rule
    report.update({
        "critical_points_found": 0,
        "segments_complete": True,
        "step_max": ex.h_max,
        "strain_tol": opt.trace.strain_tol,
    })
    search = SearchReport(report, timed_out=ex.timed_out, budget=truncated,
                          time_budget_s=granted(ex.deadline), argument=ARGUMENT_DERIVED,
                          argument_detail=CLOSED_FORM_ARGUMENT)
    return SpaceResult(components, [], [], misses, search, False)


#: The argument of a closed-form answer (:mod:`engine.space.dyads`).
CLOSED_FORM_ARGUMENT = (
    "closed form of the planar dyad chain: every sheet sampled over the rotor's whole turn, "
    "with the certificate that no fold or critical point lies between samples")
#: The argument of a critical-point answer from the closed-form candidates.
CANDIDATES_ARGUMENT = (
    "closed form of the planar dyad chain: every place where its certificate is in doubt "
    "(a candidate for a critical point) refined, each to a critical point")

#: ``search["closed_form"]`` of :func:`closed_form_critical` when the closed form certifies that
#: there is no critical point (the near misses then come from the closed-form walks).
NO_CANDIDATE = ("declined: no candidate (no critical point); the near misses come from the "
                "closed-form walks or the general search")


def closed_form_critical(ex: Explorer) -> CriticalSearch | None:
    """:func:`find_critical_points` from the closed-form candidates of
    :func:`engine.space.dyads.critical_candidates`, or None (the general path runs;
    ``search["closed_form"]`` then says why).

    Every candidate is refined, deduplicated and classified as in the general search. The
    answer is given only when it is beyond doubt: at least one candidate, every candidate
    refines to a critical point (a start that does not is a near miss, i.e. lengths near but
    not at critical values, or a failed refinement: the general search decides), and no
    critical point is degenerate (non-isolated sets are merged by the general search). With no
    candidate at all the certificate holds (no critical point) but the near misses come from
    the general search, which then runs."""
    try:
        cc = critical_candidates(ex.linkage, ex.tol)
    except (ArithmeticError, ValueError, MemoryError) as exc:  # a safety net, as in explore
        ex.report["closed_form"] = f"declined: {type(exc).__name__}: {exc}"
        return None
    if cc.points is None:
        ex.report["closed_form"] = cc.report["closed_form"]
        return None
    if not len(cc.points):
        ex.report["closed_form"] = NO_CANDIDATE
        return None
    crit, _, degenerate, failed = resolve(ex, list(cc.points))
    if failed or degenerate or not crit:
        why = (f"{failed} of {len(cc.points)} candidates did not refine to a critical point"
               if failed else "a degenerate critical point" if degenerate
               else "no critical point")
        ex.report["closed_form"] = f"declined: {why}"
        return None
    search: dict[str, object] = {
        "method": "closed-form candidates",
        "closed_form": "used",
        "closed_form_rotor": cc.report["rotor"],
        "closed_form_sheets": cc.report["sheets"],
        "closed_form_samples": cc.report["samples"],
        "closed_form_margin": cc.report["margin"],
        "closed_form_extrema": cc.report.get("extrema_within_margin", 0),
        "closed_form_doubtful_folds": cc.report.get("doubtful_folds", 0),
        "critical_candidates": len(cc.points),
        "critical_multistart": 0,
        "curves_traced": 0,
        "assemblies_truncated": False,
        "component_budget_reached": False,
        "open_curves": 0,
        "critical_points_found": len(crit),
        "step_max": ex.h_max,
        "strain_tol": ex.opt.trace.strain_tol,
    }
    # every sheet of the rotor's whole turn was searched: complete as the general search is
    # when its curves cover the space and no critical point is degenerate, and when the
    # deadline left no candidate unrefined or unclassified
    return CriticalSearch(crit, [], SearchReport(search, timed_out=ex.timed_out,
                                                 time_budget_s=granted(ex.deadline),
                                                 argument=ARGUMENT_DERIVED,
                                                 argument_detail=CANDIDATES_ARGUMENT),
                          False)
