from typing import Annotated

from fastapi import APIRouter, Depends

from engine.configuration_space import explore
from engine.constraints import on_constraints
from engine.critical_values import critical_value_slice
from engine.errors import InvalidRequest
from engine.rigidity import first_order
from engine.robustness import robustness
from engine.second_order import second_order
from engine.splitting import length_change, split
from service import mappers
from service.config import Settings, get_settings
from service.errors import PROBLEM_JSON
from service.schemas.analysis import RigidityResponse, SecondOrderResponse
from service.schemas.common import AnalysisRequest, Problem
from service.schemas.space import (
    CriticalPointsResponse,
    CriticalValuesRequest,
    CriticalValuesResponse,
    RobustnessRequest,
    RobustnessResponse,
    SpaceRequest,
    SpaceResponse,
    SplittingRequest,
    SplittingResponse,
)

router = APIRouter(prefix="/v1/analysis", tags=["analysis"])
_problems = {422: {"model": Problem, "content": {PROBLEM_JSON: {}}}}
SettingsDep = Annotated[Settings, Depends(get_settings)]


@router.post("/rigidity", response_model=RigidityResponse, responses=_problems)  # type: ignore[arg-type]
def rigidity(body: AnalysisRequest, settings: SettingsDep) -> RigidityResponse:
    """First-order analysis: rank, zero modes, self-stresses, trivial motions, tangent form."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, proj = on_constraints(linkage, tol)
    return mappers.rigidity_out(at, first_order(at, tol), proj)


@router.post("/second-order", response_model=SecondOrderResponse, responses=_problems)  # type: ignore[arg-type]
def second_order_analysis(body: AnalysisRequest, settings: SettingsDep) -> SecondOrderResponse:
    """Second-order analysis: regular, branch (with branch tangents), rigid or degenerate."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, proj = on_constraints(linkage, tol)
    return mappers.second_order_out(at, second_order(at, tol), proj)


@router.post(
    "/critical-points", response_model=CriticalPointsResponse, responses=_problems  # type: ignore[arg-type]
)
def critical_points(body: SpaceRequest, settings: SettingsDep) -> CriticalPointsResponse:
    """Every critical point for the given lengths (or the closest approaches when none)."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, proj = on_constraints(linkage, tol)
    res = explore(at, tol, mappers.space_options_in(body.options))
    return mappers.critical_points_out(at, res, proj, tol)


@router.post(
    "/configuration-space", response_model=SpaceResponse, responses=_problems  # type: ignore[arg-type]
)
def configuration_space(body: SpaceRequest, settings: SettingsDep) -> SpaceResponse:
    """Every component of a one-degree-of-freedom linkage, traced; at critical lengths also the
    segments between critical points."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, proj = on_constraints(linkage, tol)
    res = explore(at, tol, mappers.space_options_in(body.options))
    points = sum(len(c.points) for c in res.components)
    if points > settings.max_points:
        raise InvalidRequest(
            f"the answer would hold {points} points, more than LINKAGE_MAX_POINTS = "
            f"{settings.max_points}: raise options.step_max or lower options.max_components",
            loc=("options",),
        )
    return mappers.space_out(at, res, proj, tol)


@router.post("/splitting", response_model=SplittingResponse, responses=_problems)  # type: ignore[arg-type]
def splitting(body: SplittingRequest, settings: SettingsDep) -> SplittingResponse:
    """How each branch point splits under the length change ``perturbation`` (Appendix A)."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, _ = on_constraints(linkage, tol)
    d_l = length_change(at, body.perturbation)
    crit = explore(at, tol, mappers.space_options_in(body.options)).critical_points
    splits = [split(at, k, cp, d_l) for k, cp in enumerate(crit) if cp.kind == "branch"]
    return mappers.splitting_out(at, splits, len(crit), tol, crit)


@router.post("/robustness", response_model=RobustnessResponse, responses=_problems)  # type: ignore[arg-type]
def robustness_margin(body: RobustnessRequest, settings: SettingsDep) -> RobustnessResponse:
    """Smallest change of the adjustable lengths (Euclidean norm) that reaches a critical value:
    the fabrication tolerance of a design."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, _ = on_constraints(linkage, tol)
    adjustable = None if body.adjustable is None else list(body.adjustable)
    res = robustness(at, adjustable, tol, mappers.space_options_in(body.options))
    return mappers.robustness_out(at, res, tol)


@router.post(
    "/critical-values", response_model=CriticalValuesResponse, responses=_problems  # type: ignore[arg-type]
)
def critical_values(body: CriticalValuesRequest, settings: SettingsDep) -> CriticalValuesResponse:
    """The slice of the critical value set in two lengths over a box, and one sample point per
    region with its number of components and a topology signature."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, _ = on_constraints(linkage, tol)
    opts = body.options.model_dump(exclude_none=True) if body.options else {}
    axes = [(a.bar, a.min, a.max) for a in body.axes]
    return mappers.critical_values_out(critical_value_slice(at, axes, tolerances=tol, **opts), tol)
