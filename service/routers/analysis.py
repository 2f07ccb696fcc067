
from fastapi import APIRouter, Request, Response

from service import jobs
from service.bodies import JsonBodyRoute
from service.config import SettingsDep
from service.errors import problem_responses
from service.schemas.analysis import RigidityResponse, SecondOrderResponse
from service.schemas.common import AnalysisRequest
from service.schemas.critical_values import CriticalValuesRequest, CriticalValuesResponse
from service.schemas.robustness import RobustnessRequest, RobustnessResponse
from service.schemas.space import CriticalPointsResponse, SpaceRequest, SpaceResponse
from service.schemas.splitting import SplittingRequest, SplittingResponse
from service.workers import engine_call

router = APIRouter(prefix="/v1/analysis", tags=["analysis"], route_class=JsonBodyRoute)
_problems = problem_responses(400, 408, 413, 415, 422, 503, 504)


@router.post(
    "/rigidity", operation_id="analyseRigidity",
    response_model=RigidityResponse, responses=_problems,
)
async def rigidity(
    body: AnalysisRequest, request: Request, settings: SettingsDep
) -> Response:
    """First-order analysis: rank, zero modes, self-stresses, trivial motions, tangent form."""
    return await engine_call(request, settings, jobs.rigidity, body, light=jobs.is_light(body),
                             inline=jobs.is_inline(body))


@router.post(
    "/second-order", operation_id="analyseSecondOrder",
    response_model=SecondOrderResponse, responses=_problems,
)
async def second_order_analysis(
    body: AnalysisRequest, request: Request, settings: SettingsDep
) -> Response:
    """Second-order analysis: regular, branch (with branch tangents), rigid or degenerate."""
    light = jobs.is_light(body, second_order=True)
    return await engine_call(request, settings, jobs.second_order_analysis, body, light=light)


@router.post(
    "/critical-points", operation_id="findCriticalPoints",
    response_model=CriticalPointsResponse, responses=_problems
)
async def critical_points(
    body: SpaceRequest, request: Request, settings: SettingsDep
) -> Response:
    """Every critical point for the given lengths (or the closest approaches when none)."""
    return await engine_call(request, settings, jobs.critical_points, body)


@router.post(
    "/configuration-space", operation_id="exploreConfigurationSpace",
    response_model=SpaceResponse, responses=_problems
)
async def configuration_space(
    body: SpaceRequest, request: Request, settings: SettingsDep
) -> Response:
    """Every component of a one-degree-of-freedom linkage, traced; at critical lengths also the
    segments between critical points."""
    return await engine_call(request, settings, jobs.configuration_space, body)


@router.post(
    "/splitting", operation_id="predictSplitting",
    response_model=SplittingResponse, responses=_problems,
)
async def splitting(
    body: SplittingRequest, request: Request, settings: SettingsDep
) -> Response:
    """How each branch point splits under the length change ``perturbation`` (Appendix A)."""
    return await engine_call(request, settings, jobs.splitting, body)


@router.post(
    "/robustness", operation_id="computeRobustnessMargin",
    response_model=RobustnessResponse, responses=_problems,
)
async def robustness_margin(
    body: RobustnessRequest, request: Request, settings: SettingsDep
) -> Response:
    """Smallest change of the adjustable lengths (Euclidean norm) that reaches a critical value:
    the fabrication tolerance of a design."""
    return await engine_call(request, settings, jobs.robustness_margin, body)


@router.post(
    "/critical-values", operation_id="mapCriticalValues",
    response_model=CriticalValuesResponse, responses=_problems
)
async def critical_values(
    body: CriticalValuesRequest, request: Request, settings: SettingsDep
) -> Response:
    """The slice of the critical value set in two lengths over a box, and one sample point per
    region with its number of components and a topology signature."""
    return await engine_call(request, settings, jobs.critical_values, body)
