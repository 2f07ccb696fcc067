"""ASGI middleware: request ids with one structured log line per request, and a body-size cap
that answers 413 before anything is parsed."""

from __future__ import annotations

import json
import logging
import re
import time
import uuid
from collections.abc import Callable

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.config import Settings
from service.metrics import Metrics

log = logging.getLogger("service.access")
_SAFE_ID = re.compile(r"^[A-Za-z0-9._-]{1,64}$")


def _problem_413(limit: int) -> bytes:
    return json.dumps({
        "type": "/problems/body-too-large",
        "title": "Request body too large",
        "status": 413,
        "detail": f"the request body exceeds LINKAGE_MAX_BODY_BYTES = {limit} bytes",
        "errors": [{"loc": ["body"], "msg": f"more than {limit} bytes"}],
    }).encode()


class RequestContext:
    """Adds ``x-request-id`` (the client's, when it is a short safe token, else a new one) to
    every response, logs one JSON line per request, and refuses bodies over the limit with a
    413 problem before the application sees them: at once from ``content-length``, else by
    reading the body here (at most limit + 1 bytes) and replaying it to the application."""

    def __init__(self, app: ASGIApp, settings: Callable[[], Settings],
                 metrics: Metrics | None = None) -> None:
        self.app = app
        self.settings = settings
        self.metrics = metrics

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        given = headers.get(b"x-request-id", b"").decode("latin-1")
        request_id = given if _SAFE_ID.match(given) else uuid.uuid4().hex
        limit = self.settings().max_body_bytes
        start = time.perf_counter()
        status = {"code": 500}

        async def send_with_id(message: Message) -> None:
            if message["type"] == "http.response.start":
                status["code"] = message["status"]
                message.setdefault("headers", [])
                message["headers"] = [*message["headers"],
                                      (b"x-request-id", request_id.encode())]
            await send(message)

        async def reply_413() -> None:
            body = _problem_413(limit)
            await send_with_id({
                "type": "http.response.start", "status": 413,
                "headers": [(b"content-type", b"application/problem+json"),
                            (b"content-length", str(len(body)).encode())],
            })
            await send_with_id({"type": "http.response.body", "body": body})

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
                while True:
                    message = await receive()
                    if message["type"] != "http.request":  # client went away
                        status["code"] = 499
                        return
                    chunks.append(message.get("body", b""))
                    size += len(chunks[-1])
                    if size > limit or not message.get("more_body", False):
                        break
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

                    await self.app(scope, replay, send_with_id)
        finally:
            seconds = time.perf_counter() - start
            if self.metrics is not None:
                self.metrics.in_flight.dec()
                route = scope.get("route")
                template = getattr(route, "path", None) or "unmatched"
                self.metrics.observe(str(scope.get("method")), template, status["code"], seconds)
            log.info(json.dumps({
                "request_id": request_id,
                "method": scope.get("method"),
                "path": scope.get("path"),
                "status": status["code"],
                "duration_ms": round(1e3 * seconds, 2),
            }))
