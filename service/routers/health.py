"""Health (liveness and readiness) and metrics: answered on the event loop without touching
the engine, so they stay prompt while every worker is busy."""

from fastapi import APIRouter, Request, Response

from engine import __version__
from service.errors import problem, problem_responses
from service.metrics import CONTENT_TYPE_LATEST, Metrics
from service.schemas.presets import Health, Readiness
from service.workers import EnginePool

router = APIRouter(tags=["health"])


@router.get("/health", operation_id="getHealth", response_model=Health)
async def health() -> Health:
    """Liveness (as `/health/live`): the process answers."""
    return Health(status="ok", version=__version__)


@router.get("/health/live", operation_id="getHealthLive", response_model=Health)
async def live() -> Health:
    """Liveness: the event loop answers (from the moment the port is open). A failure means
    the process should be restarted (Kubernetes' `livenessProbe`, Docker's `HEALTHCHECK`)."""
    return Health(status="ok", version=__version__)


@router.get("/health/ready", operation_id="getHealthReady", response_model=Readiness,
            responses=problem_responses(503))
async def ready(request: Request) -> Response | Readiness:
    """Readiness: the compiled kernels are loaded and the engine workers have started and
    are not broken (a pool whose worker died while idle is replaced within a second; until
    then this is a 503 with `Retry-After`). Kubernetes' `readinessProbe`."""
    pool: EnginePool = request.app.state.engine_pool
    if pool.ready:
        return Readiness(status="ready", version=__version__, workers=len(pool.worker_pids()))
    if pool.broken or (pool.replacements and pool.starting):
        detail = "an engine worker died and the worker pool is being replaced"
    else:
        detail = "starting: the compiled kernels and the engine workers are not loaded yet"
    return problem(503, "not-ready", "Not ready", detail, headers={"retry-after": "1"})


@router.get(
    "/metrics", operation_id="getMetrics",
    response_class=Response,
    responses={200: {"content": {CONTENT_TYPE_LATEST: {}}, "description": "Prometheus text"}},
)
async def metrics(request: Request) -> Response:
    """Prometheus metrics in the text exposition format: request counts by route and status,
    latency histograms, requests in flight, and engine time-limit hits, worker failures, pool
    replacements and refusals when busy."""
    registry: Metrics = request.app.state.metrics
    return Response(registry.exposition(), media_type=CONTENT_TYPE_LATEST)
