"""The path of hinged rotor chains in 3D (:mod:`engine.space.hinge_chain`): answers derived
from the chain's cells.

* No cell turns in its outer angle (:func:`engine.space.hinge_chain.hinge_count`): every
  component is a graph over ``theta_0``, sampled in closed form in one vectorised pass
  (:func:`sheet_answer`), ``2^(n-1)`` of them and no critical point.
* Otherwise (:func:`gather`): the critical candidates and the seeds of
  :func:`engine.space.hinge_chain.derive`, handed to the critical-point search (as starts) and
  the tracer (as seeds); :func:`argument` says ``derived`` when every candidate within the
  certain margin refined to a critical point, every critical point found is a candidate and
  (for the components) every seed lies on a traced curve or at a critical point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from engine.local.critical import CriticalPoint, NearMiss
from engine.model.budget import ARGUMENT_DERIVED, Argument, granted
from engine.model.linkage import Linkage
from engine.model.report import SearchReport, count_text
from engine.space.chain_count import ChainCount
from engine.space.configuration_space.closed_form import walk_curve, walk_distance
from engine.space.configuration_space.critical_search import critical_points
from engine.space.configuration_space.explorer import Explorer
from engine.space.configuration_space.results import Component, SpaceResult
from engine.space.hinge_chain import CERTAIN_RTOL, Derivation, HingeChain, derive, hinge_chain
from engine.space.hinge_sheets import angles_of, sheet_of, sheets
from engine.space.trace import Curve

#: A candidate or seed is at a found critical point within this (relative to the median bar).
AT_CRITICAL_REL = 1e-3
#: Samples of ``theta_0`` of the first pass over the sheets (their arc length).
SHEET_SAMPLES = 512
#: Spacing of a sheet's samples, as a share of the step bound (arc length of the first pass).
SHEET_SPACING = 0.8


def _coordinates(linkage: Linkage, chain: HingeChain, theta: np.ndarray) -> np.ndarray:
    """Free coordinates (K, M) of angle rows (K, n)."""
    pos = np.empty((len(theta), *linkage.positions.shape))
    pos[:] = linkage.positions
    pos[:, chain.tips] = chain.points(theta)
    return pos[:, ~linkage.fixed]


def _walks(ex: Explorer, chain: HingeChain, bits: np.ndarray) -> list[np.ndarray] | None:
    """Closed walks (K + 1, M) of the sheets ``bits``, consecutive points within the step
    bound (samples of ``theta_0`` spaced by arc length from a first uniform pass, refined
    where a gap is still too long); None where a sheet does not exist everywhere or would
    pass the point budget."""
    theta0 = np.linspace(-np.pi, np.pi, SHEET_SAMPLES, endpoint=False)
    rows = sheets(chain, bits, theta0)
    if not np.isfinite(rows).all():
        return None
    walks = []
    for k, r in enumerate(rows):
        u = _coordinates(ex.linkage, chain, r)
        length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(
            np.diff(np.vstack([u, u[:1]]), axis=0), axis=1))])
        count = int(np.ceil(length[-1] / (SHEET_SPACING * ex.h_max)))
        t = np.interp(np.linspace(0.0, length[-1], count, endpoint=False), length,
                      np.append(theta0, np.pi))
        for _ in range(8):  # halve the gaps still too long
            u = _coordinates(ex.linkage, chain, sheets(chain, bits[k:k + 1], t)[0])
            gap = np.linalg.norm(np.diff(np.vstack([u, u[:1]]), axis=0), axis=1)
            if not np.isfinite(u).all() or len(t) > ex.opt.trace.max_points or \
                    ex.out_of_time():
                return None
            if gap.max() <= ex.h_max:
                break
            after = np.append(t[1:], t[0] + 2 * np.pi)
            t = np.sort(np.concatenate([t, 0.5 * (t + after)[gap > ex.h_max]]))
        else:
            return None
        walks.append(np.vstack([u, u[:1]]))
    return walks


def sheet_answer(ex: Explorer, count: ChainCount, start: np.ndarray | None,
                 near_misses: bool) -> SpaceResult | None:
    """The answer of :func:`engine.space.configuration_space.explore` for a hinged chain
    counted by :func:`engine.space.hinge_chain.hinge_count`: its sheets in closed form (the one
    through ``start`` first, then in branch order up to ``max_components``), or None (the
    general path runs)."""
    chain = hinge_chain(ex.linkage)
    if chain is None or count.components == 0:
        return None
    n, opt = chain.n, ex.opt
    shown = min(opt.max_components, count.components)
    first = None
    if start is not None:
        free = np.zeros_like(ex.linkage.positions, dtype=float)
        free[:] = ex.linkage.positions
        free[~ex.linkage.fixed] = start
        first = int(sheet_of(chain, angles_of(chain, free[chain.tips])) @ (1 << np.arange(n - 1)))
    order = [first] if first is not None else []
    order += [s for s in range(min(count.components, shown + 1)) if s != first][:shown - len(order)]
    bits = (np.array(order)[:, None] >> np.arange(n - 1)) & 1
    walks = _walks(ex, chain, bits)
    allowed = ex.values_in_time()
    if walks is None or (allowed is not None
                         and sum(len(w) for w in walks) * ex.linkage.n_vertices > allowed):
        ex.report["hinge_chain"] = "declined: the sheets need more points than the budget"
        return None
    misses: list[NearMiss] = []
    report: dict[str, object] = {
        "method": "closed form", "closed_form": "used: 3D hinged rotor chain",
        "closed_form_samples": len(walks[0]) - 1, "curves_traced": 0,
        "component_budget_reached": shown < count.components, "open_curves": 0,
        "components_total": count.components, "components_total_rule": count.rule}
    if near_misses:  # (those of the sheet through the start: no other has more to say)
        ex.curves = [walk_curve(ex.cons, w) for w in walks[:1]]
        ex._rebuild_tree()
        crit, misses, degenerate = critical_points(ex)
        if crit or degenerate:  # the rule is contradicted: never a confident answer
            ex.curves, ex.tree = [], None
            ex.report["hinge_chain"] = "declined: the critical-point search found one"
            return None
        report["critical_candidates"] = ex.report.get("critical_candidates", 0)
    dist = [walk_distance(w, start, ex.h_max) for w in walks] if start is not None else []
    components = [Component(w, True, bool(dist) and k == 0 and dist[0] <= ex.h_max, [], [])
                  for k, w in enumerate(walks)]
    report.update({"critical_points_found": 0, "segments_complete": True,
                   "step_max": ex.h_max, "strain_tol": opt.trace.strain_tol})
    detail = (f"{count.rule}: {count_text(count.components)} components and no critical "
              f"point; {len(walks)} sampled in closed form")
    search = SearchReport(report, timed_out=ex.timed_out, budget=shown < count.components,
                          time_budget_s=granted(ex.deadline), argument=ARGUMENT_DERIVED,
                          argument_detail=detail)
    search = search.with_details(proved={  # (the rule counts what the budget may not show)
        "critical_points": {"count": 0, "exact": True},
        "components": {"count": count.components, "exact": True}})
    return SpaceResult(components, [], [], misses, search, False)


@dataclass(frozen=True)
class HingeProof:
    """The derivation of a hinged chain and its rows as free coordinates: ``seeds`` (K, M),
    ``candidates`` (C, M) with their relative ``|b_j|`` ``margins`` (C,)."""

    derivation: Derivation
    seeds: np.ndarray
    candidates: np.ndarray
    margins: np.ndarray


def gather(ex: Explorer, seeds: bool = True) -> HingeProof | None:
    """The derivation of ``ex``'s hinged chain (None: not one), bounded by the deadline;
    ``seeds`` False: the critical candidates alone. ``report["hinge_chain"]`` says what was
    done."""
    chain = hinge_chain(ex.linkage)
    if chain is None:
        return None
    d = derive(chain, ex.deadline, seeds=seeds)
    ex.report["hinge_chain"] = {**d.counts, "degenerate": d.degenerate, "stopped": d.stopped}
    return HingeProof(d, _coordinates(ex.linkage, chain, d.seeds),
                      _coordinates(ex.linkage, chain, d.candidates), d.margins)


def _near(points: np.ndarray, found: np.ndarray, scale: float) -> np.ndarray:
    """Which of ``points`` (K, M) lie at one of ``found`` (F, M)."""
    if not len(points) or not len(found):
        return np.zeros(len(points), dtype=bool)
    dist = np.linalg.norm(points[:, None, :] - found[None], axis=2).min(axis=1)
    return dist <= AT_CRITICAL_REL * scale


def argument(ex: Explorer, proof: HingeProof, crit: list[CriticalPoint],
             components: bool = True) -> tuple[Argument | None, str | None]:
    """``derived`` with its sentence, or ``(None, why not)``: ``components`` False for the
    critical-point search (the seeds are not needed)."""
    d = proof.derivation
    if d.degenerate is not None:
        return None, f"3D hinged chain: degenerate: {d.degenerate}"
    if not d.critical_done or (components and not d.seeds_done):
        return None, f"3D hinged chain: not derived: {d.stopped}"
    why = []
    at = np.array([c.u for c in crit]).reshape(-1, ex.cons.n_free)
    certain = proof.candidates[proof.margins <= CERTAIN_RTOL]
    if (lost := int((~_near(certain, at, ex.scale)).sum())):
        why.append(f"{lost} candidates with b_j = 0 refined to no critical point")
    if (extra := int((~_near(at, proof.candidates, ex.scale)).sum())):
        why.append(f"{extra} critical points found off the candidates")
    if components:
        seeds = proof.seeds[~_near(proof.seeds, at, ex.scale)]
        if (off := sum(not ex.on_traced(u) for u in seeds)):
            why.append(f"{off} seeds lie on no traced curve")
    if why:
        return None, "3D hinged chain: " + "; ".join(why)
    c = d.counts
    text = (f"3D hinged chain of {d.chain.n} rotors: every critical point is on a run of cells "
            f"from a fold a_i = 0 to b_j = 0; {c.get('critical_candidates', 0)} such runs "
            f"walked in closed form refined to the {len(crit)} critical points")
    if components:
        text += (f"; a point on every component: the fibre theta_0 = {d.fibre_angle:.4f} "
                 f"({c.get('fibre', 0)} points) and every fold b_k = 0 completed through the "
                 f"chain ({c.get('turning', 0)} points), all on the {len(ex.curves)} traced "
                 "curves or at a critical point")
    return ARGUMENT_DERIVED, text


def drop_open_through_critical(ex: Explorer, crit: list[CriticalPoint]) -> int:
    """Drop the open curves (stopped by a budget) that pass within the step bound of a
    critical point: traced through a branch point they may wander on past it, but the
    segments from that point reach their whole component (the components are assembled from
    those segments, not from such curves). Returns how many were dropped, and recounts
    ``report["open_curves"]``."""
    if not crit:
        return 0
    at = np.array([c.u for c in crit])
    keep = [c for c in ex.curves if c.stop == "closed" or np.linalg.norm(
        c.array("points")[:, None, :] - at[None], axis=2).min() > ex.h_max]
    dropped = len(ex.curves) - len(keep)
    if dropped:
        ex.curves = keep
        ex._rebuild_tree()
        ex.report["open_curves"] = sum(c.stop != "closed" for c in keep)
        ex.report["open_curves_through_critical"] = dropped
    return dropped


def off_components(ex: Explorer, traced: list[Curve], components: list[Component]) -> int:
    """Traced curves with a point farther than the step bound from every point of the
    assembled components: a part of the space the answer would leave out (the segments
    through a branch point missed a loop), so the answer is not complete."""
    pts = [c.points for c in components if len(c.points)]
    if not traced:
        return 0
    if not pts:
        return len(traced)
    tree = cKDTree(np.vstack(pts))
    return sum(bool((tree.query(c.array("points"))[0] > ex.h_max).any()) for c in traced)
