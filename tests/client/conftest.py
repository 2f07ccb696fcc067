"""The client against the real app: the sync client through Starlette's TestClient (an
httpx.Client on the ASGI app), the async client through httpx's ASGI transport; both record
the operations they call (path templates of openapi/openapi.json)."""

from __future__ import annotations

import asyncio
import json
import re
from collections.abc import Coroutine, Iterator
from pathlib import Path
from typing import Any, TypeVar

import httpx
import pytest
from fastapi.testclient import TestClient
from linkage_client import AsyncClient, Client

ROOT = Path(__file__).resolve().parents[2]
OPENAPI = json.loads((ROOT / "openapi" / "openapi.json").read_text())
T = TypeVar("T")


def operations() -> dict[tuple[str, str], str]:
    """``(METHOD, path template) -> operationId`` of every operation."""
    return {(method.upper(), path): op["operationId"]
            for path, item in OPENAPI["paths"].items() for method, op in item.items()}


def operation_of(method: str, path: str) -> str:
    """The operationId a request went to (exact paths before templates: /v1/presets/four-bar
    is getPresetFourBar, not getPreset)."""
    ops = operations()
    if (method, path) in ops:
        return ops[(method, path)]
    for (m, template), op_id in ops.items():
        pattern = "^" + re.sub(r"\{[^}]+\}", "[^/]+", template) + "$"
        if m == method and re.match(pattern, path):
            return op_id
    raise AssertionError(f"{method} {path} is no operation of the OpenAPI file")


class Recorder:
    """The operationIds of the requests seen (an httpx event hook, the requests go through)."""

    def __init__(self) -> None:
        self.seen: set[str] = set()

    def __call__(self, request: httpx.Request) -> None:
        self.seen.add(operation_of(request.method, request.url.path))

    async def asynchronous(self, request: httpx.Request) -> None:
        self(request)


@pytest.fixture(scope="module")
def recorder() -> Recorder:
    return Recorder()


@pytest.fixture(scope="module")
def sync(app: Any, recorder: Recorder) -> Iterator[Client]:
    """The sync client on the session's app (tests/conftest.py)."""
    http = TestClient(app, raise_server_exceptions=False)
    http.event_hooks = {"request": [recorder], "response": []}
    with Client(http=http) as c:
        yield c
    http.close()


class Loop:
    """One event loop for a module's async calls (``loop.run(coroutine)``)."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()

    def run(self, coroutine: Coroutine[Any, Any, T]) -> T:
        return self.loop.run_until_complete(coroutine)


@pytest.fixture(scope="module")
def aio(app: Any, recorder: Recorder) -> Iterator[tuple[AsyncClient, Loop]]:
    """The async client on the session's app through httpx's ASGI transport, and its loop."""
    loop = Loop()
    client = AsyncClient(base_url="http://testserver",
                         transport=httpx.ASGITransport(app=app, raise_app_exceptions=False))
    client.http.event_hooks = {"request": [recorder.asynchronous], "response": []}
    yield client, loop
    loop.run(client.aclose())
    loop.loop.close()
