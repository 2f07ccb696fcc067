"""ASGI app: ``service.main:app``."""

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from starlette.concurrency import run_in_threadpool

from engine import __version__
from service import errors
from service.config import Settings, get_settings
from service.metrics import Metrics
from service.middleware import RequestContext
from service.routers import analysis, design, health, jobs, presets
from service.tasks import JobManager
from service.workers import EnginePool


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application (one per process; tests may build their own with ``settings``,
    which then replace the environment's everywhere in this app).

    Heavy engine work runs in a pool of worker processes owned by the app: started at
    start-up under a server (or on first use without one) and, at shutdown, closed after the
    requests in flight have been answered."""
    resolved = settings or get_settings()
    metrics = Metrics()
    pool = EnginePool(resolved.workers, resolved.max_queue, on_event=metrics.engine_event)
    job_manager = JobManager(resolved)  # its Dask cluster starts with the first job

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await run_in_threadpool(pool.start)
        try:
            yield
        finally:
            await run_in_threadpool(job_manager.close)
            await run_in_threadpool(pool.close)

    app = FastAPI(
        title="Linkage topology service",
        version=__version__,
        description="Configuration-space topology of bar-and-joint linkages: first- and "
        "second-order analysis at a configuration, presets from the paper. Errors are "
        "application/problem+json (RFC 9457).",
        lifespan=lifespan,
    )
    app.state.engine_pool = pool
    app.state.metrics = metrics
    app.state.jobs = job_manager
    if settings is not None:
        app.dependency_overrides[get_settings] = lambda: settings
    errors.install(app)
    app.add_middleware(RequestContext, settings=(lambda: settings) if settings else get_settings,
                       metrics=metrics)
    app.include_router(health.router)
    app.include_router(presets.router)
    app.include_router(analysis.router)
    app.include_router(design.router)
    app.include_router(jobs.router)
    return app


app = create_app()
