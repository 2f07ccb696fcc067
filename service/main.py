"""ASGI app: ``service.main:app``."""

# The engine workers' forkserver imports the engine while this process imports the rest
# (service.forkserver): on two cores, start-up takes the longer of the two, not their sum.
from service import forkserver

forkserver.start()

import asyncio
import logging
import time
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI
from fastapi.middleware.cors import CORSMiddleware
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool

from engine import __version__
from service import docs, errors
from service.config import Settings, get_settings
from service.metrics import Metrics
from service.middleware import RequestContext
from service.routers import analysis, design, figures, health, jobs, presets
from service.tasks import JobManager
from service.workers import EnginePool, tune_malloc

VIEWER = Path(__file__).parent / "viewer"
#: uvicorn's own logger (configured by uvicorn at INFO): start-up steps appear beside its lines.
log = logging.getLogger("uvicorn.error")


async def _start(pool: EnginePool) -> None:
    """Start the engine workers, saying so in the log.

    The workers' forkserver imports the engine and loads the compiled kernels once
    (:mod:`service.warm`; compiled there where numba's cache is cold: 20-30 s on an idle machine
    after an install, 78 s on a loaded 2-core one; the Docker image compiles them at build
    time), and every worker is forked from it with them loaded. The service process itself
    loads no kernel: its small requests (first and second order) trace nothing, nor the
    figures (drawn in the workers) nor Dask (loaded by the first job)."""
    t0 = time.perf_counter()
    try:
        log.info("start-up: starting %d engine workers (their forkserver imports the engine "
                 "and loads the compiled kernels, compiled now if numba's cache is cold); "
                 "/health/live answers, /health/ready will when they have started; figures "
                 "load in the workers, Dask with the first job",
                 pool.workers)
        # the service process reads and sends the workers' answers: megabytes per request
        tune_malloc()
        await run_in_threadpool(pool.start)
        log.info("start-up: ready in %.1f s (%d engine workers)", time.perf_counter() - t0,
                 pool.workers)
    except Exception:  # /health/ready stays 503: the orchestrator restarts the container
        log.exception("start-up failed after %.1f s", time.perf_counter() - t0)


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application (one per process; tests may build their own with ``settings``,
    which then replace the environment's everywhere in this app).

    Heavy engine work runs in a pool of worker processes owned by the app: started in the
    background at start-up under a server (or on first use without one) and, at shutdown,
    closed after the requests in flight have been answered."""
    resolved = settings or get_settings()
    metrics = Metrics()
    pool = EnginePool(resolved.workers, resolved.max_queue, on_event=metrics.engine_event,
                      memory_mb=resolved.worker_memory)
    job_manager = JobManager(resolved)  # its Dask cluster starts with the first job

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # The port opens at once (/health/live answers); the kernels and the workers load in
        # the background and /health/ready answers 200 when they have.
        startup = asyncio.create_task(_start(pool))
        app.state.startup = startup
        try:
            yield
        finally:
            if not startup.done():
                log.info("start-up interrupted: waiting for the current step to end")
            await asyncio.gather(startup, return_exceptions=True)
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
