"""The work behind each analysis endpoint: request model in, response model out.

Each function runs either in a worker process or, for small first- and second-order requests,
in the service's thread pool (see :mod:`service.workers`), so each is a plain module-level
function of picklable arguments. Engine errors raised here travel back unchanged and become
problem+json in :mod:`service.errors`.
"""

from __future__ import annotations

from dataclasses import replace

from engine.design.critical_values import critical_value_slice
from engine.design.design import Target, check_request, design, verify
from engine.design.robustness import robustness
from engine.design.splitting import length_change, split
from engine.design.surface_design import MARGIN_REL, check_targets, design_surface
from engine.design.surface_splitting import split_surface
from engine.local.rigidity import first_order, plan_first_order
from engine.local.second_order import second_order
from engine.model.budget import Deadline, answer_values
from engine.model.constraints import Constraints, ProjectionResult, on_constraints
from engine.model.errors import InvalidRequest
from engine.model.linkage import Linkage as EngineLinkage
from engine.model.tolerances import Tolerances
from engine.space.configuration_space import explore, find_critical_points
from engine.space.surfaces.explore import explore_surfaces
from service import answers, mappers
from service.config import Settings
from service.schemas.analysis import RigidityResponse, SecondOrderResponse
from service.schemas.common import AnalysisRequest, Linkage
from service.schemas.critical_values import (
    CriticalValuesOptions,
    CriticalValuesRequest,
    CriticalValuesResponse,
)
from service.schemas.design import DesignRequest, DesignResponse
from service.schemas.robustness import RobustnessRequest, RobustnessResponse
from service.schemas.space import (
    CriticalPointOut,
    CriticalPointsResponse,
    SpaceOptions,
    SpaceRequest,
    SpaceResponse,
)
from service.schemas.splitting import SplittingRequest, SplittingResponse
from service.workers import (
    INLINE_MAX_BARS,
    INLINE_MAX_VERTICES,
    LIGHT_MAX_NUMBERS,
    LIGHT_SECOND_ORDER_MAX_PRODUCT,
)


def free_coordinates(linkage: Linkage) -> int:
    """``M``, the linkage's free coordinates, from the request alone (a pinned vertex has none,
    a slider those of its free axes); a ``fixed`` the engine will refuse counts as given."""
    d = linkage.dimension
    return sum(d if v.fixed is False else 0 if v.fixed is True else
               sum(not axis for axis in v.fixed) for v in linkage.vertices)


def is_light(body: AnalysisRequest, second_order: bool = False) -> bool:
    """The request's worst cost, estimated from its sizes before any work, is small enough for
    the service's own process (``M`` free coordinates, ``E`` bars): at most
    ``LIGHT_MAX_NUMBERS`` numbers of zero modes and self-stresses (``M^2 + E^2``), and for
    ``second_order`` a prestress SDP of at most ``LIGHT_SECOND_ORDER_MAX_PRODUCT`` (``M E``).
    Anything larger goes to the engine workers, whatever it turns out to cost."""
    m, e = free_coordinates(body.linkage), len(body.linkage.bars)
    if m * m + e * e > LIGHT_MAX_NUMBERS:
        return False
    return not second_order or m * e <= LIGHT_SECOND_ORDER_MAX_PRODUCT


def is_inline(body: AnalysisRequest) -> bool:
    """First order of a tiny linkage (at most ``INLINE_MAX_VERTICES`` vertices and
    ``INLINE_MAX_BARS`` bars: about a millisecond), answered on the event loop itself."""
    return (len(body.linkage.vertices) <= INLINE_MAX_VERTICES
            and len(body.linkage.bars) <= INLINE_MAX_BARS)


def rigidity(body: AnalysisRequest, settings: Settings) -> RigidityResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    plan_first_order(linkage)  # the engine's own limits first: they name the method's bounds
    answers.check_first_order(linkage, settings)
    at, proj = on_constraints(linkage, tol)
    rig = first_order(at, tol, deadline=analysis_deadline(settings))
    answers.check_null_spaces(rig.zero_modes, rig.self_stresses, settings)
    return mappers.rigidity_out(at, rig, proj)


def second_order_analysis(body: AnalysisRequest, settings: Settings) -> SecondOrderResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    at, proj = on_constraints(linkage, tol)
    res = second_order(at, tol, deadline=analysis_deadline(settings))
    answers.check_null_spaces(res.rigidity.zero_modes, res.rigidity.self_stresses, settings)
    return mappers.second_order_out(at, res, proj)


