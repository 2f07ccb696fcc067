"""Shared fixtures: a synchronous httpx client on the ASGI app, and linkage builders."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from service.config import Settings
from service.main import create_app


def pytest_report_header(config: pytest.Config) -> list[str]:
    from tests.service.test_fuzz_openapi import FUZZ_EXAMPLES, FUZZ_SEED

    return [f"schemathesis: {FUZZ_EXAMPLES} examples per operation, seed {FUZZ_SEED} "
            f"(replay with FUZZ_SEED={FUZZ_SEED})"]


class ApiClient:
    """Synchronous facade over ``httpx.AsyncClient`` with the ASGI transport (no network)."""

    def __init__(self, app: Any) -> None:
        self._loop = asyncio.new_event_loop()
        self._client = httpx.AsyncClient(
            transport=httpx.ASGITransport(app=app, raise_app_exceptions=False),
            base_url="http://testserver",
        )

    def request(self, method: str, url: str, **kw: Any) -> httpx.Response:
        return self._loop.run_until_complete(self._client.request(method, url, **kw))

    def get(self, url: str, **kw: Any) -> httpx.Response:
        return self.request("GET", url, **kw)

    def post(self, url: str, **kw: Any) -> httpx.Response:
        return self.request("POST", url, **kw)

    def close(self) -> None:
        self._loop.run_until_complete(self._client.aclose())
        self._loop.close()


@pytest.fixture(scope="session")
def app() -> Iterator[Any]:
    # A generous time limit and search time: CI machines are shared and slow, and most tests
    # check complete answers; the limit itself is tested in tests/service/test_hardening.py,
    # the default search time (anytime answers) in tests/service/test_anytime.py, with apps of
    # their own.
    application = create_app(Settings.from_env().replace(time_limit_s=600.0,
                                                         search_time_s=300.0))
    yield application
    application.state.engine_pool.close()


@pytest.fixture(scope="session")
def client(app: Any) -> Iterator[ApiClient]:
    c = ApiClient(app)
    yield c
    c.close()
