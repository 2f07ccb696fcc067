"""ASGI middleware: request ids with one structured log line per request, a body-size cap
that answers 413 before anything is parsed, and a time limit on reading the body (408)."""

from __future__ import annotations

import asyncio
import json
import logging
import re
import sys
import time
import uuid
from typing import Any, TextIO

from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.config import app_settings
from service.metrics import Metrics

log = logging.getLogger("service.access")
error_log = logging.getLogger("service")
_SAFE_ID = re.compile(r"^[A-Za-z0-9._-]{1,64}$")
#: Methods counted under their own name in metrics; any other is ``other`` (the method is
#: copied from the request line, so unknown ones would make a series each).
KNOWN_METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})


class _StdoutHandler(logging.StreamHandler[TextIO]):
    """Writes to whatever ``sys.stdout`` is at the time (test runners swap it)."""

    @property
    def stream(self) -> TextIO:
        return sys.stdout

    @stream.setter
    def stream(self, value: TextIO) -> None:
        pass


def install_access_log() -> None:
    """Write the access log (one JSON line per request) to stdout at level INFO, unless the
    operator configured the ``service.access`` logger (e.g. ``uvicorn --log-config``). Without
    this, servers that configure only their own loggers drop every line."""
    if log.handlers:
        return
    handler = _StdoutHandler()
    handler.setFormatter(logging.Formatter("%(message)s"))
    log.addHandler(handler)
    log.setLevel(logging.INFO)
    log.propagate = False


def _problem(status: int, kind: str, title: str, detail: str, msg: str) -> bytes:
    return json.dumps({
        "type": f"/problems/{kind}",
        "title": title,
        "status": status,
        "detail": detail,
        "errors": [{"loc": ["body"], "msg": msg}],
    }).encode()


def route_label(scope: Scope) -> str:
    """The metric label of a request's route: the template of the matched route (``/docs``,
    ``/redoc`` and mounts included), else ``other``. Never the raw path, so that the number of
    series stays bounded by the application's routes."""
    route = scope.get("route")
    template = getattr(route, "path", None)
    if template:
        return str(template)
    app = scope.get("app")
    for candidate in getattr(app, "routes", ()):
        try:
            match, _ = candidate.matches(scope)
        except (KeyError, TypeError, ValueError):  # a route that cannot judge this scope
            continue
        if match is not Match.NONE and getattr(candidate, "path", None):
            return str(candidate.path)
    return "other"


class RequestContext:
    """Adds ``x-request-id`` (the client's, when it is a short safe token, else a new one) to
    every response, logs one JSON line per request, and refuses bodies over the limit with a
    413 problem before the application sees them: at once from ``content-length``, else by
    reading the body here (at most limit + 1 bytes) and replaying it to the application. A
    body that does not arrive within ``body_timeout_s`` gets a 408 and the connection is
    closed (a slow client holds no one else up)."""

    def __init__(self, app: ASGIApp, metrics: Metrics | None = None) -> None:
        self.app = app
        self.metrics = metrics
        install_access_log()

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        given = headers.get(b"x-request-id", b"").decode("latin-1")
        request_id = given if _SAFE_ID.match(given) else uuid.uuid4().hex
        settings = app_settings(scope["app"])  # the app's own, as its routes see them
        limit = settings.max_body_bytes
        original: dict[str, Any] = dict(scope)  # the router adds to scope; labels match on this
        start = time.perf_counter()
        status = {"code": 500}
        started = {"yes": False}

        async def send_with_id(message: Message) -> None:
            if message["type"] == "http.response.start":
                status["code"] = message["status"]
                started["yes"] = True
                message.setdefault("headers", [])
                message["headers"] = [*message["headers"],
                                      (b"x-request-id", request_id.encode())]
            await send(message)

        async def reply(status: int, body: bytes) -> None:
            # The rest of the body is not read: the connection cannot be reused.
            await send_with_id({
                "type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/problem+json"),
                            (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")],
            })
            await send_with_id({"type": "http.response.body", "body": body})

        async def reply_413() -> None:
            await reply(413, _problem(
                413, "body-too-large", "Request body too large",
                f"the request body exceeds LINKAGE_MAX_BODY_BYTES = {limit} bytes",
                f"more than {limit} bytes"))

        if self.metrics is not None:
            self.metrics.in_flight.inc()
        try:
            try:
                declared = int(headers.get(b"content-length", b"0") or 0)
            except ValueError:
                declared = 0
            if declared > limit:
                await reply_413()
            else:
                chunks: list[bytes] = []
                size = 0
                try:
                    async with asyncio.timeout(settings.body_timeout_s):
                        while True:
                            message = await receive()
                            if message["type"] != "http.request":  # client went away
                                status["code"] = 499
                                return
                            chunks.append(message.get("body", b""))
                            size += len(chunks[-1])
                            if size > limit or not message.get("more_body", False):
                                break
                except TimeoutError:
                    await reply(408, _problem(
                        408, "body-timeout", "Request body too slow",
                        f"the request body did not arrive within LINKAGE_BODY_TIMEOUT_S = "
                        f"{settings.body_timeout_s:g} s ({size} bytes received)",
                        "incomplete"))
                    return
                if size > limit:
                    await reply_413()
                else:
                    body = b"".join(chunks)
                    replayed = {"done": False}

                    async def replay() -> Message:
                        if not replayed["done"]:
                            replayed["done"] = True
                            return {"type": "http.request", "body": body, "more_body": False}
                        return await receive()  # e.g. http.disconnect

                    try:
                        await self.app(scope, replay, send_with_id)
                    except Exception:  # answered here, so that the connection stays usable
                        await _internal_error(send_with_id, scope, started["yes"])
        finally:
            self._record(scope, original, request_id, status["code"], start)

    def _record(self, scope: Scope, original: dict[str, Any], request_id: str, status: int,
                start: float) -> None:
        """The request's metrics and access-log line."""
        seconds = time.perf_counter() - start
        route = route_label({**original, "route": scope.get("route")})
        if self.metrics is not None:
            self.metrics.in_flight.dec()
            method = str(scope.get("method"))
            self.metrics.observe(method if method in KNOWN_METHODS else "other", route,
                                 status, seconds)
        if log.isEnabledFor(logging.INFO):
            log.info(json.dumps({
                "request_id": request_id,
                "method": scope.get("method"),
                "route": route,
                "path": scope.get("path"),
                "status": status,
                "duration_ms": round(1e3 * seconds, 2),
            }))


async def _internal_error(send: Send, scope: Scope, responded: bool) -> None:
    """A 500 problem for an unforeseen error. Starlette's outermost middleware would answer the
    500 and then re-raise, and uvicorn closes a connection whose application raised: the
    client's next request on it would fail. Answered here instead, the connection is kept."""
    error_log.exception("unhandled error on %s %s", scope.get("method"), scope.get("path"))
    if responded:
        return
    body = json.dumps({"type": "/problems/internal-error", "title": "Internal error",
                       "status": 500, "detail": "the service failed unexpectedly",
                       "errors": []}).encode()
    await send({
        "type": "http.response.start", "status": 500,
        "headers": [(b"content-type", b"application/problem+json"),
                    (b"content-length", str(len(body)).encode())],
    })
    await send({"type": "http.response.body", "body": body})
