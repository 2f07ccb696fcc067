
from fastapi import APIRouter, Request, Response

from service import jobs
from service.bodies import JsonBodyRoute
from service.config import SettingsDep
from service.errors import problem_responses
from service.schemas.design import DesignRequest, DesignResponse
from service.workers import engine_call

router = APIRouter(prefix="/v1/design", tags=["design"], route_class=JsonBodyRoute)


_problems = problem_responses(400, 408, 413, 415, 422, 503, 504)


@router.post(
    "/splitting", operation_id="designSplitting",
    response_model=DesignResponse, responses=_problems,
)
async def design_splitting(
    body: DesignRequest, request: Request, settings: SettingsDep
) -> Response:
    """Smallest largest change of the adjustable bars that splits the targeted branch points
    with the requested signs; every feasible answer is verified by re-tracing."""
    return await engine_call(request, settings, jobs.design_splitting, body)
