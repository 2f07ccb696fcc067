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
    Argument,
    Deadline,
)
from engine.model.linkage import Linkage
from engine.model.tolerances import Tolerances
from engine.space.chain_count import ChainCount, gate_decision, gated_chain
from engine.space.configuration_space.closed_form import (
    NO_CANDIDATE,
    closed_form_answer,
    closed_form_critical,
)
from engine.space.configuration_space.critical_search import critical_points, resolve
from engine.space.configuration_space.explorer import Explorer
from engine.space.configuration_space.hinge import (
    HingeProof,
    drop_open_through_critical,
    off_components,
    sheet_answer,
)
from engine.space.configuration_space.hinge import argument as hinge_argument
from engine.space.configuration_space.hinge import gather as hinge_gather
from engine.space.configuration_space.proof import (
    Proof,
    argument,
    count_text,
    gather,
    proved_so_far,
)
from engine.space.configuration_space.results import (
    Component,
    CriticalSearch,
    SpaceOptions,
    SpaceResult,
)
from engine.space.configuration_space.segments import (
    assemble_components,
    mark_through_start,
    trace_segments,
)
from engine.space.gated_count import exact_components
from engine.space.hinge_sheets import HINGE_RULE, hinge_count
from engine.space.trace import Curve


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
    count = _count(linkage, opt)
    ex = Explorer(linkage, tol, opt, deadline or NEVER)
    # a 3D hinged chain: every critical point among the runs walked in closed form
    hinge = hinge_gather(ex, seeds=False) if count is None and opt.closed_form else None
    if hinge is not None and not hinge.derivation.critical_done:
        hinge = None  # (degenerate or cut short: the homotopy's turn, as for any linkage)
    sample = start_on_space and (count is not None or (
        hinge is not None and hinge.derivation.critical_done))
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
    proof = gather(ex) if count is None and hinge is None else None
    if sample:  # (the closed form above samples every sheet: it needs no such choice)
        ex.opt = replace(opt, max_components=1)
    if sample and count is not None and count.rule == HINGE_RULE:
        # (no multistart: the rule proves there is no critical point, and near misses come
        # from the curve through the start; refinements on 3n unknowns are most of the cost;
        # without a start, as for a map's seed lengths, the multistart finds the near misses)
        ex.opt = replace(ex.opt, random_starts=0)
    # (no seed traced from a rigid critical point: an isolated point of the space, where the
    # tracer crawled around rounding, 12 open curves and 1.3 s at a skew four-bar's)
    ex.trace_all(start, isolated=_seeds_and_isolated(
        ex, None if proof is None else proof.seeds,
        None if proof is None else proof.critical_starts)[1])
    if sample and count is not None:
        ex.report["near_misses_from"] = (
            f"the component through the given configuration: the chain rules ({count.rule}) "
            f"prove that none of the {count_text(count.components)} components has a "
            "critical point")
    extra = proof.critical_starts if proof is not None else (
        hinge.candidates if hinge is not None else None)
    crit, misses, degenerate = critical_points(ex, extra)
    _gate_details(ex.report, linkage)
    why = hinge_argument(ex, hinge, crit, components=False) if hinge is not None else \
        argument(ex, proof, crit, count, components=False)
    search = ex.finish(degenerate, argument=why, curves_needed=False,
                       critical_points_found=len(crit), step_max=ex.h_max,
                       strain_tol=opt.trace.strain_tol)
    search = search.with_details(proved=proved_so_far(ex, proof, crit, count, degenerate,
                                               search.complete))
    return CriticalSearch(crit, misses if not crit else [], search, degenerate)


def _count(linkage: Linkage, opt: SpaceOptions) -> ChainCount | None:
    """The chain rules' count: planar rotor chains (:mod:`engine.space.chain_count`) or (with
    ``opt.closed_form``) 3D hinged chains none of whose cells turns
    (:func:`engine.space.hinge_chain.hinge_count`)."""
    return exact_components(linkage) or (hinge_count(linkage) if opt.closed_form else None)


def _hinge_claims(ex: Explorer, hinge: HingeProof | None, crit: list[CriticalPoint],
                  degenerate: bool, proved: dict[str, dict[str, object]]
                  ) -> dict[str, dict[str, object]]:
    """``proved`` with the critical points exact where a hinged chain's runs prove them."""
    if hinge is None or degenerate or hinge_argument(ex, hinge, crit, components=False)[0] \
            is None:
        return proved
    return {**proved, "critical_points": {"count": len(crit), "exact": True}}


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


