"""ASGI app: ``service.main:app``."""

from fastapi import FastAPI

from engine import __version__
from service import errors
from service.config import Settings, get_settings
from service.middleware import RequestContext
from service.routers import analysis, design, health, presets


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application (one per process; tests may build their own). ``settings``
    overrides the environment for the middleware (request handlers take theirs from the
    ``get_settings`` dependency)."""
    app = FastAPI(
        title="Linkage topology service",
        version=__version__,
        description="Configuration-space topology of bar-and-joint linkages: first- and "
        "second-order analysis at a configuration, presets from the paper. Errors are "
        "application/problem+json (RFC 9457).",
    )
    errors.install(app)
    app.add_middleware(RequestContext, settings=(lambda: settings) if settings else get_settings)
    app.include_router(health.router)
    app.include_router(presets.router)
    app.include_router(analysis.router)
    app.include_router(design.router)
    return app


app = create_app()
