"""CORS: off by default; LINKAGE_CORS_ORIGINS lists the origins a browser may call from."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from service.config import Settings
from service.main import create_app
from tests.conftest import ApiClient

ALLOWED = "https://design.example.org"
PREFLIGHT = {"access-control-request-method": "POST",
             "access-control-request-headers": "content-type"}


def client_with(origins: tuple[str, ...]) -> Iterator[ApiClient]:
    app = create_app(Settings.from_env().replace(cors_origins=origins))
    c = ApiClient(app)
    yield c
    c.close()
    app.state.engine_pool.close()


@pytest.fixture
def cors_client() -> Iterator[ApiClient]:
    yield from client_with((ALLOWED,))


def test_preflight_from_an_allowed_origin_succeeds(cors_client: Any) -> None:
    r = cors_client.request("OPTIONS", "/v1/analysis/rigidity",
                            headers={"origin": ALLOWED, **PREFLIGHT})
    assert r.status_code == 200
    assert r.headers["access-control-allow-origin"] == ALLOWED
    assert "POST" in r.headers["access-control-allow-methods"]
    assert "content-type" in r.headers["access-control-allow-headers"].lower()
    r = cors_client.get("/v1/presets", headers={"origin": ALLOWED})
    assert r.status_code == 200
    assert r.headers["access-control-allow-origin"] == ALLOWED


def test_another_origin_gets_no_cors_headers(cors_client: Any) -> None:
    other = "https://elsewhere.example.com"
    r = cors_client.request("OPTIONS", "/v1/analysis/rigidity",
                            headers={"origin": other, **PREFLIGHT})
    assert "access-control-allow-origin" not in r.headers
    r = cors_client.get("/v1/presets", headers={"origin": other})
    assert r.status_code == 200
    assert "access-control-allow-origin" not in r.headers


def test_no_cors_by_default() -> None:
    for c in client_with(()):
        r = c.request("OPTIONS", "/v1/analysis/rigidity", headers={"origin": ALLOWED, **PREFLIGHT})
        assert "access-control-allow-origin" not in r.headers
        assert r.status_code == 405
        assert r.headers["content-type"].startswith("application/problem+json")


def test_origins_come_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LINKAGE_CORS_ORIGINS", f" {ALLOWED}, http://127.0.0.1:5173 ,")
    assert Settings.from_env().cors_origins == (ALLOWED, "http://127.0.0.1:5173")
    monkeypatch.delenv("LINKAGE_CORS_ORIGINS")
    assert Settings.from_env().cors_origins == ()
