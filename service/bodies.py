"""Request bodies: JSON only (415 otherwise), and large ones parsed off the event loop.

Parsing and validating a 4 MB linkage takes a few hundred milliseconds of CPU in calls that
hold the GIL throughout (``json.loads``, pydantic-core), so neither the event loop nor a thread
can answer anyone else meanwhile. Bodies of more than :data:`OFFLOAD_BYTES` are therefore
parsed, counted against the size limits and validated in an engine worker process; the
endpoint receives the validated model, which FastAPI then accepts as it is. A linkage over
``LINKAGE_MAX_VERTICES`` or ``LINKAGE_MAX_BARS`` is refused right after the parse, before any
validation. Smaller bodies take FastAPI's usual path (a 256 kB body costs about 10 ms).
"""

from __future__ import annotations

import email.message
import json
import sys
import time
from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import HTTPException, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import BaseModel, ValidationError

from engine.model.errors import LimitExceeded
from engine.model.linkage import Limits
from service.config import app_settings
from service.errors import problem
from service.gcpause import gc_paused

#: Bodies larger than this are parsed and validated in a worker process.
OFFLOAD_BYTES = 256 * 1024


def is_json(content_type: str) -> bool:
    message = email.message.Message()
    message["content-type"] = content_type
    subtype = message.get_content_subtype()
    return message.get_content_maintype() == "application" and (
        subtype == "json" or subtype.endswith("+json"))


def parse_request(model: type[BaseModel], body: bytes,
                  limits: Limits) -> tuple[str, Any]:
    """Parse and validate ``body`` as ``model`` (in a worker process). Returns ``("ok",
    instance)``, ``("json", (position, message))``, ``("undecodable", message)``,
    ``("limit", (loc, message))``, ``("deep", message)`` (nested deeper than the parser's
    recursion limit) or ``("invalid", errors)``: plain values that pickle."""
    try:
        with gc_paused():  # some 10^5 objects at once: see service.gcpause
            data = json.loads(body)
    except json.JSONDecodeError as err:
        return "json", (err.pos, err.msg)
    except ValueError as err:  # not UTF-8/16/32
        return "undecodable", str(err)
    except RecursionError:  # e.g. 300,000 opening brackets: refused, not a 500
        return "deep", (f"the JSON body is nested deeper than the parser allows (Python's "
                        f"recursion limit, {sys.getrecursionlimit()} levels)")
    linkage = data.get("linkage") if isinstance(data, dict) else None
    if isinstance(linkage, dict):
        for key, limit in (("vertices", limits.max_vertices), ("bars", limits.max_bars)):
            items = linkage.get(key)
            if isinstance(items, list) and len(items) > limit:
                return "limit", ((key,), f"{len(items)} {key} exceed the limit of {limit}")
    try:
        with gc_paused():
            # as FastAPI validates bodies (from_attributes: the same messages)
            return "ok", model.model_validate(data, from_attributes=True)
    except ValidationError as err:
        return "invalid", [{"type": e["type"], "loc": ("body", *e["loc"]), "msg": e["msg"]}
                           for e in err.errors(include_url=False)]


class ParsedBody(Request):
    """The request with its body already parsed (FastAPI reads ``body()`` and ``json()``)."""

    def __init__(self, request: Request, body: bytes, value: Any) -> None:
        super().__init__(request.scope, request.receive)
        self._given_body = body
        self._value = value

    async def body(self) -> bytes:
        return self._given_body

    async def json(self) -> Any:
        return self._value


async def _parsed(request: Request, model: type[BaseModel], body: bytes) -> Request:
    settings = app_settings(request.app)
    kind, value = await request.app.state.engine_pool.run(
        settings.time_limit_s, parse_request, model, body, settings.limits)
    if kind == "ok":
        return ParsedBody(request, body, value)
    if kind == "json":
        position, message = value
        raise RequestValidationError([{"type": "json_invalid", "loc": ("body", position),
                                       "msg": "JSON decode error", "ctx": {"error": message}}])
    if kind == "undecodable":
        raise HTTPException(400, "There was an error parsing the body")
    if kind == "deep":
        raise HTTPException(400, value)
    if kind == "limit":
        loc, message = value
        raise LimitExceeded(message, loc=loc)
    raise RequestValidationError(value)


class JsonBodyRoute(APIRoute):
    """A route whose body is JSON: other content types get a 415 problem, and bodies over
    :data:`OFFLOAD_BYTES` are parsed and validated in a worker process."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        params = self.dependant.body_params
        if len(params) != 1 or getattr(params[0].field_info, "embed", False):
            return handler  # not one model as the whole body: FastAPI's own path only
        model = getattr(params[0].field_info, "annotation", None)
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return handler

        async def json_body_handler(request: Request) -> Response:
            request.state.arrived_at = time.monotonic()
            content_type = request.headers.get("content-type")
            if content_type is not None and not is_json(content_type):
                return problem(415, "unsupported-media-type", "Unsupported media type",
                               f"the request body must be application/json, not "
                               f"{content_type[:100]!r}",
                               [{"loc": ["header", "content-type"],
                                 "msg": "expected application/json"}])
            body = await request.body()
            if len(body) > OFFLOAD_BYTES:
                request = await _parsed(request, model, body)
            return await handler(request)

        return json_body_handler
