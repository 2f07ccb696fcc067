"""Liveness and readiness (issue 28, item 1): ``/health`` and ``/health/live`` answer as soon
as the process does; ``/health/ready`` only once the engine workers have started, and not while
the worker pool is broken (tests/service/test_workers.py kills workers in every state)."""

import asyncio

import pytest

from service.config import Settings
from service.main import create_app
from tests.service.test_hardening import assert_problem, client_for


def test_health(client):
    r = client.get("/health")
    assert r.status_code == 200
    assert r.json()["status"] == "ok"


def test_live(client):
    r = client.get("/health/live")
    assert r.status_code == 200
    assert r.json()["status"] == "ok" and r.json()["version"]


@pytest.mark.slow
def test_ready_only_once_the_workers_have_started():
    app = create_app(Settings(workers=1))
    pool = app.state.engine_pool

    async def scenario() -> tuple[object, ...]:
        async with client_for(app) as c:
            before = await c.get("/health/ready")
            live = await c.get("/health/live")
            await asyncio.to_thread(pool.start)
            return before, live, await c.get("/health/ready")

    try:
        before, live, after = asyncio.run(scenario())
    finally:
        pool.close()
    body = assert_problem(before, 503, "not-ready")
    assert "starting" in body["detail"] and before.headers["retry-after"] == "1"
    assert live.status_code == 200
    assert after.status_code == 200, after.text
    assert after.json() == {"status": "ready", "version": after.json()["version"], "workers": 1}
