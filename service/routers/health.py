from fastapi import APIRouter, Request, Response

from engine import __version__
from service.metrics import CONTENT_TYPE_LATEST, Metrics
from service.schemas.presets import Health

router = APIRouter(tags=["health"])


@router.get("/health", operation_id="getHealth", response_model=Health)
async def health() -> Health:
    """Liveness: answers on the event loop without touching the engine, so it stays prompt
    while every worker is busy."""
    return Health(status="ok", version=__version__)


@router.get(
    "/metrics", operation_id="getMetrics",
    response_class=Response,
    responses={200: {"content": {CONTENT_TYPE_LATEST: {}}, "description": "Prometheus text"}},
)
async def metrics(request: Request) -> Response:
    """Prometheus metrics in the text exposition format: request counts by route and status,
    latency histograms, requests in flight, and engine time-limit hits, worker failures and
    refusals when busy."""
    registry: Metrics = request.app.state.metrics
    return Response(registry.exposition(), media_type=CONTENT_TYPE_LATEST)