#: Share of the request's time limit an analysis without a search (rigidity, second order) may
#: take: the rest is for the unit of work that runs past it (one block of the sparse null
#: space's completion: up to 4 s on a 20,000-rotor chain, loaded machine) and the answer; one
#: that would run past it stops with a 422 (``too-costly``) instead of the 504 at the limit.
ANALYSIS_SHARE = 0.5


def analysis_deadline(settings: Settings) -> Deadline:
    """The deadline of an analysis without a search: ``ANALYSIS_SHARE`` of the request's time
    limit, counted from the request's arrival."""
    seconds = ANALYSIS_SHARE * settings.time_limit_s
    if settings.arrived_at is not None:
        return Deadline(settings.arrived_at + seconds, budget_s=seconds)
    return Deadline.after(seconds)


def search_deadline(
    options: SpaceOptions | CriticalValuesOptions | None, settings: Settings,
    given: Deadline | None,
) -> Deadline:
    """The deadline of a search: a job's own (its time limit, progress and cancel flag), else
    ``options.time_budget_s`` or the default search time, within the request's time limit (the
    engine reports the seconds granted as ``search.time_budget_s``)."""
    if given is not None:
        return given
    seconds = settings.search_seconds(options.time_budget_s if options is not None else None)
    if settings.arrived_at is not None:  # counted from the request's arrival
        return Deadline(settings.arrived_at + seconds, budget_s=seconds)
    return Deadline.after(seconds)


def critical_points(
    body: SpaceRequest, settings: Settings, deadline: Deadline | None = None
) -> CriticalPointsResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    dl = search_deadline(body.options, settings, deadline)
    at, proj = on_constraints(linkage, tol)
    # The answer holds no components or segments: only the search for critical points runs.
    res = find_critical_points(at, tol, mappers.space_options_in(body.options), deadline=dl)
    answers.check_critical(at, len(res.critical_points), len(res.near_misses), settings)
    return mappers.critical_points_out(at, res, proj, tol)


def configuration_space(
    body: SpaceRequest, settings: Settings, deadline: Deadline | None = None
) -> SpaceResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    dl = search_deadline(body.options, settings, deadline)
    at, proj = on_constraints(linkage, tol)
    if at.n_free - int(at.active.sum()) == 2 and at.anything_fixed:
        return _surfaces(body, settings, at, proj, tol, dl)
    # the response carries no near misses: where the closed form certifies, or the rotor-chain
    # rules prove, that there is no critical point, the critical-point search is skipped
    # the search stops at the values (points x vertices) mapped in time past the deadline
    opt = replace(mappers.space_options_in(body.options), max_values=answer_values(dl))
    res = explore(at, tol, opt, near_misses=False, deadline=dl)
    points = sum(len(c.points) for c in res.components)
    if points > settings.max_points:
        raise InvalidRequest(
            f"the answer would hold {points} points, more than LINKAGE_MAX_POINTS = "
            f"{settings.max_points}: raise options.step_max or lower options.max_components",
            loc=("options",),
        )
    compact = body.options is not None and body.options.points == "compact"
    answers.check_points(at, points, len(res.critical_points), compact, settings)
    return mappers.space_out(at, res, proj, tol,
                             points=body.options.points if body.options else None)


#: Mesh vertices per triangle of a closed surface (``V = F / 2 + chi``), with a margin.
VERTICES_PER_TRIANGLE = 0.55


def _surfaces(body: SpaceRequest, settings: Settings, at: EngineLinkage, proj: ProjectionResult,
              tol: Tolerances, dl: Deadline) -> SpaceResponse:
    """Two degrees of freedom: the surfaces, after an estimate of the answer's size from the
    triangle budget (a 422 naming ``options`` before any work where it is too large)."""
    opt = mappers.surface_options_in(body.options)
    vertices = int(VERTICES_PER_TRIANGLE * opt.max_triangles) + 7
    numbers = vertices * at.n_vertices * at.dimension + 3 * opt.max_triangles
    if vertices > settings.max_points \
            or numbers * answers.ANSWER_BYTES_PER_NUMBER > settings.max_answer_mb * 2**20:
        raise InvalidRequest(
            f"the surfaces could hold {vertices:,} mesh vertices ({numbers:,} numbers) within "
            f"options.max_triangles = {opt.max_triangles}, more than LINKAGE_MAX_POINTS = "
            f"{settings.max_points} or LINKAGE_MAX_ANSWER_MB = {settings.max_answer_mb}: "
            "lower options.max_triangles", loc=("options",))
    res = explore_surfaces(at, tol, opt, deadline=dl)
    return mappers.surfaces_out(at, res, proj, tol,
                                points=body.options.points if body.options else None)


