"""Request ids, the body-size cap (413 before parsing) and the per-answer point limit."""

from __future__ import annotations

import asyncio

import httpx

from service import config
from service.config import Settings
from service.main import create_app


def run(app, coro_fn):
    async def main():
        transport = httpx.ASGITransport(app=app, raise_app_exceptions=False)
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            return await coro_fn(c)

    return asyncio.run(main())


def test_every_response_has_a_request_id(client):
    a, b = client.get("/health"), client.get("/v1/presets/nope")
    assert len(a.headers["x-request-id"]) == 32 and len(b.headers["x-request-id"]) == 32
    assert a.headers["x-request-id"] != b.headers["x-request-id"]
    echoed = client.get("/health", headers={"x-request-id": "client-42"})
    assert echoed.headers["x-request-id"] == "client-42"
    unsafe = client.get("/health", headers={"x-request-id": "bad id\\n" * 20})
    assert unsafe.headers["x-request-id"] != "bad id\\n" * 20


def test_oversized_bodies_get_413_before_parsing():
    app = create_app(Settings(max_body_bytes=1000))

    async def go(c):
        declared = await c.post("/v1/analysis/rigidity", content=b"{" * 5000,
                                headers={"content-type": "application/json"})

        async def chunks():
            for _ in range(10):
                yield b"[" * 300

        streamed = await c.post("/v1/analysis/rigidity", content=chunks(),
                                headers={"content-type": "application/json"})
        small = await c.post("/v1/analysis/rigidity", content=b"{}",
                             headers={"content-type": "application/json"})
        health = await c.get("/health")
        return declared, streamed, small, health

    declared, streamed, small, health = run(app, go)
    for r in (declared, streamed):
        assert r.status_code == 413
        assert r.headers["content-type"].startswith("application/problem+json")
        assert r.json()["type"] == "/problems/body-too-large" and r.json()["status"] == 413
    assert small.status_code == 422  # under the cap: parsed and validated as usual
    assert health.status_code == 200


def test_answer_point_limit(app, client):
    lk = client.get("/v1/presets/four-bar?L2=0.9").json()
    before = app.dependency_overrides[config.get_settings]
    app.dependency_overrides[config.get_settings] = lambda: before().replace(max_points=50)
    try:
        r = client.post("/v1/analysis/configuration-space",
                        json={"linkage": lk, "options": {"angles": 12, "random_starts": 2}})
    finally:
        app.dependency_overrides[config.get_settings] = before
    assert r.status_code == 422
    assert r.json()["errors"][0]["loc"] == ["body", "options"]
    assert "LINKAGE_MAX_POINTS" in r.json()["detail"]


def test_the_middleware_reads_the_same_settings_dependency_as_the_routes(app, client):
    """One settings dependency: overriding get_settings (as tests and create_app(settings) do)
    reaches the body-size cap of the middleware too, not only the routes."""
    before = app.dependency_overrides[config.get_settings]
    app.dependency_overrides[config.get_settings] = lambda: before().replace(max_body_bytes=100)
    try:
        capped = client.post("/v1/analysis/rigidity", content=b"{" * 500,
                             headers={"content-type": "application/json"})
    finally:
        app.dependency_overrides[config.get_settings] = before
    assert capped.status_code == 413 and capped.json()["type"] == "/problems/body-too-large"
    after = client.post("/v1/analysis/rigidity", content=b"{" * 500,
                        headers={"content-type": "application/json"})
    assert after.status_code == 422  # the override gone, the app's own limit again
