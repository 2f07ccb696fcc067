from typing import Annotated

import numpy as np
from fastapi import APIRouter, Depends

from engine.configuration_space import explore
from engine.constraints import on_constraints
from engine.design import Target, design, verify
from service import mappers
from service.config import Settings, get_settings
from service.errors import PROBLEM_JSON
from service.schemas.common import Problem
from service.schemas.space import DesignRequest, DesignResponse

router = APIRouter(prefix="/v1/design", tags=["design"])
_problems = {422: {"model": Problem, "content": {PROBLEM_JSON: {}}}}


@router.post("/splitting", response_model=DesignResponse, responses=_problems)  # type: ignore[arg-type]
def design_splitting(
    body: DesignRequest, settings: Annotated[Settings, Depends(get_settings)]
) -> DesignResponse:
    """Smallest largest change of the adjustable bars that splits the targeted branch points
    with the requested signs; every feasible answer is verified by re-tracing."""
    linkage = mappers.linkage_in(body.linkage, settings.limits)
    tol = mappers.tolerances_in(body.tolerances)
    at, _ = on_constraints(linkage, tol)
    crit = explore(at, tol, mappers.space_options_in(body.options)).critical_points
    targets = [Target(t.branch_point, t.sign) for t in body.targets]
    margin = body.margin or 1e-4 * float(np.median(at.lengths[at.active]))
    result = design(at, crit, targets, list(body.adjustable), margin, body.max_change)
    checks = verify(at, crit, targets, result.perturbation, tol) if result.feasible else []
    return mappers.design_out(at, result, list(body.adjustable), checks, tol)
