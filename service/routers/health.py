from fastapi import APIRouter

from engine import __version__
from service.schemas.presets import Health

router = APIRouter(tags=["health"])


@router.get("/health", response_model=Health)
def health() -> Health:
    """Liveness: answers without touching the engine."""
    return Health(status="ok", version=__version__)
