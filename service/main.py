"""ASGI app: ``service.main:app``."""

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool

from engine import __version__
from engine.space import trace_kernel
from engine.space.dyads import kernel as dyads_kernel
from service import docs, errors
from service.config import Settings, get_settings
from service.metrics import Metrics
from service.middleware import RequestContext
from service.routers import analysis, design, figures, health, jobs, presets
from service.tasks import JobManager
from service.workers import EnginePool, tune_malloc

VIEWER = Path(__file__).parent / "viewer"


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application (one per process; tests may build their own with ``settings``,
    which then replace the environment's everywhere in this app).

    Heavy engine work runs in a pool of worker processes owned by the app: started at
    start-up under a server (or on first use without one) and, at shutdown, closed after the
    requests in flight have been answered."""
    resolved = settings or get_settings()
    metrics = Metrics()
    pool = EnginePool(resolved.workers, resolved.max_queue, on_event=metrics.engine_event,
                      memory_mb=resolved.worker_memory)
    job_manager = JobManager(resolved)  # its Dask cluster starts with the first job

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # The tracer's compiled kernel: compiled here once where numba's cache is cold (20-30 s
        # on the first start after an install), so that the workers load it from the cache.
        await run_in_threadpool(trace_kernel.prepare)
        await run_in_threadpool(dyads_kernel.prepare)  # the closed form's loops, likewise
        # the service process reads and sends the workers' answers: megabytes per request
        tune_malloc()
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
        docs_url=None,  # /docs and /redoc are served offline by service.docs
        redoc_url=None,
    )
    app.state.engine_pool = pool
    app.state.metrics = metrics
    app.state.jobs = job_manager
    if settings is not None:
        app.dependency_overrides[get_settings] = lambda: settings
    errors.install(app)
    docs.install(app)
    app.add_middleware(RequestContext, metrics=metrics)
    app.include_router(health.router)
    app.include_router(presets.router)
    app.include_router(analysis.router)
    app.include_router(design.router)
    app.include_router(jobs.router)
    app.include_router(figures.router)
    # The web viewer: static files shipped in the package, calling the public endpoints only.
    app.mount("/viewer", StaticFiles(directory=VIEWER, html=True), name="viewer")
    if resolved.cors_origins:  # outermost, so that a preflight is answered before anything
        app.add_middleware(CORSMiddleware, allow_origins=list(resolved.cors_origins),
                           allow_methods=["GET", "POST", "DELETE"], allow_headers=["*"],
                           expose_headers=["Location", "Retry-After", "X-Request-ID"])
    return app


app = create_app()
