"""Every error leaves the service as ``application/problem+json`` (RFC 9457)."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from engine.model.budget import OutOfTime
from engine.model.errors import (
    EngineError,
    InvalidLinkage,
    InvalidParameter,
    InvalidRequest,
    InvalidTolerance,
    LimitExceeded,
    NoNearbySolution,
    NumericalFailure,
    UnknownPreset,
)
from engine.model.memory import MemoryLimitExceeded
from service.schemas.common import Problem
from service.workers import ServiceFault

PROBLEM_JSON = "application/problem+json"
log = logging.getLogger("service")

# Engine error class -> (status, problem type, title, location prefix in the request)
# (the first class that matches wins: subclasses before their bases)
_ENGINE: dict[type[EngineError], tuple[int, str, str, tuple[str, ...]]] = {
    MemoryLimitExceeded: (422, "memory-limit", "Memory limit exceeded", ("body", "linkage")),
    InvalidLinkage: (422, "invalid-linkage", "Invalid linkage", ("body", "linkage")),
    LimitExceeded: (422, "limit-exceeded", "Linkage too large", ("body", "linkage")),
    NoNearbySolution: (
        422,
        "no-nearby-solution",
        "No configuration near the given positions",
        ("body", "linkage"),
    ),
    InvalidTolerance: (422, "invalid-tolerance", "Invalid tolerance", ("body",)),
    InvalidRequest: (422, "invalid-request", "Invalid request", ("body",)),
    InvalidParameter: (422, "invalid-parameter", "Invalid preset parameter", ("query",)),
    UnknownPreset: (404, "unknown-preset", "Unknown preset", ("path",)),
}


def problem_responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries: these statuses answer with a problem+json body."""
    return {s: {"model": Problem, "content": {PROBLEM_JSON: {}}} for s in statuses}


def problem(
    status: int,
    kind: str,
    title: str,
    detail: str,
    errors: Sequence[dict[str, Any]] = (),
    headers: Mapping[str, str] | None = None,
) -> JSONResponse:
    body = {
        "type": f"/problems/{kind}",
        "title": title,
        "status": status,
        "detail": detail,
        "errors": list(errors),
    }
    return JSONResponse(body, status_code=status, media_type=PROBLEM_JSON, headers=headers)


def _loc_str(loc: Sequence[str | int]) -> str:
    return ".".join(str(p) for p in loc)


async def _validation(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    errors = [
        {"loc": [p if isinstance(p, int) else str(p) for p in e.get("loc", ())], "msg": e["msg"]}
        for e in exc.errors()
    ]
    first = errors[0] if errors else {"loc": [], "msg": "invalid request"}
    detail = f"{_loc_str(first['loc'])}: {first['msg']}"
    if len(errors) > 1:
        detail += f" (and {len(errors) - 1} more)"
    return problem(422, "validation-error", "Request validation failed", detail, errors)


async def _engine(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, EngineError)
    status, kind, title, prefix = next(
        (v for cls, v in _ENGINE.items() if isinstance(exc, cls)),
        (422, "invalid-input", "Invalid input", ("body",)),
    )
    loc = [*prefix, *exc.loc]
    detail = f"{_loc_str(loc)}: {exc.message}"
    if isinstance(exc, MemoryLimitExceeded):
        detail += " (an engine worker's limit is LINKAGE_WORKER_MEMORY_MB)"
    return problem(status, kind, title, detail, [{"loc": loc, "msg": exc.message}])


async def _out_of_memory(request: Request, exc: Exception) -> JSONResponse:
    # in the service's own process (work that runs in a worker is mapped by the pool): the
    # machine is short of memory right now, which may pass
    log.error("out of memory on %s %s: %s", request.method, request.url.path, exc)
    return problem(503, "out-of-memory", "Out of memory",
                   "the service ran out of memory answering this request; retry shortly",
                   headers={"retry-after": "5"})


async def _numerical(request: Request, exc: Exception) -> JSONResponse:
    log.warning("numerical failure on %s: %s", request.url.path, exc)
    return problem(
        422,
        "numerical-failure",
        "No trustworthy answer",
        f"the numerical method could not produce a trustworthy answer for this input: {exc}",
    )


async def _out_of_time(request: Request, exc: Exception) -> JSONResponse:
    # an analysis without a search (rigidity, second order) that would not end before the
    # request's time limit stops before it, with a 422 instead of the 504 at the limit
    loc = ["body", "linkage"]
    msg = (f"the analysis would not finish within the request's time limit "
           f"(LINKAGE_TIME_LIMIT_S): {exc}; ask for a smaller linkage or raise the limit")
    return problem(422, "too-costly", "Analysis too costly for the time limit",
                   f"{_loc_str(loc)}: {msg}", [{"loc": loc, "msg": msg}])


async def _fault(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ServiceFault)
    headers = {"retry-after": str(exc.retry_after)} if exc.retry_after else None
    return problem(exc.status, exc.kind, exc.title, exc.detail, headers=headers)


def _route_methods(routes: Sequence[Any], scope: dict[str, Any]) -> set[str]:
    """The methods of the routes among ``routes`` (and the routers included in them) whose
    path matches ``scope``'s."""
    methods: set[str] = set()
    for route in routes:
        included = getattr(route, "original_router", None)  # FastAPI's include_router
        if included is not None:
            prefix = getattr(getattr(route, "include_context", None), "prefix", "") or ""
            if scope["path"].startswith(prefix):
                methods |= _route_methods(included.routes,
                                          {**scope, "path": scope["path"][len(prefix):]})
            continue
        route_methods = getattr(route, "methods", None)
        if route_methods and route.matches(scope)[0] is not Match.NONE:
            methods |= set(route_methods)
    return methods


def allowed_methods(request: Request) -> list[str]:
    """Every method some route takes at this request's path. Starlette's 405 names only the
    methods of the first route that matches the path, and a path served by several routes
    (``GET`` and ``DELETE /v1/jobs/{job_id}``, ``GET`` and ``POST /v1/jobs``) would list one."""
    scope = {**request.scope, "method": ""}  # no route takes it: a path match is PARTIAL
    return sorted(_route_methods(request.app.router.routes, scope))


async def _http(request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, StarletteHTTPException)
    title = {404: "Not found", 405: "Method not allowed"}.get(exc.status_code, "HTTP error")
    # a 400 is a body the JSON parser refused (undecodable, nested too deep)
    errors = [{"loc": ["body"], "msg": str(exc.detail)}] if exc.status_code == 400 else []
    headers = dict(exc.headers or {})
    if exc.status_code == 405:
        methods = allowed_methods(request)
        if methods:
            headers = {key: value for key, value in headers.items() if key.lower() != "allow"}
            headers["allow"] = ", ".join(methods)
    return problem(exc.status_code, f"http-{exc.status_code}", title, str(exc.detail), errors,
                   headers=headers or None)


async def _unhandled(request: Request, exc: Exception) -> JSONResponse:
    log.exception("unhandled error on %s %s", request.method, request.url.path)
    return problem(500, "internal-error", "Internal error", "the service failed unexpectedly")


def install(app: FastAPI) -> None:
    """Register the problem+json handlers on ``app``."""
    app.add_exception_handler(RequestValidationError, _validation)
    app.add_exception_handler(EngineError, _engine)
    app.add_exception_handler(NumericalFailure, _numerical)
    app.add_exception_handler(OutOfTime, _out_of_time)
    app.add_exception_handler(ServiceFault, _fault)
    app.add_exception_handler(MemoryError, _out_of_memory)
    app.add_exception_handler(StarletteHTTPException, _http)
    app.add_exception_handler(Exception, _unhandled)