def splitting(
    body: SplittingRequest, settings: Settings, deadline: Deadline | None = None
) -> SplittingResponse:
    return splitting_with_points(body, settings, deadline)[0]


def splitting_with_points(
    body: SplittingRequest, settings: Settings, deadline: Deadline | None = None
) -> tuple[SplittingResponse, list[CriticalPointOut]]:
    """The splitting answer and the critical points behind it (with Q's eigenvalues and
    tangents, which the splitting figure draws)."""
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    dl = search_deadline(body.options, settings, deadline)
    at, _ = on_constraints(linkage, tol)
    d_l = length_change(at, body.perturbation)
    if at.n_free - Constraints(at).n_constraints == 2:
        res = split_surface(at, d_l, tol, mappers.surface_options_in(body.options), dl)
        return mappers.surface_splitting_out(at, res, tol), []
    found = find_critical_points(at, tol, mappers.space_options_in(body.options), deadline=dl)
    crit = found.critical_points
    splits = [split(at, k, cp, d_l) for k, cp in enumerate(crit) if cp.kind == "branch"]
    return (mappers.splitting_out(at, splits, len(crit), tol, crit, found.search),
            mappers.critical_list_out(at, crit))


def robustness_margin(
    body: RobustnessRequest, settings: Settings, deadline: Deadline | None = None
) -> RobustnessResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    dl = search_deadline(body.options, settings, deadline)
    at, _ = on_constraints(linkage, tol)
    adjustable, method = mappers.robustness_in(body)
    res = robustness(at, adjustable, tol, mappers.space_options_in(body.options),
                     method=method, deadline=dl)
    return mappers.robustness_out(at, res, tol)


def critical_values(
    body: CriticalValuesRequest, settings: Settings, deadline: Deadline | None = None
) -> CriticalValuesResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    dl = search_deadline(body.options, settings, deadline)
    at, _ = on_constraints(linkage, tol)
    axes, opts = mappers.critical_values_in(body)
    res = critical_value_slice(at, axes, tolerances=tol, deadline=dl, **opts)
    answers.check_slice(sum(len(c) for c in res.curves), len(res.regions), settings)
    return mappers.critical_values_out(res, tol)


def design_splitting(
    body: DesignRequest, settings: Settings, deadline: Deadline | None = None
) -> DesignResponse:
    linkage, tol = mappers.problem_in(body.linkage, body.tolerances, settings.limits)
    cons = Constraints(linkage)
    if cons.n_free - cons.n_constraints == 2:
        return _design_surface(body, settings, linkage, tol, deadline)
    for k, t in enumerate(body.targets):
        if t.sheets is not None:
            raise InvalidRequest("sheets are for two degrees of freedom (M - E = 2); give "
                                 "sign", loc=("targets", k, "sheets"))
    targets, adjustable = mappers.design_in(body)
    check_request(linkage, targets, adjustable)  # before the costly exploration
    dl = search_deadline(body.options, settings, deadline)
    at, _ = on_constraints(linkage, tol)
    found = find_critical_points(at, tol, mappers.space_options_in(body.options), deadline=dl)
    crit = found.critical_points
    margin = mappers.design_margin(body, at)
    result = design(at, crit, targets, adjustable, margin, body.max_change)
    checks = verify(at, crit, targets, result.perturbation, tol, deadline=dl) \
        if result.feasible else []
    return mappers.design_out(at, result, adjustable, checks, tol, found.search)


def _design_surface(body: DesignRequest, settings: Settings, linkage: EngineLinkage,
                    tol: Tolerances, deadline: Deadline | None) -> DesignResponse:
    """Two degrees of freedom: resolve the target cones as asked, checked by re-meshing."""
    targets, adjustable = mappers.cone_targets_in(body), list(body.adjustable)
    check_targets(targets)
    check_request(linkage, [Target(t.cone, 1) for t in targets], adjustable)
    dl = search_deadline(body.options, settings, deadline)
    at, _ = on_constraints(linkage, tol)
    res = design_surface(at, targets, adjustable, mappers.design_margin(body, at, MARGIN_REL),
                         body.max_change, tol, mappers.surface_options_in(body.options), dl)
    return mappers.surface_design_out(at, res, adjustable, tol)
