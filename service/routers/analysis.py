from typing import Annotated

from fastapi import APIRouter, Depends

from engine.constraints import on_constraints
from engine.rigidity import first_order
from engine.second_order import second_order
from service import mappers
from service.config import Settings, get_settings
from service.errors import PROBLEM_JSON
from service.schemas.analysis import RigidityResponse, SecondOrderResponse
from service.schemas.common import AnalysisRequest, Problem

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