def _trace(ex: Explorer, start: np.ndarray | None, hinge: HingeProof | None,
           proof: Proof | None) -> None:
    """Trace from the start and the seeds: a hinged chain's alone (they meet every
    component; every critical point skipped as a seed), else a proof's and the sweeps'."""
    if hinge is not None:
        done = hinge.derivation.seeds_done
        ex.trace_all(start, *_seeds_and_isolated(ex, hinge.seeds, hinge.candidates, every=True),
                     sweeps=not done)
    else:
        ex.trace_all(start, *_seeds_and_isolated(
            ex, None if proof is None else proof.seeds,
            None if proof is None else proof.critical_starts))


def _hinge_agrees(ex: Explorer, why: tuple[Argument | None, str | None] | None,
                  traced: list[Curve], components: list[Component]
                  ) -> tuple[tuple[Argument | None, str | None] | None, bool]:
    """A hinged chain's argument and whether the assembled components hold every traced
    curve (False: a second method disagrees, never a confident count)."""
    if why is None or why[0] is None or not (off := off_components(ex, traced, components)):
        return why, True
    why = (None, f"3D hinged chain: {off} traced curves leave the assembled components")
    ex.report["components_disagree"] = why[1]
    return why, False


def _seeds_and_isolated(ex: Explorer, seeds: np.ndarray | None,
                        critical_starts: np.ndarray | None, every: bool = False
                        ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A proof's seeds, and the rigid critical points among its critical starts (``every``:
    all of them), refined before tracing: no seed is traced from an isolated point (nor, with
    ``every``, from a branch point, whose segments reach its component)."""
    if seeds is None:
        return None, None
    rigid = None
    if critical_starts is not None and len(critical_starts):
        found, _, _, _ = resolve(ex, list(critical_starts))
        rigid = np.array([c.u for c in found if every or c.kind == "rigid"]).reshape(
            -1, ex.cons.n_free)
    return seeds, rigid


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
    count = _count(linkage, opt)
    if count is not None and count.rule == HINGE_RULE:
        sheets = sheet_answer(ex, count, start, near_misses)
        if sheets is not None:
            return sheets
    ex.report.setdefault("method", "tracer")
    ex.report.setdefault("closed_form", "off")
    hinge = hinge_gather(ex) if count is None and opt.closed_form else None
    if hinge is not None and not hinge.derivation.critical_done:
        hinge = None  # (degenerate or cut short: the homotopy's turn, as for any linkage)
    # (critical points derived, seeds cut short: the sweeps seed the tracer, and the answer
    # says the critical points are exact, the components at least what was traced)
    proof = gather(ex) if count is None and hinge is None else None
    _trace(ex, start, hinge, proof)
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
            ex, proof.critical_starts if proof is not None else (
                hinge.candidates if hinge is not None else None))
    why = None
    traced = list(ex.curves)
    if hinge is not None:  # (its seeds checked on every traced curve, then the open ones
        why = hinge_argument(ex, hinge, crit)  # through a branch point left to the segments)
        if not degenerate:
            drop_open_through_critical(ex, crit)
    # Segments need every critical point classified; with a degenerate one the traced curves
    # themselves are the answer (they may pass through critical points).
    segs, seg_complete = trace_segments(ex, crit) if not degenerate else ([], False)
    components = assemble_components(ex, crit, segs, degenerate)
    mark_through_start(components, start, ex.h_max)
    why, agreed = _hinge_agrees(ex, why, traced, components)
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
    if why is None:
        why = argument(ex, proof, crit, count, len(components))
    _gate_details(ex.report, linkage)
    search = ex.finish(degenerate, seg_complete, agreed, why,
                       seeds_needed=count is None or why[0] is None,
                       critical_points_found=len(crit),
                       segments_complete=seg_complete, step_max=ex.h_max,
                       strain_tol=opt.trace.strain_tol)
    search = search.with_details(proved=_hinge_claims(ex, hinge, crit, degenerate, proved_so_far(
        ex, proof, crit, count, degenerate, search.complete, len(components), agreed)))
    return SpaceResult(components, crit, segs, misses if not crit else [], search, degenerate)
