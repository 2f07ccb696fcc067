"""The two searches: :func:`explore` (components, critical points, segments) and
:func:`find_critical_points` (the critical points alone).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

import numpy as np

from engine.local.critical import CriticalPoint, NearMiss
from engine.model.budget import (
    NEVER,
    Deadline,
)
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.chain_count import exact_components, gate_decision, gated_chain
from engine.space.configuration_space.closed_form import (
    NO_CANDIDATE,
    closed_form_answer,
    closed_form_critical,
)
from engine.space.configuration_space.critical_search import critical_points, resolve
from engine.space.configuration_space.explorer import Explorer
from engine.space.configuration_space.proof import (
    Proof,
    argument,
    count_text,
    gather,
    proved_so_far,
)
from engine.space.configuration_space.results import (
    CriticalSearch,
    SpaceOptions,
    SpaceResult,
)
from engine.space.configuration_space.segments import (
    assemble_components,
    mark_through_start,
    trace_segments,
)


def find_critical_points(
    linkage: Linkage,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    start_on_space: bool = True,
    deadline: Deadline | None = None,
) -> CriticalSearch:
    """Critical points and near misses of a 1-DOF linkage, as :func:`explore` finds them,
    without building the segments and components.

    The critical points come from the traced curves (sign changes and deep minima of the
    augmented determinant, closest approaches) and the multistart, exactly as in
    :func:`explore`; the segments only connect critical points already found (a ray traced
    from a branch point crosses any other critical point on its way and goes on to a known
    one), so they add nothing to the search: its ``complete`` here is that of the curves
    (component budget, assemblies, no open curve) and of the classification (not degenerate).

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> res = find_critical_points(build_preset("four-bar", {"L2": 1.0}))
    >>> len(res.critical_points), res.search["complete"]
    (3, True)
    """
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions()
    # The chain rules prove that there is no critical point (engine.space.chain_count): for a
    # gated chain as for a plain one, since with the chain driven from the gate rotor a
    # self-stress vanishes tip by tip inwards to the gate's tip, where it is left on the gate
    # four-bar P_g T_g R G (G held by the slider's transversal meeting with the circle of
    # radius D: a pin for the stress), which carries one only when flat, and its lengths are
    # generic; driven from another rotor, only where |T_g - G| is stationary at an end of the
    # gate's range, which the rule's transversal crossings exclude (engine.space.gate_transfer).
    # The curves then serve only the near misses, and the components a budget would
    # trace are an arbitrary few of 2^(n-1) (a 100-rotor chain: 32 of 2^99, the whole default
    # budget): the near misses are those of the component the linkage is on.
    count = exact_components(linkage)
    sample = start_on_space and count is not None
    ex = Explorer(linkage, tol, opt, deadline or NEVER)
    start = linkage.coordinates() if start_on_space else None
    if opt.closed_form and opt.critical_closed_form:
        fast = closed_form_critical(ex)
        if fast is not None:
            return _with_found(fast)
        if opt.near_misses_closed_form and ex.report.get("closed_form") == NO_CANDIDATE:
            # certified: no critical point; the near misses from the closed form's walks (as
            # explore finds them), instead of tracing the curves
            space = closed_form_answer(ex, start, near_misses=True)
            if space is not None:
                return _with_found(CriticalSearch([], space.near_misses, space.search, False))
    if opt.critical_closed_form:
        ex.report["method"] = "tracer"
        ex.report.setdefault("closed_form", "off")
    proof = gather(ex) if count is None else None
    if sample:  # (the closed form above samples every sheet: it needs no such choice)
        ex.opt = replace(opt, max_components=1)
    # (no seed traced from a rigid critical point: an isolated point of the space, where the
    # tracer crawled around rounding, 12 open curves and 1.3 s at a skew four-bar's)
    ex.trace_all(start, isolated=_seeds_and_isolated(ex, proof)[1])
    if sample and count is not None:
        ex.report["near_misses_from"] = (
            f"the component through the given configuration: the chain rules ({count.rule}) "
            f"prove that none of the {count_text(count.components)} components has a "
            "critical point")
    extra = proof.critical_starts if proof is not None else None
    crit, misses, degenerate = critical_points(ex, extra)
    _gate_details(ex.report, linkage)
    search = ex.finish(degenerate, argument=argument(ex, proof, crit, count, components=False),
                       curves_needed=False, critical_points_found=len(crit), step_max=ex.h_max,
                       strain_tol=opt.trace.strain_tol)
    search = search.with_details(proved=proved_so_far(ex, proof, crit, count, degenerate,
                                               search.complete))
    return CriticalSearch(crit, misses if not crit else [], search, degenerate)


R = TypeVar("R", SpaceResult, CriticalSearch)


def _with_found(res: R) -> R:
    """A closed form's answer with its ``proved`` claims: what it found, exactly where it is
    complete (the closed form's certificate), else at least (see :func:`proved_so_far`)."""
    exact = bool(res.search.complete)
    found: dict[str, dict[str, object]] = {
        "critical_points": {"count": len(res.critical_points), "exact": exact}}
    if isinstance(res, SpaceResult):
        total = res.search.get("components_total")  # (the chain rules' count: exact)
        found["components"] = ({"count": len(res.components), "exact": exact} if total is None
                               else {"count": total, "exact": True})
    return replace(res, search=res.search.with_details(proved=found))


def _gate_details(report: dict[str, object], linkage: Linkage) -> None:
    """For a chain with the paper's gate: ``gated`` (no rotor completes a turn on any
    component), decided from the gate four-bar and the chain's cells whatever was traced
    (:func:`engine.space.chain_count.gate_decision`), or None, and ``gated_reason``."""
    if gated_chain(linkage) is None:
        return
    decision = gate_decision(linkage)
    report["gated"] = decision.gated
    report["gated_reason"] = decision.reason


def _seeds_and_isolated(ex: Explorer, proof: Proof | None
                        ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The proof's seeds, and the rigid critical points among its singular solutions (refined
    before tracing: no seed is traced from an isolated point)."""
    if proof is None:
        return None, None
    rigid = None
    if len(proof.critical_starts):
        found, _, _, _ = resolve(ex, list(proof.critical_starts))
        rigid = np.array([c.u for c in found if c.kind == "rigid"]).reshape(-1, ex.cons.n_free)
    return proof.seeds, rigid


def explore(
    linkage: Linkage,
    tolerances: Tolerances | None = None,
    options: SpaceOptions | None = None,
    start_on_space: bool = True,
    near_misses: bool = True,
    deadline: Deadline | None = None,
) -> SpaceResult:
    """Components, critical points, segments and near misses of a 1-DOF linkage (on its
    configuration space: see :func:`engine.model.constraints.on_constraints`).

    ``near_misses=False`` says the caller does not need the near misses: where the closed form
    of :mod:`engine.space.dyads` certifies that no critical point exists, or the rules of
    :mod:`engine.space.chain_count` prove it for a rotor chain, the critical-point search (which
    finds the near misses, and would find no critical point) is then skipped.

    Examples
    --------
    >>> from engine.catalogue.presets import build_preset
    >>> res = explore(build_preset("four-bar", {"L2": 1.2}))
    >>> len(res.components), len(res.critical_points)
    (1, 0)
    """
    tol = tolerances or Tolerances()
    opt = options or SpaceOptions()
    ex = Explorer(linkage, tol, opt, deadline or NEVER)
    # With start_on_space=False the given positions need not satisfy the lengths (e.g. lengths
    # changed for a map): only the seeds are used, and none means an empty configuration space.
    start = linkage.coordinates() if start_on_space else None
    # -- closed-form path (engine.space.dyads); None: not a dyad chain, or at/near critical lengths
    # --
    if opt.closed_form:
        fast = closed_form_answer(ex, start, near_misses)
        if fast is not None:
            return _with_found(fast)
    # -- general path ---------------------------------------------------------------------
    ex.report.setdefault("method", "tracer")
    ex.report.setdefault("closed_form", "off")
    count = exact_components(linkage)
    proof = gather(ex) if count is None else None
    ex.trace_all(start, *_seeds_and_isolated(ex, proof))
    if count is not None and not near_misses:
        # The chain rules prove that there is no critical point (engine.space.chain_count): the
        # search would only find near misses, which the caller does not want. On long chains
        # it is most of the cost (dense refinements on 2n unknowns).
        crit: list[CriticalPoint] = []
        misses: list[NearMiss] = []
        degenerate = False
        ex.report["critical_search"] = f"skipped: {count.rule} proves no critical point"
    else:
        crit, misses, degenerate = critical_points(
            ex, proof.critical_starts if proof is not None else None)
    # Segments need every critical point classified; with a degenerate one the traced curves
    # themselves are the answer (they may pass through critical points).
    segs, seg_complete = trace_segments(ex, crit) if not degenerate else ([], False)
    components = assemble_components(ex, crit, segs, degenerate)
    mark_through_start(components, start, ex.h_max)
    agreed = True
    if count is not None:
        # the true total for rotor chains (four-bar decomposition), also when the budget of
        # traced components is far below it (a 100-rotor spinner chain has 2^99)
        ex.report["components_total"] = count.components
        ex.report["components_total_rule"] = count.rule
        # (a search cut by its budget or deadline says so itself)
        agreed = ex.timed_out or bool(ex.report.get("component_budget_reached")) \
            or ex.size_reached() or len(components) == count.components
        if not agreed:  # a second method disagrees: never a confident count (unresolved)
            ex.report["components_disagree"] = (
                f"traced {len(components)} components, {count.rule} gives "
                f"{count_text(count.components)}")
    why = argument(ex, proof, crit, count, len(components))
    _gate_details(ex.report, linkage)
    search = ex.finish(degenerate, seg_complete, agreed, why,
                       seeds_needed=count is None or why[0] is None,
                       critical_points_found=len(crit),
                       segments_complete=seg_complete, step_max=ex.h_max,
                       strain_tol=opt.trace.strain_tol)
    search = search.with_details(proved=proved_so_far(ex, proof, crit, count, degenerate,
                                               search.complete, len(components), agreed))
    return SpaceResult(components, crit, segs, misses if not crit else [], search, degenerate)
